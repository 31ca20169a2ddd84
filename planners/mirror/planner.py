"""The mirrored-target planner: one plan = one direction switch (paper II.C-E).

Variables: planned states xi_0..xi_N, controls u_0..u_{N-1}, the switch point S. The planned
motion is monodirectional; at the switch step s the car stands (v_s = 0) and from then on
executes negated commands (Eq. 42), so its real pose is the planned pose reflected
through S: real = (2 S - p, theta) (Theorem 2, ``frames.py``).
Exactly so with the actuator lags too: at s the planned lag states are the real ones
negated, which the dynamics row of step s encodes (``FLIP``). Consequences, all linear
for fixed s (``qp.py``):

- the mirrored target is 2 S - p_target; the cost pulls the planned poses to it, which is
  the real pose error after the switch (and terminal error at N);
- in the natural order S lies in Theorem 1's band (parallel), beyond Eqs. 5-6 (others);
- obstacle constraints are written on the real body: before s on p + R(theta) c, after s
  on 2 S - p + R(theta) c (the flipped body against obstacles reflected through S).

Solving (Algorithm I inside sequential convex programming): a QP without obstacles; the
exact footprint check of the rolled-out plan finds the colliding steps; disjunctive
obstacle rows (Eq. 40, ``obstacles.py``) are added at those steps only, the MIQP solved by
branch and bound; repeat until clear, re-linearising about each rollout (``seeds.py``).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, replace

import numpy as np

from mirrorpark_env.angles import unwrap_near
from mirrorpark_env.scenario import ParkingType, ScenarioGeometry
from mirrorpark_env.vehicle import TruthModel, VehicleState

from ..base import PlanStats
from .checks import Checks, Start, converged_to, same_pose
from .config import MirrorPlannerConfig
from .frames import FLIP, XI_TH, XI_V, XI_X, XI_Y, planned_controls, real_commands, to_planned
from .guide import GuideSearch, prepared_search
from .mirror_line import MirrorLine, SwitchBand, band_margin, mirror_line, switch_band
from .model import PlanningModel
from .obstacles import ObstacleRows
from .plans import Candidate, Plan
from .qp import MirrorQP
from .seeds import GuidedSeed, ShapeSeeds
from .solvers import BranchAndBound, PiqpQP
from .value import cost_to_go
from .value_plan import ValuePlanning


class _PaperModel:
    """Eqs. (22)-(32) for one candidate: about its linearising angle, with a speed per step
    in the v terms. Both start as 1 m/s in the plan's gear about the mean of the start and
    goal headings; ``paper_speed`` / ``paper_angle`` = "previous" take them from each
    round's rollout (the paper leaves the speed open and draws the angle, Fig. 13, "close
    to the average yaw angle of the parking path")."""

    def __init__(self, planner: MirrorPlanner, cand: Candidate, angle: float):
        self.pl, self.cand, self.angle = planner, cand, angle
        self.v = np.full(planner.N, 1.0 * cand.direction)
        self.lin = planner.model.paper_linearisation(planner.N, angle, self.v)
        self.correction: np.ndarray | None = None  # ``paper_correction``: see ``model_error``

    def update(self, real: np.ndarray, x: np.ndarray | None = None) -> bool:
        """Re-linearise about a rollout (half steps, real frame) of the QP's solution ``x``
        (None: a seed); True: nothing moved beyond the config's tolerances (or nothing is
        taken from rollouts)."""
        cfg, d = self.pl.cfg, self.cand.direction
        if cfg.paper_correction != "off" and x is not None:
            self.correction = self.model_error(real, x)
        if cfg.paper_speed == "nominal" and cfg.paper_angle == "ends":
            return True
        planned = to_planned(real, self.cand, cfg.model_substeps)
        settled = True
        if cfg.paper_speed == "previous":  # Eq. (31)'s v_i: the speeds just driven
            v = d * np.maximum(d * planned[: self.pl.N, XI_V], cfg.paper_speed_floor)
            settled = float(np.max(np.abs(v - self.v))) <= cfg.paper_speed_tolerance
            self.v = v
        if cfg.paper_angle == "previous":  # the average yaw of the path just driven
            angle = float(np.mean(planned[:, XI_TH]))
            settled = settled and abs(angle - self.angle) <= cfg.paper_angle_tolerance
            self.angle = angle
        if not settled:
            self.lin = self.pl.model.paper_linearisation(self.pl.N, self.angle, self.v)
        return settled

    def model_error(self, real: np.ndarray, x: np.ndarray) -> np.ndarray:
        """Rollout minus the QP's prediction of x, y, heading and S, in z's layout (the
        slacks left out): what the obstacle rows miss by planning on the linear model."""
        qp, cand = self.pl.qp, self.cand
        err = np.zeros(qp.nz)
        pl = to_planned(real, cand, self.pl.cfg.model_substeps)
        for j in (XI_X, XI_Y, XI_TH):
            err[qp.x_index[:, j]] = pl[:, j] - x[qp.x_index[:, j]]
        if cand.switch is not None:
            err[qp.iS : qp.iS + 2] = pl[cand.switch, :2] - x[qp.iS : qp.iS + 2]
        return err


