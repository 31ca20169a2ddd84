"""One candidate solved: rounds of Algorithm I inside a linearisation loop (paper II.C-E).

Each round is solved on the linear model of the candidate's ``Rounds`` (``linearisation.py``)
with the disjunctive obstacle rows of every step that a rollout collides at (Algorithm I):
a QP where there are none, else the MIQP by branch and bound. Each round's solution is
rolled out on the planning model and scored by the merit (the true cost plus the exact
penalty on penetration); a clear rollout whose switch lies in its band is a plan. The
cheapest plans that the truth model confirms are the candidate's answer.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from mirrorpark_env.angles import unwrap_near
from mirrorpark_env.scenario import ScenarioGeometry

from .checks import Start, same_pose
from .cost import band_penalty, linear_term
from .frames import XI_TH, real_commands, to_planned
from .linearisation import RoundParts, RoundsFactory
from .mirror_line import MirrorLine, SlotLines, SwitchBand, band_margin, switch_band
from .plans import Candidate, Plan, Tally
from .qp import MirrorQP
from .rollouts import Rollouts
from .solvers import BranchAndBound, PiqpQP
from .stages import CallBudget, StageClock


@dataclass(frozen=True, eq=False)
class Reference:
    """A rollout that rounds linearise about: real states at half steps, planned commands,
    its footprint penetration and merit."""

    real: np.ndarray
    u: np.ndarray
    pen: np.ndarray
    merit: float = math.nan


@dataclass(frozen=True, eq=False)
class Solved:
    """One candidate's answer: its plan (None: no clear one confirmed by the truth model),
    ``status`` ("ok", "infeasible", "failed"), the work, and ``partial``: a safe stop short
    of the best iterate's first contact, where there is one. ``converged``: its SCP stopped
    before its round cap; ``cut_short``: a branch and bound ran out of nodes; ``safety_net``:
    one hit its wall-clock limit."""

    plan: Plan | None
    status: str
    tally: Tally
    partial: Plan | None = None
    converged: bool = False
    cut_short: bool = False
    safety_net: bool = False


class SCP:
    """Solves candidates on a slot's planning parts, each with the rounds of ``rounds``."""

    def __init__(
        self,
        *,
        geometry: ScenarioGeometry,
        lines: SlotLines,
        parts: RoundParts,
        rollouts: Rollouts,
        qp: MirrorQP,
        qp_solver: PiqpQP,
        miqp: BranchAndBound,
        budget: CallBudget,
        clock: StageClock,
        rounds: RoundsFactory,
    ):
        self.g, self.cfg, self.p = geometry, parts.cfg, geometry.vehicle
        self.parallel = lines.slot.fixed  # Theorem 1's line: parallel parking
        self.parts, self.checks, self.rollouts, self.qp = parts, parts.checks, rollouts, qp
        self.qp_solver, self.miqp, self.budget, self.clock, self.rounds = qp_solver, miqp, budget, clock, rounds
        self.first_direction = parts.seeds.first_direction

    def solve(
        self,
        xi0: np.ndarray,
        cand: Candidate,
        goal: np.ndarray,
        start: Start,
        line: MirrorLine,
        seed: np.ndarray | None = None,
        iterations: int | None = None,
        band: bool = False,
        miqp: BranchAndBound | None = None,
    ) -> Solved:
        """The candidate (direction, switch step) toward ``goal`` from ``xi0``.

        ``band``: the switch lies in the band of ``switch_band`` toward ``goal`` (linearised
        at each reference); otherwise on ``line`` in the natural order. ``iterations``: the
        round cap (default the config's ``max_iterations``; a switch still outside its band
        may go on to that). ``miqp``: the branch and bound to use (default the planner's).
        """
        cfg, clock = self.cfg, self.clock
        theta_t = unwrap_near(goal[2], xi0[XI_TH])
        terminal = self.checks.terminal_toward(goal)
        c = linear_term(cfg, cand.switch, goal, theta_t, terminal)
        theta_set: dict[tuple[int, int], None] = {}  # (step, obstacle) pairs with obstacle rows
        clear_plans: list[Plan] = []  # clear on the planning model; verified on the truth model at the end
        work = _Work(miqp or self.miqp)
        status, converged = "failed", False
        mirror = cand.direction == self.first_direction and not band
        rounds = self.rounds(self.parts, xi0, cand, theta_t, goal)
        with clock("seeds"):
            first = rounds.first(seed, line)
        ref = None
        if first is not None:
            with clock("checks"):
                ref, _, _ = self._score(*first, cand, goal, theta_t, start, line, band, clear_plans)
        cap = cfg.max_iterations if iterations is None else iterations
        for it in range(cfg.max_iterations):
            if it >= cap and (clear_plans or not band):
                break  # a switch outside its band: more rounds (to max_iterations) to move it in
            work.iterations += 1
            with clock("build"):
                lin = rounds.model(ref, theta_set, start)
                ref_real = ref.real if ref is not None else None
                rows = self._band(cand, goal, ref_real) if band else None
                qp, disj, active, preferred = self.qp.build(
                    xi0,
                    cand,
                    c,
                    lin,
                    ref_real,
                    theta_set,
                    line,
                    rounds.trust,
                    mirror=mirror,
                    trust_scale=rounds.trust_scale,
                    band=rows,
                    terminal=terminal,
                )
            with clock("solve"):
                x = self._solve(qp, disj, active, preferred, work)
            if x is None:
                status = "infeasible"
                break
            u_planned = x[self.qp.u_index]
            with clock("checks"):
                real = self.rollouts.half(xi0, u_planned, cand)
                new, hits, usable = self._score(real, u_planned, cand, goal, theta_t, start, line, band, clear_plans)
            for i, k in hits:  # Algorithm I on the new solution too, accepted or not
                theta_set[(i, k)] = None
            ref, stop, converged = rounds.after(ref, new, hits, usable)
            if stop:
                break
        partial = None
        with clock("checks"):
            best = self._confirmed(xi0, clear_plans, start)
            if best is not None:
                status = "ok"
            elif ref is not None:  # no clear plan: the best iterate's safe start, if any
                partial = self._safe_stop(xi0, cand, ref, goal, theta_t, start, line)
        return Solved(best, status, work.tally(), partial, converged, work.cut_short, work.safety_net)

    def _band_args(self, cand: Candidate, goal: np.ndarray) -> tuple[int, float, float | None]:
        """(gear after the switch, margin, slot width or None) of a plan's switch band: the
        reach bound (Eqs. 1, 5, 6) toward the plan's goal, and Theorem 1's kerb bound
        (Eq. 2) where a parallel plan reverses into the slot and then aims at the target."""
        into_slot = self.parallel and cand.direction < 0 and same_pose(goal, self.g.target)
        margin = 1.0 if self.parallel else self.cfg.mirror_margin
        return -cand.direction, margin, self.g.slot_width if into_slot else None

    def _band(self, cand: Candidate, goal: np.ndarray, ref_real: np.ndarray | None) -> SwitchBand | None:
        """The band's rows about the reference's switch heading (None: no switch)."""
        if cand.switch is None or ref_real is None:
            return None
        th = float(ref_real[cand.switch * self.cfg.model_substeps, XI_TH])
        g = np.array(goal, float)
        g[2] = unwrap_near(g[2], th)
        return switch_band(self.p, g, th, *self._band_args(cand, goal))

    def _outside_band(self, band: bool, cand: Candidate, goal: np.ndarray, real: np.ndarray) -> float:
        """How far [m] a rollout's switch lies outside its band (exact; 0 inside or without one)."""
        if not band or cand.switch is None:
            return 0.0
        pose = real[cand.switch * self.cfg.model_substeps, :3]
        return max(0.0, -band_margin(self.p, goal, pose, *self._band_args(cand, goal)))

    def _score(self, real, u, cand, goal, theta_t, start, line, band: bool, clear_plans: list[Plan]):
        """(reference, colliding (step, obstacle) pairs, usable) of a rollout; a usable one
        (clear by ``check_margin``, its switch in its band) joins ``clear_plans``. The merit
        adds the exact penalty on the switch's distance outside its band."""
        cfg = self.cfg
        pen = self.checks.penetration(real)  # one footprint check per rollout, shared
        hits = self.checks.collisions(real, cfg.check_margin, start, pen)  # closer than that: constrain
        outside = self._outside_band(band, cand, goal, real)
        usable = not hits and outside <= cfg.band_tolerance
        if usable:
            clear_plans.append(self._make_plan(cand, u, real, goal, theta_t, line))
        merit = self.checks.merit(real, goal, theta_t, pen) + band_penalty(cfg, outside)
        return Reference(real, u, pen, merit), hits, usable

    def _safe_stop(self, xi0, cand, ref: Reference, goal, theta_t, start, line) -> Plan | None:
        """The reference's start, braking to a stand before its first contact (None: no contact)."""
        hits = self.checks.collisions(ref.real, 0.0, start, ref.pen)
        return self.checks.safe_prefix(xi0, cand, ref.u, hits, goal, theta_t, start, line) if hits else None

    def _solve(self, qp, disj, active, preferred, work: _Work) -> np.ndarray | None:
        """The QP, or the MIQP (by ``work``'s branch and bound) where there are disjunctions;
        effort counted into ``work`` and taken from the call's budget (None once that is spent)."""
        budget = self.budget
        if budget.spent:
            return None
        if disj:
            res = work.miqp.solve(qp, disj, active, preferred, max_solves=budget.left)
            work.qp_solves += res.qp_solves
            work.nodes += res.nodes
            budget.spend(res.qp_solves)
            work.safety_net = work.safety_net or res.status == "time_limit"
            if res.status == "node_limit":
                work.cut_short = True  # out of nodes: its optimum not proved, perhaps not found
            return res.x
        work.qp_solves += 1
        budget.spend(1)
        return self.qp_solver.solve(qp).x

    def _confirmed(self, xi0: np.ndarray, clear_plans: list[Plan], start: Start) -> Plan | None:
        """The cheapest of the three cheapest clear plans that the truth model confirms."""
        for plan in sorted(clear_plans, key=lambda q: q.cost)[:3]:
            if self.checks.truth_safe(xi0, plan.commands, start):
                return plan
        return None

    def _make_plan(self, cand, u_planned, real_half, goal, theta_t, line) -> Plan:
        real = real_half[:: self.cfg.model_substeps]
        cost, pos_err, th_err = self.checks.true_cost(real, goal, theta_t)
        S = tuple(real[cand.switch, :2]) if cand.switch is not None else None
        planned = to_planned(real_half, cand, self.cfg.model_substeps)
        goal = tuple(float(v) for v in goal[:2]) + (float(theta_t),)
        return Plan(
            real_commands(u_planned, cand), real, cand, S, line, planned, cost, (pos_err, th_err), True, goal=goal
        )


class _Work:
    """One candidate solve's running tallies."""

    def __init__(self, miqp: BranchAndBound):
        self.miqp = miqp
        self.iterations = self.qp_solves = self.nodes = 0
        self.cut_short = self.safety_net = False

    def tally(self) -> Tally:
        return Tally(self.iterations, self.qp_solves, self.nodes)
