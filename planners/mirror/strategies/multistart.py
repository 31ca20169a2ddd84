"""``mirror-multistart``: neither guide nor cost to go; the classic shapes, compared by optimisation.

Candidates over both gears (one while moving), at two switch steps and without a switch,
are seeded by the manoeuvre's classic shapes and a few heading excursions (``seeds.py``),
ranked by merit; the best few are refined by SCP toward the mirrored target, and the plan
of lowest optimal cost wins. Where none is clear and progressing, the best safe stop short
of a contact is returned as a partial plan.
"""

from __future__ import annotations

import math

import numpy as np

from mirrorpark_env.angles import unwrap_near
from mirrorpark_env.scenario import ParkingType
from mirrorpark_env.vehicle import VehicleState

from ..checks import Start
from ..config import MultistartConfig
from ..core import PlannerCore
from ..plans import Candidate, Plan
from ..scp import no_effort
from .base import Strategy


class MultiStart(Strategy):
    """Shape seeds over the candidates, the best refined; ``plan_candidates`` takes given ones."""

    def __init__(self, core: PlannerCore, config: MultistartConfig):
        super().__init__(core, config)
        by_type = config.refine_candidates_parallel if core.g.parking_type is ParkingType.PARALLEL else None
        self.refine = by_type or config.refine_candidates  # candidates refined in this slot

    def plan(self, state: VehicleState, xi0: np.ndarray, start: Start, t0: float) -> Plan | None:
        return self.plan_candidates(state, xi0, start, t0, None)

    def plan_candidates(
        self, state: VehicleState, xi0: np.ndarray, start: Start, t0: float, candidates: list[Candidate] | None
    ) -> Plan | None:
        """The best plan over ``candidates`` (None: the classic ones), each seeded by its best shape."""
        core = self.core
        line = core.line_from(state.theta)
        goal = np.array(core.g.target, float)
        theta_t = unwrap_near(goal[2], state.theta)
        seeds = core.shape_seeds.ranked(
            xi0,
            candidates or core.shape_seeds.candidates(state, line),
            line,
            lambda real: core.checks.merit(real, goal, theta_t),
        )
        stay = core.checks.merit(np.repeat(xi0[None], core.cfg.model_substeps * core.N + 1, axis=0), goal, theta_t)
        best = partial = None
        totals = no_effort()
        net = False
        tried = []
        for n, (cand, seed) in enumerate(seeds):
            if n >= self.refine and best is not None and best.cost < 0.9 * stay:
                break  # refine the best few; go on down the list while none is clear and progressing
            plan, st = core.scp.solve(xi0, cand, goal, start, line, seed)
            for k in totals:
                totals[k] += st[k]
            net = net or st.get("safety_net", False)
            tried.append((cand, None if plan is None else round(plan.cost, 3), st["status"]))
            if plan is not None and plan.collision_free and (best is None or plan.cost < best.cost):
                best = plan
            p_ = st.get("partial")
            if p_ is not None and (partial is None or p_.cost < partial.cost):
                partial = p_
        status = "ok" if best is not None else "infeasible"
        if partial is not None and partial.cost < 0.98 * min(stay, best.cost if best else math.inf):
            best, status = partial, "partial"  # no full plan progresses: go as far as is safe
        detail = {"candidates": tried, "stay_cost": stay, "guided": False, "safety_net": net}
        return core.finish(t0, status, totals, best.cost if best else math.nan, detail, best)
