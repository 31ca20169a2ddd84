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
from ..plans import Candidate, Tally
from ..scp import Solved
from ..seeds import TrackedSeed
from .base import Outcome, Strategy


class Guided(Strategy):
    """One candidate along the guide; the same manoeuvre at other switch steps where it has one."""

    def __init__(self, core: PlannerCore, config: GuidedConfig):
        super().__init__(core, config)
        self.tracked_seed = TrackedSeed(self.g, self.cc, core.rollouts.truth)
        self.guide: GuideSearch | None = None  # built by prepare()

    def prepare(self) -> None:
        """The guide's tails, shared by episodes in the same slot (``guide.prepared_search``)."""
        if self.guide is None:
            self.guide = prepared_search(self.g)

    def plan(
        self, state: VehicleState, xi0: np.ndarray, start: Start, candidates: list[Candidate] | None = None
    ) -> Outcome:
        """Seed from tracking the guide, then SCP toward the guided goal. No plan where there
        is no guide (status ``no_guide``) or no clear plan along it; the progress is the
        guide's cost."""
        self.prepare()
        guide = self.guide.search(xi0[:3])
        progress = guide.cost if guide else math.inf
        if guide is None:
            return Outcome(None, "no_guide", Tally(), progress=progress)
        res, tally, net, goal, tried = self._solve(xi0, guide, start)
        plan, status = res.plan, "ok"
        if plan is None and res.partial is not None:  # go along the guide as far as is safe
            plan, status = res.partial, "partial"
        if plan is None:  # a failed call records no effort (as the guided planner always has)
            return Outcome(None, "infeasible", Tally(), progress=progress, safety_net=net)
        detail = {"candidates": tried, "goal": tuple(round(float(v), 3) for v in goal)}
        return Outcome(plan, status, tally, plan.cost, progress, net, detail)

    def _solve(self, xi0: np.ndarray, guide: Guide, start: Start) -> tuple[Solved, Tally, bool, np.ndarray, list]:
        """The guided candidate, and for a plan with a switch the same manoeuvre seeded at
        the other ``switch_speeds`` (other switch steps, same goal): the plan of lowest
        optimal cost wins. Returns (its solve, the work of all, any safety net, goal, tried)."""
        cand, seed, goal = self.tracked_seed.seed(xi0, guide)
        variants = [(cand, seed)]
        if cand.switch is not None:
            for v in self.cfg.switch_speeds:
                c2, s2, g2 = self.tracked_seed.seed(xi0, guide, v)
                if c2.switch is not None and np.allclose(g2, goal) and all(c2 != c for c, _ in variants):
                    variants.append((c2, s2))
        natural = cand.direction == self.seeds.first_direction  # the order of the paper's mirror line
        best: Solved | None = None
        tried, tally, net = [], Tally(), False
        for c, seed in variants:
            res = self.scp.solve(
                xi0, c, goal, start, self.lines.slot, seed, iterations=self.cfg.iterations, band=natural
            )
            tally += res.tally
            net = net or res.safety_net
            plan = res.plan
            tried.append((c, None if plan is None else round(plan.cost, 3), res.status))
            if best is None or (plan is not None and (best.plan is None or plan.cost < best.plan.cost)):
                best = res
        return best, tally, net, goal, tried
