"""The planner's cost, every term once: the QP's objective (Eq. 33 toward the mirrored
target) with its exact penalty, the true cost of a rollout and the merit that SCP and the
checks score by, the end's weight across a tight slot, and the price of driving
(``PriceConfig``'s weights, in metres) by which the cost to go, the guide, the seeds and
the cost-to-go strategy's candidates are ranked.

The QP's objective is sum_r w_r (L_r z + k_r)^2 over residual rows (``cost_pattern``:
L, w; ``offsets``: k): the running pose error toward the mirrored target, the end's pose
error, the end's lagged acceleration and the commands and their rates. After the switch a
planned position p is the real 2 S - p (Theorem 2), so the residual p - 2 S + goal is the
real error negated: the end's rows price the real end exactly (tests/test_cost.py).

The true cost prices a real rollout's pose only (its commands were already optimised):
``end_cost`` of its last pose, by the same rows as the QP's end, plus the running position
error at every control step toward the real goal.

The end's weight across the slot: in a tight slot one weight is too weak across it: in a
1.92 m angle slot the ISO window is 2.5 cm to each side of the target, and an end 3 cm off
costs 400 x 0.03^2 = 0.36, less than the steering of a correcting move; the car then
enters a little to one side and corrects it a millimetre per plan, for dozens of direction
switches. So the weight across the slot grows as the window narrows (``terminal_for``),
so that an end at the window's edge costs what it costs in a slot of
``lateral_window`` each side; wider slots keep the one weight.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import scipy.sparse as sp

from mirrorpark_env.angles import unwrap_near
from mirrorpark_env.config import ParkingType
from mirrorpark_env.criteria import SuccessCriteria
from mirrorpark_env.scenario import ScenarioGeometry
from mirrorpark_env.vehicle import footprint

from ..common.cost_to_go_config import CostToGoConfig, PriceConfig, path_price
from .config import CoreConfig
from .frames import XI_A, XI_TH, XI_X, XI_Y
from .solvers import CscPattern
from .variables import iu, ix, switch_index, x_index

MIN_WINDOW = 1e-3  # [m] narrower than this, no pose passes in practice: nothing to sharpen


@dataclass(frozen=True)
class Terminal:
    """The end's position cost in the target's frame: along its heading at the config's
    ``w_terminal_position``; across it on the body's front and rear ends (where the ISO side
    margins are measured), each at half ``w_lateral``, so that a sideways offset with the
    heading exact costs ``w_lateral`` per m^2."""

    heading: float  # [rad] the target's heading (the slot's axis)
    w_lateral: float
    front: float  # [m] rear axle to the front of the body
    rear: float  # [m] rear axle to the back of the body


def terminal_error(terminal: Terminal, dx: float, dy: float) -> tuple[float, float]:
    """(along, across) the target's heading of an end's offset (dx, dy) from the target."""
    c, s = math.cos(terminal.heading), math.sin(terminal.heading)
    return c * dx + s * dy, -s * dx + c * dy


def end_cost(terminal: Terminal, w_along: float, dx: float, dy: float, dtheta: float) -> float:
    """The position cost of a real end offset (dx, dy, dtheta) from the target, as the QP's
    rows weigh it (``cost_pattern``, kinds 4 to 6)."""
    along, across = terminal_error(terminal, dx, dy)
    front, rear = across + terminal.front * dtheta, across - terminal.rear * dtheta
    return w_along * along**2 + 0.5 * terminal.w_lateral * (front**2 + rear**2)


def lateral_window(geometry: ScenarioGeometry) -> float | None:
    """[m] How far the car may move across the slot from the target, to the nearer side, and
    still pass the ISO margins (reverse, angle: the side margins >= their minimum;
    parallel: inside the entrance and the back). None without a slot."""
    if geometry.slot is None or not geometry.slot_edges:
        return None
    crit = SuccessCriteria(geometry)
    corners = footprint(geometry.vehicle, *geometry.target)
    d = crit.edge_distances(corners)  # (corner, edge)
    parallel = geometry.parking_type is ParkingType.PARALLEL
    names = ("entrance", "back") if parallel else ("left", "right")
    cols = [i for i, (n, _) in enumerate(geometry.slot_edges) if n in names]
    return float(d[:, cols].min()) - crit.min_margin


def terminal_for(geometry: ScenarioGeometry, cfg: CoreConfig) -> Terminal | None:
    """The terminal cost toward ``geometry``'s target: None where one weight serves (no
    slot, a window of at least ``cfg.lateral_window``, or one too narrow to park in)."""
    w = lateral_window(geometry)
    if w is None or cfg.lateral_window <= 0 or not MIN_WINDOW <= w < cfg.lateral_window:
        return None
    scale = (cfg.lateral_window / w) ** 2
    v = geometry.vehicle
    return Terminal(float(geometry.target[2]), cfg.w_terminal_position * scale, v.front_length, v.rear_overhang)


def offsets(
    cfg: CoreConfig, s: int | None, goal: np.ndarray, theta_t: float, terminal: Terminal | None = None
) -> np.ndarray:
    """k of every residual row toward ``goal`` (the real target or another pose), mirrored
    through S after the switch: residual = L z + k (``cost_pattern``'s rows)."""
    _, w, kinds, _ = cost_pattern(cfg, s, terminal)
    kappa = 1.0 if s is not None else 0.0
    tx, ty, _ = goal
    k0 = np.zeros(len(w))  # residual = p_i - 2 kappa S - (1 - 2 kappa) goal
    k0[kinds == 1] = -(1 - 2 * kappa) * tx
    k0[kinds == 2] = -(1 - 2 * kappa) * ty
    k0[kinds == 3] = -theta_t
    if terminal is not None:  # the end along the target's heading; its front and rear across it
        along, across = terminal_error(terminal, tx, ty)
        k0[kinds == 4] = -(1 - 2 * kappa) * along
        k0[kinds == 5] = -across - terminal.front * theta_t
        k0[kinds == 6] = -across + terminal.rear * theta_t
    return k0


def linear_term(
    cfg: CoreConfig, s: int | None, goal: np.ndarray, theta_t: float, terminal: Terminal | None = None
) -> np.ndarray:
    """c of the QP's objective (piqp: 1/2 z'Pz + c'z) toward ``goal``."""
    L, w, _, _ = cost_pattern(cfg, s, terminal)
    return 2.0 * (L.T @ (w * offsets(cfg, s, goal, theta_t, terminal)))


def objective(
    cfg: CoreConfig, s: int | None, z: np.ndarray, goal: np.ndarray, theta_t: float, terminal: Terminal | None = None
) -> np.ndarray:
    """Each residual row's cost w (L z + k)^2 at ``z``: their sum is the QP's objective
    plus a constant (k' W k)."""
    L, w, _, _ = cost_pattern(cfg, s, terminal)
    return w * (L @ z + offsets(cfg, s, goal, theta_t, terminal)) ** 2


def true_cost(
    cfg: CoreConfig, real: np.ndarray, goal: np.ndarray, theta_t: float, terminal: Terminal | None = None
) -> tuple[float, float, float]:
    """(cost, position error, heading error) of real states at the control steps: the end's
    pose by the QP's end rows, plus the running position error toward ``goal``."""
    tx, ty, _ = goal
    pos_err = float(np.hypot(real[-1, 0] - tx, real[-1, 1] - ty))
    th_err = float(abs(real[-1, 2] - theta_t))
    run = float((np.hypot(real[1:, 0] - tx, real[1:, 1] - ty) ** 2).sum()) * cfg.w_position * cfg.dt
    if terminal is not None:  # along and across the target's heading, as the QP weighs them
        d = real[-1, :3] - (tx, ty, theta_t)
        end = end_cost(terminal, cfg.w_terminal_position, float(d[0]), float(d[1]), float(d[2]))
        return end + cfg.w_terminal_heading * th_err**2 + run, pos_err, th_err
    return cfg.w_terminal_position * pos_err**2 + cfg.w_terminal_heading * th_err**2 + run, pos_err, th_err


def merit(cfg: CoreConfig, cost: float, pen: np.ndarray) -> float:
    """A rollout's true ``cost`` plus the exact penalty on its footprint's largest
    penetration per step (``pen``), by the QP's own slack weight (``slack_weights``)."""
    return cost + cfg.w_slack * float(np.clip(pen + cfg.obstacle_margin, 0, None).sum())


def band_penalty(cfg: CoreConfig, outside: float) -> float:
    """The exact penalty on a switch ``outside`` [m] its band, by the QP's slack weight."""
    return cfg.w_slack * outside


def slack_weights(cfg: CoreConfig, n: int) -> np.ndarray:
    """The QP's linear cost on each of ``n`` slacks of its soft rows: the exact penalty."""
    return np.full(n, cfg.w_slack)


# -- the price of driving, in metres ---------------------------------------------------
def plan_price(price: PriceConfig, real: np.ndarray, switches: int, end_value: float) -> float:
    """J, by which the cost-to-go strategy compares optimised plans: the states' (x, y,
    theta, v, ...) path, reversed where v < 0, through ``switches``, plus the cost to go
    where it ends."""
    d = np.diff(real[:, :2], axis=0)
    ds = np.hypot(d[:, 0], d[:, 1])
    return path_price(price, ds, real[1:, 3] < 0, switches) + end_value


def penetration_price(price: PriceConfig, pen: np.ndarray) -> float:
    """A rollout's footprint penetration (its largest per step, ``pen``) priced: a seed that
    runs into an obstacle ranks behind the clear ones."""
    return price.penetration_cost * float(np.clip(pen, 0, None).sum())


def finish_price(cfg: CostToGoConfig, v: float, pose, target) -> float:
    """V at ``pose`` near the target, where V's cells are too coarse to rank poses: the pose
    error in metres of driving, at most ``finish_cap`` above V."""
    tx, ty, tth = target
    e = cfg.finish_position * math.hypot(pose[0] - tx, pose[1] - ty) + cfg.finish_heading * abs(
        unwrap_near(tth, pose[2]) - pose[2]
    )
    return v + min(max(e - v, 0.0), cfg.finish_cap)


@lru_cache(maxsize=256)
def cost_pattern(cfg: CoreConfig, s: int | None, terminal: Terminal | None = None):
    """(L, w, residual kinds, (P's pattern with the trust penalty, P's values, trust's
    values)) for switch step ``s``; built once per config (and ``terminal``) and shared by
    episodes. Kinds: 1, 2, 3 x, y, heading toward the goal; 4 the end's position along
    ``terminal``'s heading, 5, 6 its front and rear across it; 0 no goal."""
    N = cfg.horizon
    iS = switch_index(N)
    nz = iS + 2
    kappa = 1.0 if s is not None else 0.0
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
        if i == N and terminal is not None:
            c, sn = math.cos(terminal.heading), math.sin(terminal.heading)
            add([(ix(i, XI_X), c), (ix(i, XI_Y), sn), (iS, -2.0 * kappa * c), (iS + 1, -2.0 * kappa * sn)], 4, wp)
            # The body's front and rear ends across the target's heading, real frame (real =
            # 2 S - planned after the switch; the heading is not reflected), linearised in
            # the heading: the real rear axle's offset + arm * heading error.
            flip, shift = 1.0 - 2.0 * kappa, 2.0 * kappa
            for arm, kind in ((terminal.front, 5), (-terminal.rear, 6)):
                add(
                    [
                        (ix(i, XI_X), -flip * sn),
                        (ix(i, XI_Y), flip * c),
                        (iS, -shift * sn),
                        (iS + 1, shift * c),
                        (ix(i, XI_TH), arm),
                    ],
                    kind,
                    0.5 * terminal.w_lateral,
                )
        else:
            for j, kind in ((XI_X, 1), (XI_Y, 2)):
                add([(ix(i, j), 1.0), (iS + j, -2.0 * kappa)], kind, wp)
        add([(ix(i, XI_TH), 1.0)], 3, wh)
    add([(ix(N, XI_A), 1.0)], 0, cfg.w_terminal_accel)
    for i in range(N):
        add([(iu(i, 0), 1.0)], 0, cfg.w_accel_cmd * cfg.dt)
        add([(iu(i, 1), 1.0)], 0, cfg.w_steer_cmd * cfg.dt)
        if i > 0 and i != s:  # no rate cost across the switch (commands flip)
            add([(iu(i, 0), 1.0), (iu(i - 1, 0), -1.0)], 0, cfg.w_accel_rate)
            add([(iu(i, 1), 1.0), (iu(i - 1, 1), -1.0)], 0, cfg.w_steer_rate)
    L = sp.csr_matrix((vals, (rows, cols)), shape=(r, nz))
    w = np.asarray(w)
    P = sp.triu(2.0 * (L.T @ sp.diags(w) @ L)).tocsc()  # piqp reads the upper triangle
    # P + scale * trust shares one pattern: (pattern, P's values, trust's values).
    Pc, T = P.tocoo(), _trust_diag(cfg, nz).tocoo()
    pattern = CscPattern(np.concatenate([Pc.row, T.row]), np.concatenate([Pc.col, T.col]), P.shape)
    zp, zt = np.zeros(Pc.nnz), np.zeros(T.nnz)
    with_trust = (pattern, np.concatenate([Pc.data, zt]), np.concatenate([zp, T.data]))
    return L, w, np.asarray(kinds), with_trust


def _trust_diag(cfg: CoreConfig, nz: int) -> sp.csc_matrix:
    d = np.zeros(nz)
    xi = x_index(cfg.horizon)
    for j, w in ((XI_X, cfg.w_trust_position), (XI_Y, cfg.w_trust_position), (XI_TH, cfg.w_trust_heading)):
        d[xi[1:, j]] = 2.0 * w
    return sp.diags(d, format="csc")
