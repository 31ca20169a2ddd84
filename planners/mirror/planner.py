"""The mirrored-target planner: one plan = one direction switch (paper II.C-E, DESIGN 4-5).

Decision variables: planned states xi_0..xi_N, controls u_0..u_{N-1}, and the switch
point S. The planned motion is monodirectional; at the switch step s the car stands
(v_s = 0) and from then on executes negated commands (Eq. 42), so its real pose is the
planned pose reflected through S: real = (2 S - p, theta) (Theorem 2). Exactly so with
the actuator lags too: at s the planned lag states are the real ones negated, which the
dynamics row of step s encodes (``flip``). Consequences, all linear for fixed s:

- the mirrored target is 2 S - p_target; the cost pulls the planned poses to it, which is
  the real pose error after the switch (and terminal error at N);
- S lies on the mirror line (parallel) or beyond its lower bound (reverse, angle);
- obstacle constraints are written on the real body: before s on p + R(theta) c, after s
  on 2 S - p + R(theta) c (the flipped body against obstacles reflected through S).

Solving (Algorithm I inside sequential convex programming): a QP without obstacles; the
exact footprint check of the rolled-out plan finds the colliding steps; disjunctive
obstacle constraints (Eq. 40) are added at those steps only and the MIQP is solved by
branch-and-bound; repeat until the plan is clear, re-linearising about each rollout.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace
from typing import Literal

import numpy as np
import scipy.sparse as sp

from mirrorpark_env.scenario import ParkingType, ScenarioGeometry
from mirrorpark_env.vehicle import TruthModel, VehicleState

from ..base import PlanStats
from ..hybrid_astar.search import Path
from ..hybrid_astar.tracker import PathTracker, TrackerConfig
from .guide import Guide, GuideSearch
from .mirror_line import MirrorLine, mirror_line
from .model import NU, NX, PlanningModel
from .solvers import INACTIVE, QP, BranchAndBound, CscPattern, Disjunction, PiqpQP

XI_X, XI_Y, XI_TH, XI_V, XI_A, XI_D = range(6)
_COST_PATTERNS: dict[MirrorPlannerConfig, dict[int | None, tuple]] = {}  # they depend on the config alone
CHECK_MARGIN = 0.01  # [m] a planning-model rollout closer than this to an obstacle is not clear
START_RELIEF = 0.5  # [m] around a start closer than a margin, only its own gap is kept ...
START_SLACK = 0.0005  # [m] ... less this much
FLIP = np.diag([1.0, 1.0, 1.0, -1.0, -1.0, -1.0])  # planned <- real lag states at the switch
TURN = math.inf  # seed mode: steer toward the target heading in both segments


@dataclass(frozen=True)
class MirrorPlannerConfig:
    """Weights, limits and solver settings of the mirrored-target planner."""

    horizon: int = 60  # N (Table II)
    dt: float = 0.1
    model_substeps: int = 2
    linearisation: Literal["scp", "paper"] = "scp"
    max_iterations: int = 6  # SCP + Algorithm I rounds per candidate
    max_trust_scale: float = 64.0  # give up on a candidate when the trust penalty grows past this
    w_trust_position: float = 0.5  # SCP trust region, as a penalty per m^2 of planned x, y moved
    w_trust_heading: float = 2.0  # ... and per rad^2 of heading
    converge_position: float = 0.02  # [m] SCP stops when the rollout moves less
    converge_heading: float = 0.01  # [rad]
    settle_position: float = 0.06  # [m] ... or when a clear rollout ends this close to its goal
    settle_heading: float = 0.02  # [rad] (0: never)
    w_position: float = 0.2  # running cost per m^2 toward the mirrored target
    w_heading: float = 0.2  # per rad^2
    w_terminal_position: float = 400.0
    w_terminal_heading: float = 400.0
    w_terminal_accel: float = 1.0
    w_accel_cmd: float = 0.02
    w_steer_cmd: float = 0.05
    w_accel_rate: float = 0.5
    w_steer_rate: float = 2.0
    obstacle_margin: float = 0.04  # [m] planned clearance to infeasible regions
    w_slack: float = 1e5  # exact penalty per m of obstacle-row violation (rows are soft)
    mirror_margin: float = 1.1  # reverse / angle: l_mi >= margin * r_min (1 - cos psi)
    node_limit: int = 3
    kkt_solver: Literal["sparse_ldlt", "sparse_multistage", "auto"] = "auto"  # piqp's (solvers.PiqpQP)
    qp_tolerance: float = 1e-4  # piqp's absolute residual and duality-gap tolerance (relative: a tenth)
    seed_swings: tuple[float, ...] = (-0.8, -0.4, 0.4, 0.8)  # [rad] heading excursions tried as seeds
    refine_candidates: int = 2  # candidates refined by SCP after the seed search
    time_limit_s: float = 0.5
    guide: bool = True  # seed each plan from a geometric guide (guide.py); SCP only
    guide_iterations: int = 2  # SCP rounds on a guided candidate
    fallback: bool = False  # without a guide, the multi-start search of manoeuvre shapes
    seed_speed: float = 1.5  # [m/s] cruise speed of the guided seed rollout
    seed_accel: float = 1.5  # [m/s^2] its acceleration and planned deceleration


@dataclass(frozen=True)
class Candidate:
    direction: int  # +1: forward first, -1: reverse first
    switch: int | None  # switch step s, None for a plan without a switch


@dataclass(frozen=True, eq=False)
class Plan:
    """A plan in the real frame, ready to execute."""

    commands: np.ndarray  # (N, 2) real a_cmd, delta_cmd (negated after the switch)
    states: np.ndarray  # (N + 1, 6) predicted real states at the control steps
    candidate: Candidate
    switch_point: tuple[float, float] | None
    mirror: MirrorLine
    planned_states: np.ndarray  # (N + 1, 6) the monodirectional, mirror-frame states
    cost: float
    terminal_error: tuple[float, float]  # [m], [rad] predicted real error at step N
    collision_free: bool
    stats: PlanStats = field(default=None)  # type: ignore[assignment]


class MirrorPlanner:
    """Plans toward the mirrored target from a measured vehicle state."""

    def __init__(self, geometry: ScenarioGeometry, config: MirrorPlannerConfig | None = None, miqp=None):
        self.g = geometry
        self.p = geometry.vehicle
        self.cfg = cfg = config or MirrorPlannerConfig()
        self.N = cfg.horizon
        self.model = PlanningModel(self.p, cfg.dt, cfg.model_substeps)
        self.coarse = TruthModel(self.p, cfg.dt, cfg.dt / cfg.model_substeps)
        self.truth = TruthModel(self.p, cfg.dt, 0.01)
        e = cfg.qp_tolerance
        self.qp_backend = PiqpQP(e, 0.1 * e, kkt_solver=cfg.kkt_solver, eps_gap=(e, 0.1 * e))
        self.miqp = miqp or BranchAndBound(self.qp_backend, cfg.node_limit, cfg.time_limit_s)
        self.line = mirror_line(geometry, margin=cfg.mirror_margin)
        self._goal = np.array(geometry.target, float)  # the goal of the plan being made
        self._start = (0.0, 0.0, math.inf)  # (x, y, gap) of the call's start, for _clearance
        self._guide: GuideSearch | None = None  # built by prepare() (the policy: at reset)
        self._guide_detail: dict = {}  # the last guide search's cost, reported with each call
        self._tracker_cfg = TrackerConfig(cruise_speed=cfg.seed_speed, accel=cfg.seed_accel, decel=cfg.seed_accel)
        self._faces, self._vertices = _useful_features(geometry)
        p = self.p
        hw = 0.5 * p.width
        mid = 0.5 * (p.front_length - p.rear_overhang)
        self.points = np.array(
            [
                [p.front_length, hw],
                [p.front_length, -hw],
                [-p.rear_overhang, -hw],
                [-p.rear_overhang, hw],
                [mid, hw],
                [mid, -hw],
            ]
        )  # the paper's six feature points: corners and the middles of the long sides
        # Car faces as (body normal, offset): front, rear, left, right.
        self.car_faces = (
            (np.array([1.0, 0.0]), p.front_length),
            (np.array([-1.0, 0.0]), p.rear_overhang),
            (np.array([0.0, 1.0]), hw),
            (np.array([0.0, -1.0]), hw),
        )
        N = self.N
        # Variables stage by stage (xi_0, u_0, xi_1, u_1, ..., xi_N), then S: the layout
        # piqp's multistage KKT solver exploits (docs/mirror_planner.md, "Sparse QP").
        self.iS = (NX + NU) * N + NX
        self.nz = self.iS + 2
        self.x_index = (NX + NU) * np.arange(N + 1)[:, None] + np.arange(NX)  # z[x_index]: (N + 1, NX)
        self.u_index = (NX + NU) * np.arange(N)[:, None] + NX + np.arange(NU)  # z[u_index]: (N, NU)
        self._dyn_pattern()
        self._trust = self._trust_diag()
        self._eq_patterns: dict[int, CscPattern] = {}  # per switch-link step
        self._g_line: sp.csc_matrix | None = None  # G of a QP without obstacle rows
        self._bounds: dict[tuple[int, int | None], tuple[np.ndarray, np.ndarray]] = {}  # per (direction, switch)
        self._cost_cache = _COST_PATTERNS.setdefault(cfg, {})  # per switch step; shared by episodes
        self.last_stats: PlanStats | None = None  # the latest call's, a failed one's too

    # --------------------------------------------------------------- indices
    def ix(self, i: int, j: int) -> int:
        return (NX + NU) * i + j

    def iu(self, i: int, j: int) -> int:
        return (NX + NU) * i + NX + j

    def _dyn_pattern(self) -> None:
        """Triplet pattern of the equality rows: initial state, dynamics, switch link."""
        N = self.N
        rows, cols = [], []
        for j in range(NX):
            rows.append(j), cols.append(self.ix(0, j))
        r0 = NX
        for i in range(N):
            for a in range(NX):
                r = r0 + NX * i + a
                rows.append(r), cols.append(self.ix(i + 1, a))
                for b in range(NX):
                    rows.append(r), cols.append(self.ix(i, b))
                for b in range(NU):
                    rows.append(r), cols.append(self.iu(i, b))
        self._n_dyn_rows = NX + NX * N
        self._dyn_rows = np.array(rows)
        self._dyn_cols = np.array(cols)

    # ------------------------------------------------------------------ plan
    def plan(self, state: VehicleState, candidates: list[Candidate] | None = None) -> Plan | None:
        """Best collision-free plan over ``candidates`` (default: ``self.candidates``), or None.

        Statistics of the call, a failed one included, are in ``self.last_stats``.
        """
        t0 = time.perf_counter()
        xi0 = state.as_array()
        self._goal = np.array(self.g.target, float)
        gap0 = -float(self.g.checker.penetration(xi0[:1], xi0[1:2], xi0[2:3]).max())
        self._start = (float(xi0[0]), float(xi0[1]), gap0)
        if self.cfg.guide and self.cfg.linearisation == "scp" and candidates is None:
            plan = self._plan_guided(xi0, t0)
            if plan is not None or not self.cfg.fallback:
                if plan is None:
                    found = math.isfinite(self._guide_detail.get("guide_cost", math.inf))
                    self.last_stats = PlanStats(
                        time.perf_counter() - t0, "infeasible" if found else "no_guide", detail=self._guide_detail
                    )
                return plan
        if not self.line.fixed:  # Eqs. (5), (6): bound by the heading change still to go
            psi = min(abs(_unwrap_near(self.g.target[2], state.theta) - state.theta), math.pi / 2)
            self.line = mirror_line(self.g, psi=psi, margin=self.cfg.mirror_margin)
        seeds = self._seed_search(xi0, candidates or self.candidates(state))
        best: Plan | None = None
        totals = {"iterations": 0, "qp_solves": 0, "nodes": 0}
        tried = []
        theta_t = _unwrap_near(self.g.target[2], state.theta)
        stay = self._merit(np.repeat(xi0[None], 2 * self.N + 1, axis=0), theta_t)
        partial: Plan | None = None
        for n, (cand, seed) in enumerate(seeds):
            if n >= self.cfg.refine_candidates and best is not None and best.cost < 0.9 * stay:
                break  # refine the best few; go on down the list while none is clear and progressing
            plan, st = self._solve_candidate(xi0, cand, seed)
            for k in totals:
                totals[k] += st[k]
            tried.append((cand, None if plan is None else round(plan.cost, 3), st["status"]))
            if plan is not None and plan.collision_free and (best is None or plan.cost < best.cost):
                best = plan
            p_ = st.get("partial")
            if p_ is not None and (partial is None or p_.cost < partial.cost):
                partial = p_
        status = "ok" if best is not None else "infeasible"
        if partial is not None and partial.cost < 0.98 * min(stay, best.cost if best else math.inf):
            best, status = partial, "partial"  # no full plan progresses: go as far as is safe
        stats = PlanStats(
            time.perf_counter() - t0,
            status,
            totals["iterations"],
            totals["qp_solves"],
            totals["nodes"],
            best.cost if best else math.nan,
            {"candidates": tried, "stay_cost": stay, "guided": False, **self._guide_detail},
        )
        self.last_stats = stats
        return replace(best, stats=stats) if best is not None else None

    # ----------------------------------------------------------------- guided
    def prepare(self) -> None:
        """Build what depends on the slot alone, once per episode (the policy does it at
        reset, as a car does once it has measured the slot): the guide's tails."""
        if self._guide is None and self.cfg.guide and self.cfg.linearisation == "scp":
            self._guide = GuideSearch(self.g)
            self._guide.road_tails()

    def _plan_guided(self, xi0: np.ndarray, t0: float) -> Plan | None:
        """One plan along the guide's next switch: seed from tracking the guide, then SCP
        toward the mirrored goal (the guide's pose after its second gear segment, or the
        target). None when there is no guide or no clear plan along it."""
        self.prepare()
        guide = self._guide.search(xi0[:3])
        self._guide_detail = {"guide_cost": guide.cost if guide else math.inf}
        if guide is None:
            return None
        cand, seed, goal = self._guided_seed(xi0, guide)
        self._goal = goal
        plan, st = self._solve_candidate(xi0, cand, seed, iterations=self.cfg.guide_iterations, free_switch=True)
        status = "ok"
        if plan is None and st.get("partial") is not None:  # go along the guide as far as is safe
            plan, status = st["partial"], "partial"
        if plan is None:
            self._goal = np.array(self.g.target, float)
            return None
        stats = PlanStats(
            time.perf_counter() - t0,
            status,
            st["iterations"],
            st["qp_solves"],
            st["nodes"],
            plan.cost,
            {
                "candidates": [(cand, round(plan.cost, 3), st["status"])],
                "guided": True,
                "goal": tuple(round(float(v), 3) for v in goal),
                **self._guide_detail,
            },
        )
        self.last_stats = stats
        return replace(plan, stats=stats)

    def _guided_seed(self, xi0: np.ndarray, guide: Guide):
        """(candidate, real rollout at half steps, goal pose) from tracking the guide's
        first two gear segments on the planning model, cut so that the car stands by N."""
        poses = guide.path.poses
        end = guide.first_switch()
        for _ in range(3):
            path = Path.from_poses(poses[: end + 1])
            real, segs, reached = self._track(xi0, path)
            if segs[-1] < 0 or reached[-1] >= end:  # stood at the portion's end within N
                break
            back = max(0, self.N - 20)  # cut where the car was 2 s before the horizon
            end = max(reached[back], 2)
        gear = path.direction[1]
        seg = np.asarray(segs)
        s = int(np.argmax(seg >= 1)) if (seg >= 1).any() else None
        if s is not None and (s < 2 or s > self.N - 2):
            s = None
        goal = self._goal.copy() if end >= len(poses) - 1 else poses[end].copy()
        goal[2] = _unwrap_near(goal[2], xi0[XI_TH])
        return Candidate(int(gear), s), real, goal

    def _track(self, xi0: np.ndarray, path: Path):
        """Roll the planning model out under a path tracker for N steps: the half-step real
        states, the tracker's segment per control step (-1 once done), the pose index reached."""
        tracker = PathTracker(path, self.p, self._tracker_cfg)
        state = tuple(float(v) for v in xi0[:6])
        out, segs, reached = [(*state, 0.0)], [0], [0]
        command, step = tracker.command_at, self.coarse.step_rows
        for _ in range(self.N):
            sub = step(state, *command(*state))
            out += sub
            state = sub[-1][:6]
            segs.append(-1 if tracker.done else tracker.seg)
            reached.append(tracker.j)
        return np.array(out)[:, :6], segs, reached

    @property
    def first_direction(self) -> int:
        """Parallel parking reverses to the mirror line first; reverse and angle drive forward."""
        return -1 if self.g.parking_type is ParkingType.PARALLEL else 1

    def _seed(self, xi0: np.ndarray, cand: Candidate, swing: float | None = None) -> np.ndarray:
        """A real rollout of the manoeuvre's classic shape, to linearise about first.

        Speed: a sine over each segment, sized to the distance the segment has to cover.
        Steering: a heading controller tracking a reference; for parallel parking an
        S-curve reversing to the mirror line then forward to the target heading, for
        reverse and angle parking forward toward the switch heading, then full lock back.
        """
        N, dt, p = self.N, self.cfg.dt, self.p
        s = cand.switch if cand.switch is not None else N
        tx, ty, tth = self.g.target
        tth = _unwrap_near(tth, xi0[XI_TH])
        ln = self.line
        u_t = np.array([math.cos(tth), math.sin(tth)])
        S_guess = np.array([tx, ty]) + ln.distance * np.array(ln.normal)
        if not ln.fixed:  # reverse, angle: out along the slot axis to the car's lane
            lam = (xi0[XI_Y] - S_guess[1]) / u_t[1] if abs(u_t[1]) > 1e-6 else 0.0
            S_guess = S_guess + max(lam, 0.0) * u_t
        p0 = xi0[:2]
        d1 = (
            float(np.hypot(*(S_guess - p0))) + 0.3
            if cand.switch is not None
            else float(np.hypot(tx - p0[0], ty - p0[1]))
        )
        d2 = float(np.hypot(S_guess[0] - tx, S_guess[1] - ty)) + 0.3
        T1, T2 = max(s, 1) * dt, max(N - s, 1) * dt
        vc1 = min(1.5, d1 * math.pi / (2 * T1))
        vc2 = min(1.5, d2 * math.pi / (2 * T2))
        psi = ln.psi if ln.fixed else 0.0
        th0 = xi0[XI_TH]
        first = cand.direction == self.first_direction
        out = [xi0]
        state = xi0.copy()
        for i in range(N):
            seg1 = cand.switch is None or i < s
            tau = (i + 1) / s if seg1 else (i + 1 - s) / max(N - s, 1)
            d = cand.direction if seg1 else -cand.direction
            v_ref = d * (vc1 if seg1 else vc2) * math.sin(math.pi * min(tau, 1.0))
            if cand.switch is None:
                th_ref = tth
            elif seg1 and swing == TURN:  # both segments rotate toward the target: a 3-point turn
                th_ref = tth
            elif seg1 and swing is not None:  # multi-start: a heading excursion before the switch
                th_ref = th0 + swing * math.sin(0.5 * math.pi * min(tau, 1.0))
            elif seg1:
                if self.g.parking_type is ParkingType.PARALLEL and first:
                    th_ref = tth + 0.7 * math.sin(math.pi * tau) + psi * tau  # the S-curve's swing
                elif first:
                    th_ref = th0 + (tth - ln.psi - th0) * tau  # toward the switch heading
                else:
                    th_ref = th0
            else:
                th_ref = tth + psi * (1 - tau) if first and ln.fixed else tth
            a_cmd = max(p.a_min, min(p.a_max, 3.0 * (v_ref - state[XI_V]) - 0.5 * state[XI_A]))
            sgn = 1.0 if v_ref >= 0 else -1.0
            d_cmd = max(-p.max_steer, min(p.max_steer, 2.5 * (th_ref - state[XI_TH]) * sgn))
            sub = self.coarse.step(state, a_cmd, d_cmd)[:, :6]
            out.extend(sub)
            state = sub[-1]
        return np.array(out)

    def candidates(self, state: VehicleState) -> list[Candidate]:
        """(direction, switch step) pairs the seed search scores: both directions, two switch
        steps, and no switch."""
        first = self.first_direction
        if abs(state.v) > 0.1:
            dirs = [1 if state.v > 0 else -1]
        else:
            dirs = [first, -first]
        s_est = self._switch_estimate(state)
        steps = sorted({s_est, min(self.N - 15, max(12, int(1.6 * s_est)))})
        out = [Candidate(d, s) for d in dirs for s in steps]
        out += [Candidate(d, None) for d in dirs]  # no switch: straight on to the target
        return out

    def _switch_estimate(self, state: VehicleState) -> int:
        off = self.line.offset((state.x, state.y))
        dist = abs(self.line.distance - off) + 0.5
        t = 2.0 * math.sqrt(dist / 1.0)  # accelerate then brake at about 1 m/s^2
        return int(min(max(round(t / self.cfg.dt), 8), self.N - 20))

    # ------------------------------------------------------------- candidate
    def _seed_search(self, xi0: np.ndarray, cands: list[Candidate]):
        """Multi-start: roll out each candidate's seed shapes, keep the best few by merit.

        A rollout costs about a millisecond, a candidate's SCP tens: the cheap search
        decides which direction, switch step and heading excursion the SCP refines.
        """
        theta_t = _unwrap_near(self.g.target[2], xi0[XI_TH])
        scored = []
        for cand in cands:
            swings = [None] if cand.switch is None else [None, TURN, *self.cfg.seed_swings]
            for sw in swings:
                real = self._seed(xi0, cand, sw)
                scored.append((self._merit(real, theta_t), cand, real))
        scored.sort(key=lambda t: t[0])
        out, seen = [], set()
        for _, cand, real in scored:
            if cand not in seen:  # the best seed of each candidate, best candidates first
                seen.add(cand)
                out.append((cand, real))
        return out

    def _solve_candidate(
        self,
        xi0: np.ndarray,
        cand: Candidate,
        seed: np.ndarray | None = None,
        iterations: int | None = None,
        free_switch: bool = False,
    ):
        """SCP with Algorithm I inside, for one (direction, switch step) candidate.

        Each round linearises about the reference rollout, adds the disjunctive obstacle
        rows of every step the reference collides at (Algorithm I), and solves. The
        rollout of the solution replaces the reference only if it lowers the merit (true
        cost plus the exact penalty on penetration); otherwise the trust-region penalty
        is raised and the round repeats. Without improvement possible, the search stops.
        """
        cfg, N = self.cfg, self.N
        theta_t = _unwrap_near(self._goal[2], xi0[XI_TH])
        c = self._cost(cand, theta_t)
        theta_set: dict[tuple[int, int], None] = {}
        best: Plan | None = None
        clear_plans: list[Plan] = []  # clear on the planning model; verified on the truth model at the end
        st = {"iterations": 0, "qp_solves": 0, "nodes": 0, "status": "failed"}
        paper = cfg.linearisation == "paper"
        if paper:
            ref_real, ref_u, ref_pen = None, None, None
            lin = self.model.paper_linearisation(N, 0.5 * (xi0[XI_TH] + theta_t), 1.0 * cand.direction)
        else:
            # Seed: a moving reference of the manoeuvre's shape. (The paper's form,
            # Eqs. 22-27, moves the car at its nominal speed even where the real speed is
            # zero; linearising about that standstill would freeze the heading.)
            ref_real = seed if seed is not None else self._seed(xi0, cand)
            ref_u = self._planned_controls(ref_real, cand)
            ref_pen = self._penetration(ref_real)  # one footprint check per rollout, shared
            ref_merit = self._merit(ref_real, theta_t, ref_pen)
            if not self._collisions(ref_real, CHECK_MARGIN, ref_pen):
                clear_plans.append(self._make_plan(cand, ref_u, ref_real, theta_t, True))  # the seed is a plan too
        trust_scale = 1.0
        for it in range(cfg.max_iterations if iterations is None else iterations):
            st["iterations"] += 1
            if not paper:
                for i, k in self._collisions(ref_real, 0.0, ref_pen):  # Algorithm I
                    theta_set[(i, k)] = None
                lin_at = self._to_planned(ref_real, cand)
                if cand.switch is not None:  # step s starts from the flipped lag states
                    lin_at[cand.switch] = FLIP @ lin_at[cand.switch]
                lin = self.model.jacobian_linearisation(lin_at, ref_u)
            qp, disj, active, preferred = self._build(
                xi0,
                cand,
                theta_t,
                c,
                lin,
                ref_real,
                theta_set,
                not paper,
                mirror=cand.direction == self.first_direction and not free_switch,
                trust_scale=trust_scale,
            )
            if disj:
                res = self.miqp.solve(qp, disj, active, preferred)
                st["qp_solves"] += res.qp_solves
                st["nodes"] += res.nodes
                x = res.x
            else:
                r = self.qp_backend.solve(qp)
                st["qp_solves"] += 1
                x = r.x
            if x is None:
                st["status"] = "infeasible"
                break
            u_planned = x[self.u_index]
            real = self._rollout(xi0, u_planned, cand)
            pen = self._penetration(real)
            hits = self._collisions(real, CHECK_MARGIN, pen)  # closer than that: constrain
            if not hits:
                clear_plans.append(self._make_plan(cand, u_planned, real, theta_t, True))

            if paper:  # the paper's scheme: one model, Algorithm I until clear
                if not hits:
                    break
                for i, k in hits:
                    theta_set[(i, k)] = None
                ref_real, ref_u, ref_pen = real, u_planned, pen
                continue
            for i, k in hits:  # Algorithm I on the new solution too, accepted or not
                theta_set[(i, k)] = None
            merit = self._merit(real, theta_t, pen)
            if merit < ref_merit - 1e-6:
                converged = _converged(real, ref_real, cfg)
                ref_real, ref_u, ref_merit, ref_pen = real, u_planned, merit, pen
                trust_scale = max(trust_scale / 2.0, 0.25)
                if not hits and (converged or self._settled(real, theta_t)):
                    break
            else:
                trust_scale *= 4.0
                if trust_scale > cfg.max_trust_scale:
                    break
        for plan in sorted(clear_plans, key=lambda q: q.cost)[:3]:  # the cheapest that the truth confirms
            if self._truth_safe(xi0, plan.commands):
                best = plan
                break
        if best is not None:
            st["status"] = "ok"
        elif ref_u is not None:  # no clear plan: the best iterate's safe start, if any
            hits = self._collisions(ref_real, 0.0, ref_pen)
            if hits:
                st["partial"] = self._safe_prefix(xi0, cand, ref_u, hits, theta_t)
        return best, st

    def _settled(self, real_half: np.ndarray, theta_t: float) -> bool:
        """The rollout ends standing this close to its goal: another SCP round would only polish it."""
        _, pos_err, th_err = self._true_cost(real_half[:: self.cfg.model_substeps], theta_t)
        return pos_err < self.cfg.settle_position and th_err < self.cfg.settle_heading

    def _penetration(self, real_half: np.ndarray) -> np.ndarray:
        """Footprint penetration of every half step into every obstacle, (2N + 1, K)."""
        return self.g.checker.penetration(real_half[:, 0], real_half[:, 1], real_half[:, 2])

    def _merit(self, real_half: np.ndarray, theta_t: float, pen: np.ndarray | None = None) -> float:
        """True cost of a rollout plus the exact penalty on its footprint's penetration
        (``pen``: its ``_penetration``, if already computed)."""
        cfg = self.cfg
        cost, _, _ = self._true_cost(real_half[:: cfg.model_substeps], theta_t)
        pen = (self._penetration(real_half) if pen is None else pen).max(axis=1)
        return cost + cfg.w_slack * float(np.clip(pen + cfg.obstacle_margin, 0, None).sum())

    # ------------------------------------------------------------------ cost
    def _cost(self, cand: Candidate, theta_t: float) -> np.ndarray:
        """c of sum w * residual^2 (piqp: 1/2 z'Pz + c'z); P's pattern is built once per
        switch step (``_cost_entry``) and filled by ``_build``."""
        L, w, kinds, _ = self._cost_entry(cand.switch)
        kappa = 1.0 if cand.switch is not None else 0.0
        tx, ty, _ = self._goal
        k0 = np.zeros(len(w))  # residual = p_i - 2 kappa S - (1 - 2 kappa) goal
        k0[kinds == 1] = -(1 - 2 * kappa) * tx
        k0[kinds == 2] = -(1 - 2 * kappa) * ty
        k0[kinds == 3] = -theta_t
        return 2.0 * (L.T @ (w * k0))

    def _cost_entry(self, s: int | None):
        """(L, w, residual kinds, (P's pattern with the trust penalty, P's values, trust's
        values)) for switch step ``s``, built once per config and shared by episodes."""
        if s not in self._cost_cache:
            self._cost_cache[s] = self._cost_pattern(Candidate(1, s))
        return self._cost_cache[s]

    def _cost_pattern(self, cand: Candidate):
        cfg, N = self.cfg, self.N
        kappa = 1.0 if cand.switch is not None else 0.0
        rows, cols, vals, kinds, w = [], [], [], [], []
        r = 0

        def add(entries, kind, weight):
            nonlocal r
            for col, v in entries:
                rows.append(r), cols.append(col), vals.append(v)
            kinds.append(kind), w.append(weight)
            r += 1

        for i in range(1, N + 1):
            wp = cfg.w_terminal_position if i == N else cfg.w_position * cfg.dt
            wh = cfg.w_terminal_heading if i == N else cfg.w_heading * cfg.dt
            for j, kind in ((XI_X, 1), (XI_Y, 2)):
                add([(self.ix(i, j), 1.0), (self.iS + j, -2.0 * kappa)], kind, wp)
            add([(self.ix(i, XI_TH), 1.0)], 3, wh)
        add([(self.ix(N, XI_A), 1.0)], 0, cfg.w_terminal_accel)
        for i in range(N):
            add([(self.iu(i, 0), 1.0)], 0, cfg.w_accel_cmd * cfg.dt)
            add([(self.iu(i, 1), 1.0)], 0, cfg.w_steer_cmd * cfg.dt)
            if i > 0 and i != cand.switch:  # no rate cost across the switch (commands flip)
                add([(self.iu(i, 0), 1.0), (self.iu(i - 1, 0), -1.0)], 0, cfg.w_accel_rate)
                add([(self.iu(i, 1), 1.0), (self.iu(i - 1, 1), -1.0)], 0, cfg.w_steer_rate)
        L = sp.csr_matrix((vals, (rows, cols)), shape=(r, self.nz))
        w = np.asarray(w)
        P = sp.triu(2.0 * (L.T @ sp.diags(w) @ L)).tocsc()  # piqp reads the upper triangle
        # P + scale * trust shares one pattern: (pattern, P's values, trust's values).
        Pc, T = P.tocoo(), self._trust.tocoo()
        pattern = CscPattern(np.concatenate([Pc.row, T.row]), np.concatenate([Pc.col, T.col]), P.shape)
        zp, zt = np.zeros(Pc.nnz), np.zeros(T.nnz)
        with_trust = (pattern, np.concatenate([Pc.data, zt]), np.concatenate([zp, T.data]))
        return L, w, np.asarray(kinds), with_trust

    def _trust_diag(self) -> sp.csc_matrix:
        cfg = self.cfg
        d = np.zeros(self.nz)
        for j, w in ((XI_X, cfg.w_trust_position), (XI_Y, cfg.w_trust_position), (XI_TH, cfg.w_trust_heading)):
            d[self.x_index[1:, j]] = 2.0 * w
        return sp.diags(d, format="csc")

    # ----------------------------------------------------------------- build
    def _build(
        self,
        xi0,
        cand,
        theta_t,
        c,
        lin,
        ref_real,
        theta_set,
        trust: bool,
        mirror: bool = True,
        trust_scale: float = 1.0,
    ):
        """The QP of one round. Its matrices refill patterns fixed per switch step (the
        cost, the dynamics); only the obstacle rows are assembled anew."""
        cfg, N = self.cfg, self.N
        A_, B_, c_ = lin
        s = cand.switch
        # Equalities: initial state, dynamics (flip at the switch), switch link.
        M = A_.copy()
        if s is not None:  # xi_{s+1} = A_s (FLIP xi_s) + B_s u_s + c_s
            M[s] = A_[s] @ FLIP
        blocks = np.concatenate([np.ones((N, NX, 1)), -M, -B_], axis=2)  # per row: [1, -M row, -B row]
        vals = np.concatenate([np.ones(NX), blocks.reshape(-1), [1.0, -1.0, 1.0, -1.0]])
        b = np.concatenate([xi0, c_.reshape(-1), [0.0, 0.0]])
        x_l, x_u = self._box(cand)
        if trust and ref_real is not None:  # penalty w (z - z_ref)^2: its linear part
            pl = self._to_planned(ref_real, cand)
            c = c.copy()
            for j, w in ((XI_X, cfg.w_trust_position), (XI_Y, cfg.w_trust_position), (XI_TH, cfg.w_trust_heading)):
                c[self.x_index[1:, j]] -= 2.0 * trust_scale * w * pl[1:, j]
        # Inequalities: the mirror line, then obstacle alternatives.
        g_rows, g_cols, g_vals, h_l, h_u, active = [], [], [], [], [], []
        ln = self.line
        n0, n1 = ln.normal
        g_rows += [0, 0]
        g_cols += [self.iS, self.iS + 1]
        g_vals += [n0, n1]
        bound = n0 * ln.target_xy[0] + n1 * ln.target_xy[1] + ln.distance
        if s is None or not mirror:
            h_l.append(INACTIVE), h_u.append(np.inf)
        elif ln.fixed:
            h_l.append(bound), h_u.append(bound + 0.02)  # on the line (to 2 cm)
        else:
            h_l.append(bound), h_u.append(np.inf)
        active.append(h_l[-1])
        disj: list[Disjunction] = []
        preferred: list[int] = []
        if theta_set and ref_real is not None:
            self._obstacle_rows(cand, ref_real, theta_set, g_rows, g_cols, g_vals, h_l, h_u, active, disj, preferred)
        # Every row is soft: row + slack >= lower bound, slack >= 0 at w_slack per m (an
        # exact penalty). No QP is infeasible; the exact footprint check decides.
        n_s = len(h_l)
        nz = self.nz + n_s
        if n_s == 1 and self._g_line is not None:  # the mirror-line row alone: the same G every time
            G = self._g_line
        else:  # triplets to CSC through CscPattern: scipy's COO route costs ~4x as much per call
            g_rows = np.concatenate([g_rows, np.arange(n_s)])
            g_cols = np.concatenate([g_cols, self.nz + np.arange(n_s)])
            G = CscPattern(g_rows, g_cols, (n_s, nz)).matrix(np.concatenate([g_vals, np.ones(n_s)]))
            if n_s == 1:
                self._g_line = G
        pattern, p_vals, t_vals = self._cost_entry(s)[3]
        P = pattern.matrix(p_vals + (trust_scale if trust else 0.0) * t_vals, (nz, nz))
        A = self._eq_pattern(s).matrix(vals, (self._n_dyn_rows + 2, nz))
        c = np.concatenate([c, np.full(n_s, cfg.w_slack)])
        x_l = np.concatenate([x_l, np.zeros(n_s)])
        x_u = np.concatenate([x_u, np.full(n_s, np.inf)])
        qp = QP(P, c, A, b, G, np.array(h_l, float), np.array(h_u, float), x_l, x_u)
        return qp, disj, np.array(active, float), preferred

    def _eq_pattern(self, s: int | None) -> CscPattern:
        """Pattern of the equality rows for switch step ``s`` (its link row names xi_s)."""
        link_s = s if s is not None else self.N
        if link_s not in self._eq_patterns:
            n = self._n_dyn_rows
            rows = np.concatenate([self._dyn_rows, [n, n, n + 1, n + 1]])
            cols = np.concatenate(
                [self._dyn_cols, [self.iS, self.ix(link_s, XI_X), self.iS + 1, self.ix(link_s, XI_Y)]]
            )
            self._eq_patterns[link_s] = CscPattern(rows, cols, (n + 2, self.nz))
        return self._eq_patterns[link_s]

    def _box(self, cand: Candidate) -> tuple[np.ndarray, np.ndarray]:
        """Variable bounds (Table II) for a direction and switch step; speed zero at the
        switch and at N. Commands after the switch are negated, so are their bounds."""
        key = (cand.direction, cand.switch)
        if key not in self._bounds:
            p, N, s = self.p, self.N, cand.switch
            x_l, x_u = np.full(self.nz, -np.inf), np.full(self.nz, np.inf)
            steps = np.arange(1, N + 1)
            after = (steps > s) if s is not None else np.zeros(N, bool)
            v_lo, v_hi = (0.0, p.v_max) if cand.direction > 0 else (p.v_min, 0.0)
            xv, xa, xd = (self.x_index[steps, j] for j in (XI_V, XI_A, XI_D))
            x_l[xv], x_u[xv] = v_lo, v_hi
            x_l[xa] = np.where(after, -p.a_max, p.a_min)
            x_u[xa] = np.where(after, -p.a_min, p.a_max)
            x_l[xd], x_u[xd] = -p.max_steer, p.max_steer
            after_u = (np.arange(N) >= s) if s is not None else np.zeros(N, bool)
            ua, ud = self.u_index[:, 0], self.u_index[:, 1]
            x_l[ua] = np.where(after_u, -p.a_max, p.a_min)
            x_u[ua] = np.where(after_u, -p.a_min, p.a_max)
            x_l[ud], x_u[ud] = -p.max_steer, p.max_steer
            for i in ([s] if s is not None else []) + [N]:  # stands at the switch; every plan ends stopped
                x_l[self.ix(i, XI_V)] = x_u[self.ix(i, XI_V)] = 0.0
            x_l.flags.writeable = x_u.flags.writeable = False
            self._bounds[key] = (x_l, x_u)
        return self._bounds[key]

    def _real_pose_coeffs(self, i: int, cand: Candidate):
        """real p_i = sign * p_i + twice * S."""
        if cand.switch is not None and i > cand.switch:
            return -1.0, 2.0
        return 1.0, 0.0

    def _obstacle_rows(self, cand, ref_real, theta_set, g_rows, g_cols, g_vals, h_l, h_u, active, disj, preferred):
        """Rows of Eq. (40) at the steps in ``theta_set``, linearised about the reference.

        Each feature point must stay behind one face of the obstacle, each obstacle vertex
        that could pierce the car behind one face of the car. ``preferred`` gets, per
        disjunction, the alternative the reference satisfies best (B&B tries it first).
        """
        margin = self.cfg.obstacle_margin
        ref = ref_real[:: self.cfg.model_substeps]  # real states at the control steps

        def add_row(i, coef_p, coef_th, lower, sign, twice):
            r = len(h_l)
            g_rows.extend([r, r, r])
            g_cols.extend([self.ix(i, XI_X), self.ix(i, XI_Y), self.ix(i, XI_TH)])
            g_vals.extend([sign * coef_p[0], sign * coef_p[1], coef_th])
            if twice:
                g_rows.extend([r, r])
                g_cols.extend([self.iS, self.iS + 1])
                g_vals.extend([twice * coef_p[0], twice * coef_p[1]])
            h_u.append(np.inf)
            return r, lower

        for i, k in sorted(theta_set):
            sign, twice = self._real_pose_coeffs(i, cand)
            th = ref[i, XI_TH]
            ct, st_ = math.cos(th), math.sin(th)
            Pbar = ref[i, :2]
            faces = self._faces[k]
            for cx, cy in self.points:
                rc = np.array([ct * cx - st_ * cy, st_ * cx + ct * cy])  # R(th) c
                drc = np.array([-st_ * cx - ct * cy, ct * cx - st_ * cy])  # dR/dth c
                q_ref = Pbar + rc
                slack = [float(nrm @ q_ref) - off for nrm, off in faces]
                if not faces or max(slack) > 1.0:
                    continue  # far outside: this point cannot reach the obstacle here
                alts = []
                for nrm, off in faces:
                    coef_th = float(nrm @ drc)
                    lower = off + margin - float(nrm @ (rc - th * drc))
                    r, lo = add_row(i, nrm, coef_th, lower, sign, twice)
                    alts.append((r, lo))
                self._register(alts, h_l, active, disj, preferred, int(np.argmax(slack)))
            centre = Pbar + self.p.center_offset * np.array([ct, st_])
            for q in self._vertices[k]:
                if np.hypot(*(q - centre)) > 0.5 * self.p.length + 1.5:
                    continue
                alts, slack = [], []
                for nb, off in self.car_faces:
                    nw = np.array([ct * nb[0] - st_ * nb[1], st_ * nb[0] + ct * nb[1]])
                    dnw = np.array([-st_ * nb[0] - ct * nb[1], ct * nb[0] - st_ * nb[1]])
                    # nw(th).(q - P) >= off + margin, linearised about (th, Pbar)
                    k_th = float(dnw @ (q - Pbar))
                    lower = off + margin - float(nw @ q) + k_th * th
                    r, lo = add_row(i, -nw, k_th, lower, sign, twice)
                    alts.append((r, lo))
                    slack.append(float(nw @ (q - Pbar)) - off)
                self._register(alts, h_l, active, disj, preferred, int(np.argmax(slack)))

    @staticmethod
    def _register(alts, h_l, active, disj, preferred, best: int):
        if len(alts) == 1:  # a single face: an ordinary constraint
            r, lo = alts[0]
            h_l.append(lo)
            active.append(lo)
            return
        for r, lo in alts:
            h_l.append(INACTIVE)
            active.append(lo)
        disj.append(Disjunction(tuple(r for r, _ in alts)))
        preferred.append(alts[best][0])

    # --------------------------------------------------------------- rollout
    def _real_commands(self, u_planned: np.ndarray, cand: Candidate) -> np.ndarray:
        u = u_planned.copy()
        if cand.switch is not None:
            u[cand.switch :] *= -1.0  # Eq. (42)
        return u

    def _rollout(self, xi0: np.ndarray, u_planned: np.ndarray, cand: Candidate) -> np.ndarray:
        """Real states at every half step: (2N + 1, 6); even rows are the control steps."""
        sub = self.coarse.rollout(xi0, self._real_commands(u_planned, cand))[:, :6]
        return np.concatenate([xi0[None], sub])

    def _planned_controls(self, real_half: np.ndarray, cand: Candidate) -> np.ndarray:
        """Commands that reproduce a rollout's lag states, in the planned frame."""
        pl = self._to_planned(real_half, cand)
        p, dt = self.p, self.cfg.dt
        ea, ed = math.exp(-dt / p.tau_a), math.exp(-dt / p.tau_delta)
        a0, a1 = pl[:-1, XI_A], pl[1:, XI_A]
        d0, d1 = pl[:-1, XI_D], pl[1:, XI_D]
        if cand.switch is not None:  # step s starts from the flipped lag states
            a0, d0 = a0.copy(), d0.copy()
            a0[cand.switch] *= -1
            d0[cand.switch] *= -1
        u = np.stack([(a1 - ea * a0) / (1 - ea), (d1 - ed * d0) / (1 - ed)], axis=1)
        return u

    def _to_planned(self, real_half: np.ndarray, cand: Candidate) -> np.ndarray:
        """Planned (mirror-frame) states of a real rollout: the reflection after the switch."""
        real = real_half[:: self.cfg.model_substeps]
        pl = real.copy()
        s = cand.switch
        if s is not None:
            S = real[s, :2]
            pl[s + 1 :, :2] = 2 * S - real[s + 1 :, :2]
            pl[s + 1 :, 3:] *= -1.0
        return pl

    def _truth_safe(self, xi0: np.ndarray, u_real: np.ndarray, clearance: float = 0.005) -> bool:
        """On the environment's own model (0.01 s sub-steps) the plan keeps clear and ends
        standing, so that whatever comes after it, the car is at rest."""
        sub = self.truth.rollout(xi0, u_real)
        return self._clear_and_stopped([sub[:, :3]], sub[-1, :6], clearance)

    def _clear_and_stopped(self, poses: list[np.ndarray], end: np.ndarray, clearance: float = 0.005) -> bool:
        q = np.concatenate(poses)
        pen = self.g.checker.penetration(q[:, 0], q[:, 1], q[:, 2]).max(axis=1)
        clear = bool(np.all(pen < -self._clearance(q, clearance)))
        return bool(clear and abs(end[XI_V]) < 0.05)

    def _clearance(self, poses: np.ndarray, margin: float) -> np.ndarray | float:
        """Clearance each pose must keep: ``margin``, but near a start that is closer than
        that, most of the start's own gap (the car may leave a tight spot, not tighten it)."""
        x0, y0, gap0 = self._start
        if gap0 >= margin + START_SLACK:
            return margin
        near = np.hypot(poses[:, 0] - x0, poses[:, 1] - y0) < START_RELIEF
        return np.where(near, min(margin, gap0 - START_SLACK), margin)

    def _collisions(
        self, real_half: np.ndarray, margin: float = 0.0, pen: np.ndarray | None = None
    ) -> list[tuple[int, int]]:
        """(step, obstacle) pairs to constrain: steps next to any half step closer than
        ``margin`` (``pen``: the rollout's ``_penetration``, if already computed)."""
        pen = self._penetration(real_half) if pen is None else pen
        need = self._clearance(real_half, margin) if margin > 0 else 0.0
        hit = pen > -1e-9 - np.reshape(need, (-1, 1))
        out = set()
        m = self.cfg.model_substeps
        for h, k in zip(*np.nonzero(hit)):
            for j in {h // m, -(-h // m)}:  # the control steps around half step h
                if 1 <= j <= self.N:
                    out.add((int(j), int(k)))
        return sorted(out)

    def _true_cost(self, real: np.ndarray, theta_t: float) -> tuple[float, float, float]:
        """(cost, position error, heading error) of real states at the control steps."""
        cfg = self.cfg
        tx, ty, _ = self._goal
        pos_err = float(np.hypot(real[-1, 0] - tx, real[-1, 1] - ty))
        th_err = float(abs(real[-1, 2] - theta_t))
        run = float((np.hypot(real[1:, 0] - tx, real[1:, 1] - ty) ** 2).sum()) * cfg.w_position * cfg.dt
        return cfg.w_terminal_position * pos_err**2 + cfg.w_terminal_heading * th_err**2 + run, pos_err, th_err

    def _make_plan(self, cand, u_planned, real_half, theta_t, clear) -> Plan:
        real = real_half[:: self.cfg.model_substeps]
        cost, pos_err, th_err = self._true_cost(real, theta_t)
        S = tuple(real[cand.switch, :2]) if cand.switch is not None else None
        planned = self._to_planned(real_half, cand)
        return Plan(
            self._real_commands(u_planned, cand), real, cand, S, self.line, planned, cost, (pos_err, th_err), clear
        )

    def _safe_prefix(self, xi0, cand, u_planned, hits, theta_t) -> Plan | None:
        """The colliding plan's start, braking to a stop before its first contact.

        Verified on the environment's own model with the same clearance as full plans;
        used when no candidate yields a clear plan that makes progress.
        """
        p = self.p
        u_real = self._real_commands(u_planned, cand)
        first = min(i for i, _ in hits)
        for cut in (first - 3, first - 8, first - 15):
            if cut < 3:
                break
            s, states, poses, cmds = xi0, [xi0], [], []
            for i in range(self.N):
                if i < cut:
                    a, d = u_real[i]
                else:  # brake to a stop, wheels held
                    a = max(p.a_min, min(p.a_max, -s[XI_V] / 0.3 - s[XI_A] if abs(s[XI_V]) > 1e-3 else -s[XI_A]))
                    d = s[XI_D]
                sub = self.truth.step(s, a, d)
                poses.append(sub[:, :3])
                s = sub[-1, :6]
                states.append(s)
                cmds.append((a, d))
            if self._clear_and_stopped(poses, s):
                real = np.array(states)
                cost, pos_err, th_err = self._true_cost(real, theta_t)
                sw = cand.switch if cand.switch is not None and cand.switch < cut else None
                return Plan(
                    np.array(cmds),
                    real,
                    Candidate(cand.direction, sw),
                    tuple(real[sw, :2]) if sw else None,
                    self.line,
                    real,
                    cost,
                    (pos_err, th_err),
                    True,
                )
        return None


def _converged(real: np.ndarray, ref: np.ndarray, cfg: MirrorPlannerConfig) -> bool:
    dp = np.hypot(real[:, 0] - ref[:, 0], real[:, 1] - ref[:, 1]).max()
    dth = np.abs(real[:, 2] - ref[:, 2]).max()
    return dp < cfg.converge_position and dth < cfg.converge_heading


def _unwrap_near(angle: float, reference: float) -> float:
    return angle + 2 * math.pi * round((reference - angle) / (2 * math.pi))


def _useful_features(g: ScenarioGeometry):
    """Per obstacle: faces next to free space near the slot, and vertices that can pierce the car.

    A face (outward normal n, offset b: outside is n.q >= b) is useful when some point
    just outside it, within the window around the slot and road, is free of obstacles.
    """
    polys = g.obstacles.polygons
    slot = g.slot
    x_lo, x_hi = float(slot[:, 0].min()) - 8.0, float(slot[:, 0].max()) + 10.0
    y_lo, y_hi = float(slot[:, 1].min()) - 0.5, g.road_width + 0.5

    def free(q):
        if not (x_lo <= q[0] <= x_hi and y_lo <= q[1] <= y_hi):
            return False
        return not any(_inside(poly, q) for poly in polys)

    faces, vertices = [], []
    for poly in polys:
        f, useful_edge = [], []
        n_v = len(poly)
        for e in range(n_v):
            a, b = poly[e], poly[(e + 1) % n_v]
            d = b - a
            n = np.array([d[1], -d[0]]) / np.hypot(*d)  # outward for CCW
            pts = [a + t * d + 0.05 * n for t in np.linspace(0.02, 0.98, 41)]
            ok = any(free(q) for q in pts)
            useful_edge.append(ok)
            if ok:
                f.append((n, float(n @ a)))
        faces.append(f)
        vs = [
            poly[e]
            for e in range(n_v)
            if useful_edge[e] and useful_edge[e - 1] and x_lo <= poly[e][0] <= x_hi and y_lo <= poly[e][1] <= y_hi
        ]
        vertices.append(vs)
    return faces, vertices


def _inside(poly: np.ndarray, q) -> bool:
    d = np.roll(poly, -1, axis=0) - poly
    cross = d[:, 0] * (q[1] - poly[:, 1]) - d[:, 1] * (q[0] - poly[:, 0])
    return bool(np.all(cross > 1e-12))
