"""The QP of one SCP round: cost (Eq. 33 toward the mirrored target), dynamics, bounds,
the mirror line (Eq. 37) and the obstacle rows (Eq. 40), on fixed sparsity patterns.

Patterns are built once and refilled: the cost per switch step (shared by every planner
with the same config, in a bounded cache), the equality rows (initial state, dynamics,
switch link) per switch step. Only the obstacle rows are assembled anew each round.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from mirrorpark_env.vehicle import VehicleParams

from .config import CoreConfig
from .cost import Terminal, cost_pattern, slack_weights
from .frames import FLIP, XI_A, XI_D, XI_TH, XI_V, XI_X, XI_Y, to_planned
from .mirror_line import MirrorLine, SwitchBand
from .model import NU, NX
from .obstacles import ObstacleRows, Rows
from .plans import Candidate
from .solvers import INACTIVE, QP, CscPattern, Disjunction
from .variables import iu, ix, switch_index, u_index, x_index


class MirrorQP:
    """Builds the QP of a round for one scenario and config."""

    def __init__(self, params: VehicleParams, cfg: CoreConfig, obstacles: ObstacleRows):
        self.p, self.cfg, self.obstacles = params, cfg, obstacles
        N = self.N = cfg.horizon
        self.iS = switch_index(N)
        self.nz = self.iS + 2
        self.x_index = x_index(N)
        self.u_index = u_index(N)
        self._dyn_rows, self._dyn_cols = _dynamics_pattern(N)
        self._n_dyn_rows = NX + NX * N
        self._eq_patterns: dict[int, CscPattern] = {}  # per switch-link step
        self._g_switch: dict[int, CscPattern] = {}  # G of a QP without obstacle rows, per switch step
        self._bounds: dict[tuple[int, int | None], tuple[np.ndarray, np.ndarray]] = {}

    # ----------------------------------------------------------------- build
    def build(
        self,
        xi0: np.ndarray,
        cand: Candidate,
        c: np.ndarray,
        lin,
        ref_real: np.ndarray | None,
        theta_set,
        line: MirrorLine,
        trust: bool,
        mirror: bool = True,
        trust_scale: float = 1.0,
        band: SwitchBand | None = None,
        terminal: Terminal | None = None,
    ) -> tuple[QP, list[Disjunction], np.ndarray, list[int]]:
        """(QP, disjunctions, each row's enforced lower bound, preferred rows) of one round.

        The switch rows: ``band`` where given (with a switch), else the fixed ``line``
        where ``mirror`` is on; neither: inactive. ``terminal``: as ``c`` was built
        (``cost.linear_term``)."""
        cfg = self.cfg
        s = cand.switch
        vals, b = self._equalities(xi0, cand, lin)
        x_l, x_u = self.box(cand)
        if -cfg.stop_first_speed < cand.direction * xi0[XI_V] < 0:
            x_l, x_u = self._stopping_start(xi0, cand, lin, x_l, x_u)
        if trust and ref_real is not None:  # penalty w (z - z_ref)^2: its linear part
            pl = to_planned(ref_real, cand, cfg.model_substeps)
            c = c.copy()
            for j, w in ((XI_X, cfg.w_trust_position), (XI_Y, cfg.w_trust_position), (XI_TH, cfg.w_trust_heading)):
                c[self.x_index[1:, j]] -= 2.0 * trust_scale * w * pl[1:, j]
        rows = Rows()
        self._switch_rows(rows, s, line, s is not None and mirror, band if s is not None else None)
        if theta_set and ref_real is not None:
            self.obstacles.add(rows, cand, ref_real, theta_set)
        # Every row's lower side is soft: row + slack >= lower bound, slack >= 0 at ``cost.slack_weights``
        # per m (an exact penalty); the exact footprint check decides. Hard are the variable
        # bounds (a car rolling back has no forward plan, but for ``stop_first_speed``) and
        # the fixed line's upper side (a parallel switch at most 2 cm past it): there a
        # candidate has no solution.
        n_s = len(rows.h_l)
        nz = self.nz + n_s
        G = self._inequalities(rows, n_s, nz)
        h_l, active = np.array(rows.h_l, float), np.array(rows.active, float)
        pattern, p_vals, t_vals = cost_pattern(cfg, s, terminal)[3]
        P = pattern.matrix(p_vals + (trust_scale if trust else 0.0) * t_vals, (nz, nz))
        A = self._eq_pattern(s).matrix(vals, (self._n_dyn_rows + 2, nz))
        c = np.concatenate([c, slack_weights(cfg, n_s)])
        x_l = np.concatenate([x_l, np.zeros(n_s)])
        x_u = np.concatenate([x_u, np.full(n_s, np.inf)])
        qp = QP(P, c, A, b, G, h_l, np.array(rows.h_u, float), x_l, x_u, row_slacks=True)
        return qp, rows.disj, active, rows.preferred

    def _stopping_start(self, xi0: np.ndarray, cand: Candidate, lin, x_l: np.ndarray, x_u: np.ndarray):
        """Speed bounds of a car still creeping against the plan's gear: until it can have
        stopped (the model's fastest stop, full command toward the gear) its speed may keep
        that stop's sign and size; from then on the gear's bound holds. Without this a car
        creeping back at 2 cm/s has no forward plan at all (the bound fails at step 1)."""
        A_, B_, c_ = lin
        d = cand.direction
        u = np.array([self.p.accel_max if d > 0 else self.p.accel_min, xi0[XI_D]])
        last = cand.switch if cand.switch is not None else self.N
        xi, x_l, x_u = xi0.copy(), x_l.copy(), x_u.copy()
        for k in range(last):
            xi = A_[k] @ xi + B_[k] @ u + c_[k]
            if d * xi[XI_V] >= 0 or k + 1 == last:
                break
            j = self.x_index[k + 1, XI_V]
            if d > 0:
                x_l[j] = xi[XI_V]
            else:
                x_u[j] = xi[XI_V]
        return x_l, x_u

    def _equalities(self, xi0: np.ndarray, cand: Candidate, lin) -> tuple[np.ndarray, np.ndarray]:
        """Values and right-hand side of: initial state, dynamics (flip at the switch), switch link."""
        A_, B_, c_ = lin
        s = cand.switch
        M = A_.copy()
        if s is not None:  # xi_{s+1} = A_s (FLIP xi_s) + B_s u_s + c_s
            M[s] = A_[s] @ FLIP
        blocks = np.concatenate([np.ones((self.N, NX, 1)), -M, -B_], axis=2)  # per row: [1, -M row, -B row]
        vals = np.concatenate([np.ones(NX), blocks.reshape(-1), [1.0, -1.0, 1.0, -1.0]])
        b = np.concatenate([xi0, c_.reshape(-1), [0.0, 0.0]])
        return vals, b

    def _switch_rows(self, rows: Rows, s: int | None, ln: MirrorLine, on: bool, band: SwitchBand | None) -> None:
        """Rows 0 and 1: where the switch may lie. With ``band``: its rows on S and the
        heading at step s. Else row 0 puts S on the fixed line (parallel, to 2 cm) or
        beyond it (reverse, angle) where ``on``; unused rows are inactive."""
        th = ix(s if s is not None else 0, XI_TH)
        g_rows, g_cols = np.repeat([0, 1], 3), np.array([self.iS, self.iS + 1, th] * 2)
        if band is not None:
            vals = []
            for r in range(2):
                if r < len(band.lo):
                    vals += [*band.a_s[r], band.a_theta[r]]
                    rows.h_l.append(band.lo[r]), rows.h_u.append(np.inf)
                else:
                    vals += [0.0, 0.0, 0.0]
                    rows.h_l.append(INACTIVE), rows.h_u.append(np.inf)
                rows.active.append(rows.h_l[-1])
            rows.extend(g_rows, g_cols, np.array(vals, float))
            return
        n0, n1 = ln.normal
        rows.extend(g_rows, g_cols, np.array([n0, n1, 0.0, 0.0, 0.0, 0.0], float))
        bound = n0 * ln.target_xy[0] + n1 * ln.target_xy[1] + ln.distance
        if not on:
            rows.h_l.append(INACTIVE), rows.h_u.append(np.inf)
        elif ln.fixed:
            rows.h_l.append(bound), rows.h_u.append(bound + 0.02)  # on the line (to 2 cm)
        else:
            rows.h_l.append(bound), rows.h_u.append(np.inf)
        rows.h_l.append(INACTIVE), rows.h_u.append(np.inf)
        rows.active += rows.h_l[-2:]

    def _inequalities(self, rows: Rows, n_s: int, nz: int) -> sp.csc_matrix:
        """G with one slack column per row."""
        # Triplets to CSC through CscPattern: scipy's COO route costs ~4x as much per call.
        g_rows, g_cols, g_vals = rows.triplets()
        vals = np.concatenate([g_vals, np.ones(n_s)])
        if n_s == 2:  # the switch rows alone: one pattern per switch step, refilled
            key = int(g_cols[2])
            if key not in self._g_switch:
                self._g_switch[key] = CscPattern(
                    np.concatenate([g_rows, [0, 1]]), np.concatenate([g_cols, self.nz + np.arange(2)]), (2, nz)
                )
            return self._g_switch[key].matrix(vals)
        g_rows = np.concatenate([g_rows, np.arange(n_s)])
        g_cols = np.concatenate([g_cols, self.nz + np.arange(n_s)])
        return CscPattern(g_rows, g_cols, (n_s, nz)).matrix(vals)

    def _eq_pattern(self, s: int | None) -> CscPattern:
        """Pattern of the equality rows for switch step ``s`` (its link row names xi_s)."""
        link_s = s if s is not None else self.N
        if link_s not in self._eq_patterns:
            n = self._n_dyn_rows
            rows = np.concatenate([self._dyn_rows, [n, n, n + 1, n + 1]])
            cols = np.concatenate([self._dyn_cols, [self.iS, ix(link_s, XI_X), self.iS + 1, ix(link_s, XI_Y)]])
            self._eq_patterns[link_s] = CscPattern(rows, cols, (n + 2, self.nz))
        return self._eq_patterns[link_s]

    def box(self, cand: Candidate) -> tuple[np.ndarray, np.ndarray]:
        """Variable bounds (Table II) for a direction and switch step; speed zero at the
        switch and at N. Commands after the switch are negated, so are their bounds."""
        key = (cand.direction, cand.switch)
        if key not in self._bounds:
            self._bounds[key] = _box(self.p, self.N, self.nz, self.x_index, self.u_index, cand, self.cfg.end_settled)
        return self._bounds[key]


def _box(p: VehicleParams, N: int, nz: int, xi: np.ndarray, ui: np.ndarray, cand: Candidate, settled: bool = False):
    s = cand.switch
    x_l, x_u = np.full(nz, -np.inf), np.full(nz, np.inf)
    steps = np.arange(1, N + 1)
    after = (steps > s) if s is not None else np.zeros(N, bool)
    v_lo, v_hi = (0.0, p.speed_max) if cand.direction > 0 else (p.speed_min, 0.0)
    xv, xa, xd = (xi[steps, j] for j in (XI_V, XI_A, XI_D))
    x_l[xv], x_u[xv] = v_lo, v_hi
    x_l[xa] = np.where(after, -p.accel_max, p.accel_min)
    x_u[xa] = np.where(after, -p.accel_min, p.accel_max)
    x_l[xd], x_u[xd] = -p.max_steer_rad, p.max_steer_rad
    after_u = (np.arange(N) >= s) if s is not None else np.zeros(N, bool)
    ua, ud = ui[:, 0], ui[:, 1]
    x_l[ua] = np.where(after_u, -p.accel_max, p.accel_min)
    x_u[ua] = np.where(after_u, -p.accel_min, p.accel_max)
    x_l[ud], x_u[ud] = -p.max_steer_rad, p.max_steer_rad
    for i in ([s] if s is not None else []) + [N]:  # stands at the switch; every plan ends stopped
        x_l[ix(i, XI_V)] = x_u[ix(i, XI_V)] = 0.0
    if settled:  # the end's lagged acceleration may not point back: the car would roll across zero
        if cand.direction > 0:
            x_l[ix(N, XI_A)] = 0.0
        else:
            x_u[ix(N, XI_A)] = 0.0
    x_l.flags.writeable = x_u.flags.writeable = False
    return x_l, x_u


def _dynamics_pattern(N: int) -> tuple[np.ndarray, np.ndarray]:
    """Triplet pattern of the equality rows: initial state, then dynamics."""
    rows, cols = [], []
    for j in range(NX):
        rows.append(j), cols.append(ix(0, j))
    r0 = NX
    for i in range(N):
        for a in range(NX):
            r = r0 + NX * i + a
            rows.append(r), cols.append(ix(i + 1, a))
            for b in range(NX):
                rows.append(r), cols.append(ix(i, b))
            for b in range(NU):
                rows.append(r), cols.append(iu(i, b))
    return np.array(rows), np.array(cols)