@dataclass(frozen=True, eq=False)
class _Reference:
    """The rollout SCP linearises about: real states at half steps, planned commands, its
    footprint penetration and merit."""

    real: np.ndarray
    u: np.ndarray
    pen: np.ndarray
    merit: float = math.nan


class MirrorPlanner:
    """Plans toward the mirrored target from a measured vehicle state."""

    def __init__(self, geometry: ScenarioGeometry, config: MirrorPlannerConfig | None = None):
        self.g = geometry
        self.p = geometry.vehicle
        self.cfg = cfg = config or MirrorPlannerConfig()
        self.N = cfg.horizon
        self.model = PlanningModel(self.p, cfg.dt, cfg.model_substeps)
        self.coarse = TruthModel(self.p, cfg.dt, cfg.dt / cfg.model_substeps)
        e = cfg.qp_tolerance
        self.qp_backend = PiqpQP(e, 0.1 * e, kkt_solver=cfg.kkt_solver, eps_gap=(e, 0.1 * e))
        self.miqp = BranchAndBound(self.qp_backend, cfg.node_limit, cfg.time_limit_s)
        self.fallback_miqp = BranchAndBound(self.qp_backend, cfg.fallback_node_limit, cfg.time_limit_s)
        self.scout_miqp = BranchAndBound(self.qp_backend, cfg.value_scout_node_limit, cfg.time_limit_s)
        self._fallbacks = 0  # calls in a row that fell back on the unguided multi-start
        self.line = mirror_line(geometry, margin=cfg.mirror_margin)
        self.qp = MirrorQP(self.p, cfg, ObstacleRows(geometry, cfg.obstacle_margin, cfg.horizon, cfg.model_substeps))
        self.checks = Checks(geometry, cfg)
        self.shape_seeds = ShapeSeeds(geometry, cfg, self.coarse)
        self.guided_seed = GuidedSeed(geometry, cfg, self.coarse)
        self._guide: GuideSearch | None = None  # built by prepare() (the policy: at reset)
        self._value: ValuePlanning | None = None  # the value mode (cfg.value), built by prepare()
        self.last_stats: PlanStats | None = None  # the latest call's, a failed one's too
        parallel = geometry.parking_type is ParkingType.PARALLEL
        by_type = cfg.refine_candidates_parallel if parallel else None
        self._refine_candidates = by_type or cfg.refine_candidates  # the multi-start's, for this slot

    @property
    def guided(self) -> bool:
        """Whether plans follow the geometric guide (SCP linearisation only)."""
        return self.cfg.guide and self.cfg.linearisation == "scp"

    def prepare(self) -> None:
        """Build what depends on the slot alone, once per episode (the policy does it at
        reset, as a car does once it has measured the slot): the guide's tails, shared by
        episodes in the same slot (``guide.prepared_search``)."""
        if self._guide is None and self.guided:
            self._guide = prepared_search(self.g)
        if self._value is None and self.cfg.value:
            self._value = ValuePlanning(self, cost_to_go(self.g, self.cfg.value_lattice))

    # ------------------------------------------------------------------ plan
    def plan(self, state: VehicleState, candidates: list[Candidate] | None = None) -> Plan | None:
        """Best collision-free plan from ``state``, or None.

        Value mode (``cfg.value``, the default ``mirror``): candidates over first gear and
        switch, aimed and compared by a cost to go (``value_plan.py``). Guided: one
        candidate, from the guide; where the guide finds no path from a standing car, the
        unguided multi-start within the fallback budget, on at most ``fallback_calls``
        calls in a row. Otherwise the candidates given, or both gears at two switch steps
        and without a switch, seeded by their classic shapes. Statistics of the call, a
        failed one included, are in ``self.last_stats``.
        """
        t0 = time.perf_counter()
        xi0 = state.as_array()
        start = self.checks.start(xi0)
        if self.cfg.value and candidates is None:
            self.prepare()
            return self._value.plan(state, xi0, start, t0)
        if not self.guided or candidates is not None:
            return self._plan_multistart(state, xi0, start, candidates, t0)
        plan = self._plan_guided(xi0, start, t0)
        if plan is not None:
            self._fallbacks = 0
        elif self.last_stats.status == "no_guide" and abs(state.v) < 0.05 and self._fallbacks < self.cfg.fallback_calls:
            self._fallbacks += 1
            budget = (1, self.cfg.fallback_iterations, self.fallback_miqp)
            plan = self._plan_multistart(state, xi0, start, None, t0, *budget)
        return plan

    def line_from(self, theta: float) -> MirrorLine:
        """The mirror line for a plan from heading ``theta``: Theorem 1's (parallel), else
        Eqs. (5), (6) bound by the heading change still to go."""
        if self.line.fixed:
            return self.line
        psi = min(abs(unwrap_near(self.g.target[2], theta) - theta), math.pi / 2)
        return mirror_line(self.g, psi=psi, margin=self.cfg.mirror_margin)

    def guide_search(self, pose):
        """The guide from ``pose`` (x, y, theta), or None."""
        self.prepare()
        return self._guide.search(pose)

    def _plan_guided(self, xi0: np.ndarray, start: Start, t0: float) -> Plan | None:
        """One plan along the guide's next switch: seed from tracking the guide, then SCP
        toward the mirrored goal (the guide's pose after its second gear segment, or the
        target). None when there is no guide or no clear plan along it."""
        self.prepare()
        guide = self._guide.search(xi0[:3])
        detail = {"guide_cost": guide.cost if guide else math.inf}
        plan = None
        if guide is not None:
            plan, st, cand, goal, tried = self._solve_guided(xi0, guide, start)
            status = "ok"
            if plan is None and st.get("partial") is not None:  # go along the guide as far as is safe
                plan, status = st["partial"], "partial"
            detail["safety_net"] = st.get("safety_net", False)
        if plan is None:
            status = "infeasible" if guide is not None else "no_guide"
            self.last_stats = PlanStats(time.perf_counter() - t0, status, detail=detail)
            return None
        detail = {
            "candidates": tried,
            "guided": True,
            "goal": tuple(round(float(v), 3) for v in goal),
            **detail,
        }
        stats = PlanStats(
            time.perf_counter() - t0, status, st["iterations"], st["qp_solves"], st["nodes"], plan.cost, detail
        )
        self.last_stats = stats
        return replace(plan, stats=stats)

    def _solve_guided(self, xi0: np.ndarray, guide, start: Start):
        """The guided candidate, and for a plan with a switch the same manoeuvre seeded at
        the other ``switch_speeds`` (other switch steps, same goal): the plan of lowest
        optimal cost wins. Returns (plan or None, statistics, candidate, goal, tried)."""
        cand, seed, goal = self.guided_seed.seed(xi0, guide)
        variants = [(cand, seed)]
        if cand.switch is not None:
            for v in self.cfg.switch_speeds:
                c2, s2, g2 = self.guided_seed.seed(xi0, guide, v)
                if c2.switch is not None and np.allclose(g2, goal) and all(c2 != c for c, _ in variants):
                    variants.append((c2, s2))
        natural = cand.direction == self.shape_seeds.first_direction  # the order of the paper's mirror line
        best = best_st = None
        tried, totals, net = [], {"iterations": 0, "qp_solves": 0, "nodes": 0}, False
        for c, seed in variants:
            plan, st = self.solve_candidate(
                xi0, c, goal, start, self.line, seed, iterations=self.cfg.guide_iterations, band=natural
            )
            for k in ("iterations", "qp_solves", "nodes"):
                totals[k] += st[k]
            net = net or st.get("safety_net", False)
            tried.append((c, None if plan is None else round(plan.cost, 3), st["status"]))
            if best_st is None or (plan is not None and (best is None or plan.cost < best.cost)):
                best, best_st, cand = plan, st, c
        return best, {**best_st, **totals, "safety_net": net}, cand, goal, tried

    def _plan_multistart(
        self,
        state: VehicleState,
        xi0: np.ndarray,
        start: Start,
        candidates: list[Candidate] | None,
        t0: float,
        refine: int | None = None,
        iterations: int | None = None,
        miqp: BranchAndBound | None = None,
    ) -> Plan | None:
        """The best plan over the candidates' shape seeds, refined by SCP (budget: ``refine``
        candidates, ``iterations`` rounds each and ``miqp``'s nodes; default the config's)."""
        line = self.line_from(state.theta)
        goal = np.array(self.g.target, float)
        theta_t = unwrap_near(goal[2], state.theta)
        seeds = self.shape_seeds.ranked(
            xi0,
            candidates or self.shape_seeds.candidates(state, line),
            line,
            lambda real: self.checks.merit(real, goal, theta_t),
        )
        stay = self.checks.merit(np.repeat(xi0[None], self.cfg.model_substeps * self.N + 1, axis=0), goal, theta_t)
        best = partial = None
        totals = {"iterations": 0, "qp_solves": 0, "nodes": 0}
        net = False
        tried = []
        for n, (cand, seed) in enumerate(seeds):
            if n >= (refine or self._refine_candidates) and best is not None and best.cost < 0.9 * stay:
                break  # refine the best few; go on down the list while none is clear and progressing
            plan, st = self.solve_candidate(xi0, cand, goal, start, line, seed, iterations, miqp=miqp)
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
        return self.finish(t0, status, totals, best.cost if best else math.nan, detail, best)

    def finish(self, t0: float, status: str, totals: dict, cost: float, detail: dict, best: Plan | None):
        """Record a call's statistics (``last_stats``) and return its plan carrying them."""
        stats = PlanStats(
            time.perf_counter() - t0, status, totals["iterations"], totals["qp_solves"], totals["nodes"], cost, detail
        )
        self.last_stats = stats
        return replace(best, stats=stats) if best is not None else None

    # ------------------------------------------------------------- candidate
    def solve_candidate(
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
    ) -> tuple[Plan | None, dict]:
        """SCP with Algorithm I inside, for one (direction, switch step) candidate toward ``goal``.

        Each round linearises about the reference rollout, adds the disjunctive obstacle
        rows of every step the reference collides at (Algorithm I), and solves. The
        rollout of the solution replaces the reference only if it lowers the merit (true
        cost plus the exact penalty on penetration); otherwise the trust-region penalty
        is raised and the round repeats. Without improvement possible, the search stops.
        ``band``: the switch lies in the band of ``switch_band`` toward ``goal`` (linearised
        at each reference); otherwise on ``line`` in the natural order. ``miqp``: the
        branch and bound to use (default the planner's). Returns the plan (None if no
        clear one is confirmed by the truth model) and the candidate's statistics, with
        ``"partial"``: a safe stop short of the first contact, where there is one.
        """
        cfg = self.cfg
        theta_t = unwrap_near(goal[2], xi0[XI_TH])
        terminal = self.checks.terminal_toward(goal)
        c = self.qp.cost(cand, goal, theta_t, terminal)
        theta_set: dict[tuple[int, int], None] = {}  # (step, obstacle) pairs with obstacle rows
        clear_plans: list[Plan] = []  # clear on the planning model; verified on the truth model at the end
        st = {"iterations": 0, "qp_solves": 0, "nodes": 0, "status": "failed"}
        paper = cfg.linearisation == "paper"
        mirror = cand.direction == self.shape_seeds.first_direction and not band
        ref: _Reference | None = None
        if paper:  # the paper's scheme: one model about a fixed angle, Algorithm I until clear
            # (and, where its speeds or angle come from the last rollout, until they settle)
            paper_model = _PaperModel(self, cand, 0.5 * (xi0[XI_TH] + theta_t))
            if cfg.paper_first == "seed" and seed is not None:
                paper_model.update(seed)  # the seed's rollout as round zero
            lin = paper_model.lin
        else:
            # Seed: a moving reference of the manoeuvre's shape. (The paper's form,
            # Eqs. 22-27, moves the car at its nominal speed even where the real speed is
            # zero; linearising about that standstill would freeze the heading.)
            real = seed if seed is not None else self.shape_seeds.seed(xi0, cand, line)
            u = planned_controls(real, cand, self.p, cfg.dt, cfg.model_substeps)
            # The seed is a plan too.
            ref, _, _ = self._score(real, u, cand, goal, theta_t, start, line, band, clear_plans)
        trust_scale = 1.0
        correction = None  # paper_correction: the last round's model error at each row
        rounds = cfg.max_iterations if iterations is None else iterations
        for it in range(cfg.max_iterations):
            if it >= rounds and (clear_plans or not band):
                break  # a switch outside its band: more rounds (to max_iterations) to move it in
            st["iterations"] += 1
            if not paper:
                lin = self._linearise(ref, cand, theta_set, start)
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
                not paper,
                mirror=mirror,
                trust_scale=trust_scale,
                band=rows,
                terminal=terminal,
                correction=correction,
            )
            x = self._solve(qp, disj, active, preferred, st, miqp or self.miqp)
            if x is None:
                st["status"] = "infeasible"
                break
            u_planned = x[self.qp.u_index]
            real = self._rollout(xi0, u_planned, cand)
            new, hits, usable = self._score(real, u_planned, cand, goal, theta_t, start, line, band, clear_plans)
            for i, k in hits:  # Algorithm I on the new solution too, accepted or not
                theta_set[(i, k)] = None
            if paper:
                settled = paper_model.update(real, x)
                correction = paper_model.correction
                lin = paper_model.lin
                if not hits and settled:
                    break
                ref = new
                continue
            if new.merit < ref.merit - 1e-6:
                converged = converged_to(real, ref.real, cfg)
                ref = new
                trust_scale = max(trust_scale / 2.0, 0.25)
                if usable and (converged or self.checks.settled(real, goal, theta_t)):
                    st["converged"] = True  # not stopped by the round cap (the value mode refines on)
                    break
            else:
                trust_scale *= 4.0
                if trust_scale > cfg.max_trust_scale:
                    break
        best = self._confirmed(xi0, clear_plans, start)
        if best is not None:
            st["status"] = "ok"
        elif ref is not None:  # no clear plan: the best iterate's safe start, if any
            st["partial"] = self._safe_stop(xi0, cand, ref, goal, theta_t, start, line)
        return best, st

    def _band_args(self, cand: Candidate, goal: np.ndarray) -> tuple[int, float, float | None]:
        """(gear after the switch, margin, slot width or None) of a plan's switch band: the
        reach bound (Eqs. 1, 5, 6) toward the plan's goal, and Theorem 1's kerb bound
        (Eq. 2) where a parallel plan reverses into the slot and then aims at the target."""
        parallel = self.line.fixed  # Theorem 1's line: parallel parking
        into_slot = parallel and cand.direction < 0 and self._is_target(goal)
        margin = 1.0 if parallel else self.cfg.mirror_margin
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

    def _is_target(self, goal: np.ndarray) -> bool:
        return same_pose(goal, self.g.target)

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
        merit = self.checks.merit(real, goal, theta_t, pen) + cfg.w_slack * outside
        return _Reference(real, u, pen, merit), hits, usable

    def _safe_stop(self, xi0, cand, ref: _Reference, goal, theta_t, start, line) -> Plan | None:
        """The reference's start, braking to a stand before its first contact (None: no contact)."""
        hits = self.checks.collisions(ref.real, 0.0, start, ref.pen)
        return self.checks.safe_prefix(xi0, cand, ref.u, hits, goal, theta_t, start, line) if hits else None

    def _linearise(self, ref: _Reference, cand: Candidate, theta_set: dict, start: Start):
        """Algorithm I on the reference (its colliding steps join ``theta_set``), then the
        exact Jacobians about it, in the planned frame."""
        for i, k in self.checks.collisions(ref.real, 0.0, start, ref.pen):
            theta_set[(i, k)] = None
        lin_at = to_planned(ref.real, cand, self.cfg.model_substeps)
        if cand.switch is not None:  # step s starts from the flipped lag states
            lin_at[cand.switch] = FLIP @ lin_at[cand.switch]
        return self.model.jacobian_linearisation(lin_at, ref.u)

    def _solve(self, qp, disj, active, preferred, st: dict, miqp: BranchAndBound) -> np.ndarray | None:
        """The QP, or the MIQP (by ``miqp``) where there are disjunctions; effort counted into ``st``."""
        if disj:
            res = miqp.solve(qp, disj, active, preferred)
            st["qp_solves"] += res.qp_solves
            st["nodes"] += res.nodes
            st["safety_net"] = st.get("safety_net", False) or res.status == "time_limit"
            if res.status == "node_limit":
                st["cut_short"] = True  # out of nodes: its optimum not proved, perhaps not found
            return res.x
        st["qp_solves"] += 1
        return self.qp_backend.solve(qp).x

    def _confirmed(self, xi0: np.ndarray, clear_plans: list[Plan], start: Start) -> Plan | None:
        """The cheapest of the three cheapest clear plans that the truth model confirms."""
        for plan in sorted(clear_plans, key=lambda q: q.cost)[:3]:
            if self.checks.truth_safe(xi0, plan.commands, start):
                return plan
        return None

    def _rollout(self, xi0: np.ndarray, u_planned: np.ndarray, cand: Candidate) -> np.ndarray:
        """Real states at every half step: (2N + 1, 6); even rows are the control steps."""
        sub = self.coarse.rollout(xi0, real_commands(u_planned, cand))[:, :6]
        return np.concatenate([xi0[None], sub])

    def rollout(self, xi0: np.ndarray, u_planned: np.ndarray, cand: Candidate) -> np.ndarray:
        """Real states at the control steps when executing planned commands (Eq. 42 after the switch)."""
        return self._rollout(xi0, u_planned, cand)[:: self.cfg.model_substeps]

    def _make_plan(self, cand, u_planned, real_half, goal, theta_t, line) -> Plan:
        real = real_half[:: self.cfg.model_substeps]
        cost, pos_err, th_err = self.checks.true_cost(real, goal, theta_t)
        S = tuple(real[cand.switch, :2]) if cand.switch is not None else None
        planned = to_planned(real_half, cand, self.cfg.model_substeps)
        goal = tuple(float(v) for v in goal[:2]) + (float(theta_t),)
        return Plan(
            real_commands(u_planned, cand), real, cand, S, line, planned, cost, (pos_err, th_err), True, goal=goal
        )
