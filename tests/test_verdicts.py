"""ISO success and collision verdicts on poses worked out by hand, per parking type.

Parallel slot 5.5 x 2.5 m: target rear axle (1.55, -1.25), heading 0, which leaves
M_r = 1.55 - 0.71 = 0.84, M_f = 5.5 - (1.55 + 3.11) = 0.84, M_e = 1.25 - 0.835 = 0.415.
Reverse slot 2.3 x 4.82 m: target (1.15, -3.61), heading 90 deg: side gaps
(2.3 - 1.67) / 2 = 0.315, entrance gap 4.82 - 0.71 - 3.61 ... = 0.5.
Angle slot 2.3 x 4.82 m at 45 deg: the same gaps in the slot's own frame.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from mirrorpark_env import Scenario, SuccessCriteria

DEG = math.pi / 180


def check(g, x, y, th, v=0.0, t=30.0):
    collided = bool(g.checker.collides(x, y, th)[0])
    return SuccessCriteria(g).verdict(x, y, th, v, t, collided)


# ---------------------------------------------------------------- parallel
PAR = Scenario.from_degrees("parallel", 4.0, 5.5, 2.5, 0, 2.0).build()


def test_parallel_target_is_a_success_with_the_hand_margins():
    x, y, th = PAR.target
    assert (x, y, th) == pytest.approx((1.55, -1.25, 0.0))
    v = check(PAR, x, y, th)
    assert v.success and v.failed is None
    assert v.margins == pytest.approx({"M_f": 0.84, "M_r": 0.84, "M_e": 0.415})


def test_parallel_touching_the_rear_end_is_no_collision_but_no_success():
    v = check(PAR, 0.71, -1.25, 0.0)  # rear bumper exactly on X = 0
    assert not v.collision
    assert v.margins["M_r"] == pytest.approx(0.0, abs=1e-12)
    assert not v.success and v.failed == "margins"  # parallel needs M_r > 0


def test_parallel_five_cm_over_the_rear_end_is_a_collision():
    v = check(PAR, 0.66, -1.25, 0.0)
    assert v.collision and v.failed == "collision"
    assert not v.inside_slot


def test_parallel_heading_four_degrees_off_fails_three_passes():
    assert check(PAR, 1.55, -1.25, 4 * DEG).failed == "heading"
    assert check(PAR, 1.55, -1.25, -4 * DEG).failed == "heading"
    assert check(PAR, 1.55, -1.25, 2.9 * DEG).success


def test_parallel_outer_margin_must_be_positive():
    # Car lifted so its road-side edge lies on the slot line: M_e = 0 -> not inside strictly.
    v = check(PAR, 1.55, -0.835, 0.0)
    assert v.margins["M_e"] == pytest.approx(0.0, abs=1e-12)
    assert not v.collision and not v.success and v.failed == "margins"
    v = check(PAR, 1.55, -0.785, 0.0)  # 5 cm into the road: outside the slot, no obstacle there
    assert not v.collision and not v.inside_slot and v.failed == "inside_slot"


def test_moving_or_late_is_no_success():
    x, y, th = PAR.target
    assert check(PAR, x, y, th, v=0.2).failed == "stopped"
    assert check(PAR, x, y, th, t=180.0).failed == "time"
    assert check(PAR, x, y, th, t=179.9).success


# ----------------------------------------------------------------- reverse
REV = Scenario.from_degrees("reverse", 6.0, 4.82, 2.3, 0, 2.5).build()


def test_reverse_target_margins():
    x, y, th = REV.target
    assert (x, y, th) == pytest.approx((1.15, -3.61, math.pi / 2))
    v = check(REV, x, y, th)
    assert v.success
    assert v.margins == pytest.approx({"M_fl": 0.315, "M_fr": 0.315, "M_rl": 0.315, "M_rr": 0.315, "M_e": 0.5})


@pytest.mark.parametrize(
    "shift, success, collision, failed",
    [
        (0.215, True, False, None),  # M_fr = M_rr = 0.1 m exactly: allowed (>= 0.1)
        (0.25, False, False, "margins"),  # 0.065 m left on the right
        (0.315, False, False, "margins"),  # touching the right neighbour
        (0.365, False, True, "collision"),  # 5 cm into it
    ],
)
def test_reverse_lateral_shift(shift, success, collision, failed):
    x, y, th = REV.target
    v = check(REV, x + shift, y, th)  # heading +Y: +X is the car's right
    assert (v.success, v.collision, v.failed) == (success, collision, failed)
    assert v.margins["M_fr"] == pytest.approx(0.315 - shift)


def test_reverse_heading_four_degrees_off():
    x, y, th = REV.target
    assert check(REV, x, y, th + 4 * DEG).failed == "heading"


def test_reverse_front_out_of_the_slot_is_not_inside():
    x, y, th = REV.target
    v = check(REV, x, y + 0.6, th)  # front 0.1 m beyond the entrance, over the open road
    assert not v.collision and not v.inside_slot
    assert v.margins["M_e"] == pytest.approx(-0.1)


def test_reverse_nose_in_is_wrong_heading():
    # Same body position, nose into the slot: rear axle 1.2 m above the body centre (1.15, -2.41).
    v = check(REV, 1.15, -2.41 + 1.2, -math.pi / 2)
    assert not v.collision and v.inside_slot
    assert v.failed == "heading"


# ------------------------------------------------------------------- angle
ANG = Scenario.from_degrees("angle", 4.0, 4.82, 2.3, 0, 2.0).build()
RIGHT = np.array([1.0, -1.0]) / math.sqrt(2)  # the parked car's right, for heading 45 deg


def test_angle_target_margins():
    x, y, th = ANG.target
    centre = np.array([2.3, -2.3]) / (2 * math.sqrt(2)) + 2.41 * np.array([-1.0, -1.0]) / math.sqrt(2)
    rear_axle = centre - 1.2 * np.array([1.0, 1.0]) / math.sqrt(2)
    assert (x, y, th) == pytest.approx((*rear_axle, math.pi / 4))
    v = check(ANG, x, y, th)
    assert v.success
    assert v.margins == pytest.approx({"M_fl": 0.315, "M_fr": 0.315, "M_rl": 0.315, "M_rr": 0.315, "M_e": 0.5})


@pytest.mark.parametrize(
    "shift, success, collision, failed",
    [(0.215, True, False, None), (0.315, False, False, "margins"), (0.365, False, True, "collision")],
)
def test_angle_lateral_shift(shift, success, collision, failed):
    x, y, th = ANG.target
    px, py = np.array([x, y]) + shift * RIGHT
    v = check(ANG, px, py, th)
    assert (v.success, v.collision, v.failed) == (success, collision, failed)


def test_angle_heading_four_degrees_off():
    x, y, th = ANG.target
    assert check(ANG, x, y, th - 4 * DEG).failed == "heading"


# ---------------------------------------------------------- an ISO pose exists
# Hand-worked limits for the paper's car (L = 3.82 m, W = 1.67 m): parallel SL > 3.82 and
# SW > 1.67; reverse and angle SW >= 1.67 + 2 x 0.1 = 1.87 and SL >= 3.82 + 0.1 = 3.92.
@pytest.mark.parametrize(
    "ptype, sl, sw, exists",
    [
        ("parallel", 3.821, 2.5, True),
        ("parallel", 3.819, 2.5, False),
        ("parallel", 3.82, 2.5, False),  # margins front and rear both 0: not > 0
        ("parallel", 5.0, 1.671, True),
        ("parallel", 5.0, 1.669, False),
        ("reverse", 4.82, 1.871, True),
        ("reverse", 4.82, 1.869, False),
        ("reverse", 3.921, 2.3, True),
        ("reverse", 3.919, 2.3, False),
        ("angle", 4.82, 1.871, True),
        ("angle", 4.82, 1.869, False),
    ],
)
def test_an_iso_pose_exists_just_above_the_limit_and_not_below(ptype, sl, sw, exists):
    from mirrorpark_env import VehicleParams
    from mirrorpark_env.criteria import iso_pose_exists

    P = VehicleParams.table_ii()
    assert bool(iso_pose_exists(ptype, sl, sw, P)) is exists
    if sl < P.length or sw < P.width:
        return  # narrower or shorter than the car: no geometry to search
    g = Scenario.from_degrees(ptype, 7.0 if ptype == "reverse" else 4.5, sl, sw, 0, 2.5).build()
    crit = SuccessCriteria(g)
    x, y, th = g.target
    # A brute-force search: every shift that keeps the car in the slot along its axis, shifts
    # across it, and heading errors within 3 deg; some pose passes exactly when one exists.
    u = np.array([math.cos(th), math.sin(th)])
    n = np.array([-u[1], u[0]])
    best = False
    room = 0.5 * (sl - P.length)
    for da in [*np.linspace(-room - 0.01, room + 0.01, 41), -room + 1e-9, room - 1e-9]:  # and against each end
        for dn in np.linspace(-0.05, 0.05, 11):
            for dth in np.radians([-3.0, -1.0, 0.0, 1.0, 3.0]):
                p = np.array([x, y]) + da * u + dn * n
                best |= crit.verdict(p[0], p[1], th + dth, 0.0, 0.0, False).success
    assert best is exists


@pytest.mark.parametrize(
    "ptype, sl, sw, slack",
    [
        ("parallel", 4.02, 2.5, 0.10),  # (4.02 - 3.82) / 2 front and rear; 0.83 m of width
        ("parallel", 5.0, 1.70, 0.03),  # the spare width decides
        ("parallel", 3.82, 2.5, 0.0),
        ("reverse", 4.82, 1.87, 0.0),  # exactly one pose: centred and aligned
        ("reverse", 4.82, 1.97, 0.05),  # (1.97 - 1.67) / 2 - 0.1
        ("angle", 3.95, 2.5, 0.03),  # the entrance margin decides: 3.95 - 3.82 - 0.1
        ("reverse", 4.82, 1.77, -0.05),
    ],
)
def test_room_to_spare_in_a_slot_by_hand(ptype, sl, sw, slack):
    from mirrorpark_env import VehicleParams
    from mirrorpark_env.criteria import iso_pose_exists, iso_pose_slack

    P = VehicleParams.table_ii()
    got = float(iso_pose_slack(ptype, sl, sw, P))
    assert got == pytest.approx(slack, abs=1e-9)
    if abs(slack) > 1e-6:
        assert bool(iso_pose_exists(ptype, sl, sw, P)) is (slack > 0)
