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
from ..plans import Candidate, Tally
from .base import Outcome, Strategy


class MultiStart(Strategy):
    """Shape seeds over the candidates, the best refined; ``plan`` also takes given ones."""

    takes_candidates = True

    def __init__(self, core: PlannerCore, config: MultistartConfig):
        super().__init__(core, config)
        by_type = config.refine_candidates_parallel if self.g.parking_type is ParkingType.PARALLEL else None
        self.refine = by_type or config.refine_candidates  # candidates refined in this slot

    def plan(
        self, state: VehicleState, xi0: np.ndarray, start: Start, candidates: list[Candidate] | None = None
    ) -> Outcome:
        """The best plan over ``candidates`` (None: the classic ones), each seeded by its best shape."""
        cc, checks = self.cc, self.checks
        line = self.lines.from_heading(state.theta)
        goal = np.array(self.g.target, float)
        theta_t = unwrap_near(goal[2], state.theta)
        seeds = self.seeds.ranked(
            xi0,
            candidates or self.seeds.candidates(state, line),
            line,
            lambda real: checks.merit(real, goal, theta_t),
        )
        stay = checks.merit(np.repeat(xi0[None], cc.model_substeps * cc.horizon + 1, axis=0), goal, theta_t)
        best = partial = None
        tally, net, tried = Tally(), False, []
        for n, (cand, seed) in enumerate(seeds):
            if n >= self.refine and best is not None and best.cost < 0.9 * stay:
                break  # refine the best few; go on down the list while none is clear and progressing
            res = self.scp.solve(xi0, cand, goal, start, line, seed)
            tally += res.tally
            net = net or res.safety_net
            plan = res.plan
            tried.append((cand, None if plan is None else round(plan.cost, 3), res.status))
            if plan is not None and plan.collision_free and (best is None or plan.cost < best.cost):
                best = plan
            if res.partial is not None and (partial is None or res.partial.cost < partial.cost):
                partial = res.partial
        status = "ok" if best is not None else "infeasible"
        if partial is not None and partial.cost < 0.98 * min(stay, best.cost if best else math.inf):
            best, status = partial, "partial"  # no full plan progresses: go as far as is safe
        cost = best.cost if best else math.nan
        return Outcome(best, status, tally, cost, progress=stay, safety_net=net, detail={"candidates": tried})
