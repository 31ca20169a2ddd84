"""``mirror-guided``: the geometric guide chooses each plan's manoeuvre, the QP polishes it.

The guide (``guide.py``: Reeds-Shepp paths through the mirror line's switch poses) is tracked
on the planning model up to its second gear segment: that rollout seeds one candidate, and
its pose there (or the target) is the candidate's goal. SCP then decides where on the
mirror line the car switches. The default planner until 2026-12-02, kept for the ablation.
"""

from __future__ import annotations

import math

import numpy as np

from mirrorpark_env.vehicle import VehicleState

from ..checks import Start
from ..config import GuidedConfig
from ..core import PlannerCore
from ..guide import Guide, GuideSearch, prepared_search
from ..plans import Plan
from ..scp import EFFORT, no_effort
from ..seeds import TrackedSeed
from .base import Strategy


class Guided(Strategy):
    """One candidate along the guide; the same manoeuvre at other switch steps where it has one."""

    def __init__(self, core: PlannerCore, config: GuidedConfig):
        super().__init__(core, config)
        self.tracked_seed = TrackedSeed(core.g, core.cfg, core.coarse)
        self.guide: GuideSearch | None = None  # built by prepare()

    def prepare(self) -> None:
        """The guide's tails, shared by episodes in the same slot (``guide.prepared_search``)."""
        if self.guide is None:
            self.guide = prepared_search(self.core.g)

    def plan(self, state: VehicleState, xi0: np.ndarray, start: Start, t0: float) -> Plan | None:
        """Seed from tracking the guide, then SCP toward the guided goal. None when there is no
        guide (status ``no_guide``) or no clear plan along it."""
        self.prepare()
        guide = self.guide.search(xi0[:3])
        detail = {"guide_cost": guide.cost if guide else math.inf}
        plan = None
        if guide is not None:
            plan, st, cand, goal, tried = self._solve(xi0, guide, start)
            status = "ok"
            if plan is None and st.get("partial") is not None:  # go along the guide as far as is safe
                plan, status = st["partial"], "partial"
            detail["safety_net"] = st.get("safety_net", False)
        if plan is None:  # a failed call records no effort (as the guided planner always has)
            status = "infeasible" if guide is not None else "no_guide"
            return self.core.finish(t0, status, no_effort(), math.nan, detail, None)
        detail = {"candidates": tried, "guided": True, "goal": tuple(round(float(v), 3) for v in goal), **detail}
        return self.core.finish(t0, status, st, plan.cost, detail, plan)

    def _solve(self, xi0: np.ndarray, guide: Guide, start: Start):
        """The guided candidate, and for a plan with a switch the same manoeuvre seeded at
        the other ``switch_speeds`` (other switch steps, same goal): the plan of lowest
        optimal cost wins. Returns (plan or None, statistics, candidate, goal, tried)."""
        core = self.core
        cand, seed, goal = self.tracked_seed.seed(xi0, guide)
        variants = [(cand, seed)]
        if cand.switch is not None:
            for v in self.cfg.switch_speeds:
                c2, s2, g2 = self.tracked_seed.seed(xi0, guide, v)
                if c2.switch is not None and np.allclose(g2, goal) and all(c2 != c for c, _ in variants):
                    variants.append((c2, s2))
        natural = cand.direction == core.shape_seeds.first_direction  # the order of the paper's mirror line
        best = best_st = None
        tried, totals, net = [], no_effort(), False
        for c, seed in variants:
            plan, st = core.scp.solve(
                xi0, c, goal, start, core.line, seed, iterations=self.cfg.iterations, band=natural
            )
            for k in EFFORT:
                totals[k] += st[k]
            net = net or st.get("safety_net", False)
            tried.append((c, None if plan is None else round(plan.cost, 3), st["status"]))
            if best_st is None or (plan is not None and (best is None or plan.cost < best.cost)):
                best, best_st, cand = plan, st, c
        return best, {**best_st, **totals, "safety_net": net}, cand, goal, tried
