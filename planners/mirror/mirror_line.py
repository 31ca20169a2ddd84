"""Mirror line (paper section II.B) and mirrored target (docs/design.md).

The mirror line is parallel to the slot's axis (the target heading), on the right-hand
side of the parked car at distance ``l_mi`` from the target's axis line:

- parallel: deeper in the slot than the target (Theorem 1): the car reverses to the
  line, then drives forward to the target;
- reverse, angle: in the road, ahead of the slot (Eqs. 5, 6): the car drives forward to
  the line, then reverses into the slot.

``psi`` below is the heading change still to go at the line, |theta_target - theta|.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import brentq

from mirrorpark_env.angles import unwrap_near
from mirrorpark_env.scenario import ParkingType, ScenarioGeometry
from mirrorpark_env.vehicle import VehicleParams


def reach_lower_bound(params: VehicleParams, psi: float) -> float:
    """Eqs. (1), (5), (6): l_mi >= r_min (1 - cos psi), to turn psi back within full lock."""
    return params.r_min * (1.0 - math.cos(psi))


def parallel_upper_bound(params: VehicleParams, slot_width: float, psi: float) -> float:
    """Eq. (2): the rear corner on the kerb side stays inside the slot at the line."""
    return 0.5 * slot_width - params.rear_overhang * math.sin(psi) - 0.5 * params.width * math.cos(psi)


def parallel_dark_point(params: VehicleParams, slot_width: float) -> tuple[float, float]:
    """(psi*, l*): where the bounds of Theorem 1 meet.

    For a fixed l the feasible headings are [0, min(psi_low(l), psi_up(l))]; the crossing
    of the bounds maximises that range, the paper's robust "dark point" (Fig. 8). Returns
    (0, 0) when the slot is too narrow for any band (upper bound < 0 at psi = 0).
    """

    def gap(psi: float) -> float:
        return parallel_upper_bound(params, slot_width, psi) - reach_lower_bound(params, psi)

    if gap(0.0) <= 0.0:
        return 0.0, 0.0
    psi = brentq(gap, 0.0, math.pi / 2)
    return psi, reach_lower_bound(params, psi)


@dataclass(frozen=True)
class MirrorLine:
    """Points p with ``normal . (p - target_xy) = distance`` (``fixed``), or ``>=`` it."""

    target_xy: tuple[float, float]
    normal: tuple[float, float]  # unit, right of the target heading
    distance: float  # l_mi [m]
    fixed: bool  # True: the switch lies on the line; False: at least this far out
    psi: float  # heading change the distance was computed for [rad]

    def offset(self, p) -> float:
        """Signed distance of point ``p`` from the target's axis line along ``normal``."""
        p = np.asarray(p, float)
        return float((p[0] - self.target_xy[0]) * self.normal[0] + (p[1] - self.target_xy[1]) * self.normal[1])


def right_normal(heading: float) -> tuple[float, float]:
    return (math.sin(heading), -math.cos(heading))


def mirror_line(geometry: ScenarioGeometry, psi: float | None = None, margin: float = 1.1) -> MirrorLine:
    """The mirror line of a scenario.

    Parallel: the dark point of Theorem 1 (fixed line). Reverse and angle: the lower bound
    of Eq. (5) / (6) for a heading change ``psi`` (default: the full turn from the road's
    direction, 90 / 45 deg), times ``margin`` so the turn keeps some steering in reserve;
    the switch may lie further out, where the road allows.
    """
    p = geometry.vehicle
    tx, ty, tth = geometry.target
    n = right_normal(tth)
    if geometry.parking_type is ParkingType.PARALLEL:
        psi_star, l_star = parallel_dark_point(p, geometry.slot_width)
        return MirrorLine((tx, ty), n, l_star, True, psi_star)
    if psi is None:
        psi = abs(tth)  # from heading 0 (along the road) to the target heading
    return MirrorLine((tx, ty), n, margin * reach_lower_bound(p, psi), False, psi)


class SlotLines:
    """A slot's mirror line, and the one for a plan from a given heading."""

    def __init__(self, geometry: ScenarioGeometry, margin: float):
        self.g, self.margin = geometry, margin
        self.slot = mirror_line(geometry, margin=margin)

    def from_heading(self, theta: float) -> MirrorLine:
        """Theorem 1's line (parallel), else Eqs. (5), (6) bound by the heading change still to go."""
        if self.slot.fixed:
            return self.slot
        psi = min(abs(unwrap_near(self.g.target[2], theta) - theta), math.pi / 2)
        return mirror_line(self.g, psi=psi, margin=self.margin)


def mirrored_target(target: tuple[float, float, float], switch_xy) -> tuple[float, float, float]:
    """The real target reflected through the switch point (Theorem 2): heading unchanged."""
    sx, sy = switch_xy
    return (2 * sx - target[0], 2 * sy - target[1], target[2])


@dataclass(frozen=True)
class SwitchBand:
    """Rows ``a_s . S + a_theta theta_s >= lo`` on the switch point S and the heading
    theta_s at the switch step: where a plan's switch may lie.

    The lower row is the reach bound of Eqs. (1), (5), (6) (from the switch, one arc
    within full lock turns the car onto its goal's axis); the optional second row is
    Theorem 1's upper bound, Eq. (2) (the rear corner stays off the kerb). Both are
    linearised at a reference switch heading (SCP re-linearises each round)."""

    a_s: tuple[tuple[float, float], ...]
    a_theta: tuple[float, ...]
    lo: tuple[float, ...]


def switch_band(
    params: VehicleParams,
    goal,
    theta_ref: float,
    after: int,
    margin: float = 1.0,
    slot_width: float | None = None,
) -> SwitchBand:
    """The band of a plan whose switch has heading ``theta_ref`` in the reference and whose
    real gear after the switch is ``after`` (+1 forward, -1 reverse), toward ``goal``
    (x, y, theta; theta on the branch of ``theta_ref``).

    With psi = |theta_s - theta_goal| and l the switch point's offset from the goal's
    axis on the side the last arc comes from: l >= margin r_min (1 - cos psi), and, given
    ``slot_width`` (parallel parking into the slot), l <= SW / 2 - l1 sin psi - W / 2 cos psi.
    """
    gx, gy, gth = (float(v) for v in goal)
    err = theta_ref - gth
    sign_e, a_s = _arc_side(err, after, gth)
    l_goal = a_s[0] * gx + a_s[1] * gy  # l = a_s . S - l_goal
    psi = abs(err)
    r = margin * params.r_min
    # l - r (1 - cos psi_r) - r sin psi_r (psi - psi_r) >= 0, psi = sign_e (theta_s - gth)
    k = r * math.sin(psi)
    rows_s, rows_th, lo = [a_s], [-k * sign_e], [l_goal + r * (1.0 - math.cos(psi)) - k * psi - k * sign_e * gth]
    if slot_width is not None:
        # U(psi_r) + U'(psi_r) (psi - psi_r) - l >= 0
        u = parallel_upper_bound(params, slot_width, psi)
        du = -params.rear_overhang * math.cos(psi) + 0.5 * params.width * math.sin(psi)
        rows_s.append((-a_s[0], -a_s[1]))
        rows_th.append(du * sign_e)
        lo.append(-l_goal - u + du * psi + du * sign_e * gth)
    return SwitchBand(tuple(rows_s), tuple(rows_th), tuple(lo))


def _arc_side(err: float, after: int, goal_heading: float) -> tuple[float, tuple[float, float]]:
    """(sign of the heading error, unit normal of the goal's axis toward the side the last
    arc comes from): a switch with heading error ``err`` that drives in gear ``after``."""
    sign_e = 1.0 if err >= 0.0 else -1.0
    n = right_normal(goal_heading)
    side = sign_e * after
    return sign_e, (side * n[0], side * n[1])


def band_margin(
    params: VehicleParams,
    goal,
    pose,
    after: int,
    margin: float = 1.0,
    slot_width: float | None = None,
) -> float:
    """How far [m] a switch at ``pose`` (x, y, theta) lies inside the band of
    ``switch_band`` (exact, not linearised): negative outside."""
    gx, gy, gth = (float(v) for v in goal)
    x, y, th = (float(v) for v in pose)
    err = math.remainder(th - gth, 2 * math.pi)
    _, a_s = _arc_side(err, after, gth)
    offset = a_s[0] * (x - gx) + a_s[1] * (y - gy)
    psi = abs(err)
    inside = offset - margin * reach_lower_bound(params, psi)
    if slot_width is not None:
        inside = min(inside, parallel_upper_bound(params, slot_width, psi) - offset)
    return inside
