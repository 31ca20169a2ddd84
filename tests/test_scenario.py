"""Scenarios: validation with clear errors, ids, geometry invariants."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mirrorpark_env import ParkingType, Scenario, default_grid_cases
from mirrorpark_env.geometry import is_convex


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(parking_type="diagonal"), r"parking_type: unknown 'diagonal'; allowed: parallel, reverse, angle"),
        (dict(y0=float("nan")), r"y0: must be a finite number"),
        (dict(road_width=-1.0), r"road_width: must be in \(0, 50\] m, got -1.0"),
        (dict(slot_width="wide"), r"slot_width: expected a number"),
        (dict(y0=9.0), r"y0: must be in \[0, road_width=4.0\] m, got 9.0"),
        (dict(theta0=4.0), r"theta0: must be in \[-pi, pi\]"),
    ],
)
def test_bad_inputs_name_the_field(kwargs, match):
    base = dict(parking_type="parallel", road_width=4.0, slot_length=5.0, slot_width=2.5, theta0=0.0, y0=2.0)
    with pytest.raises(ValueError, match=match):
        Scenario(**{**base, **kwargs})


def test_slot_narrower_than_the_car_cannot_be_built():
    with pytest.raises(
        ValueError, match=r"slot too small for the car: reverse slot 4.82 x 1.60 m needs slot_width >= car width 1.67"
    ):
        Scenario.from_degrees("reverse", 6.0, 4.82, 1.60, 0, 2.0).build()
    with pytest.raises(ValueError, match=r"slot too small.*slot_length >= car length 3.82"):
        Scenario.from_degrees("parallel", 4.0, 3.5, 2.5, 0, 2.0).build()


def test_start_outside_the_road_cannot_be_built():
    # Heading 0: the car's sides are 0.835 m from the rear axle, so y0 = 0.5 crosses Y = 0.
    with pytest.raises(ValueError, match=r"y0=0.5 m, theta0=0.0 deg: the start footprint leaves the road strip"):
        Scenario.from_degrees("parallel", 4.0, 5.0, 2.5, 0, 0.5).build()


def test_parking_type_parses_strings():
    assert Scenario.from_degrees("ANGLE", 4.0, 4.82, 2.0, 0, 2.0).parking_type is ParkingType.ANGLE


def test_case_id_round_trip():
    sc = Scenario.from_degrees("reverse", 6.0, 4.82, 2.17, -30, 2.5, start_x_offset=1.0)
    assert sc.case_id == "reverse_rw6.00_sl4.82_sw2.17_th-30_y2.50_dx+1.00"
    assert Scenario.from_case_id(sc.case_id) == sc
    with pytest.raises(ValueError, match="case id: cannot parse"):
        Scenario.from_case_id("not-an-id")


def test_start_and_target_poses():
    sc = Scenario.from_degrees("angle", 4.0, 4.82, 2.0, 20, 2.0)
    g = sc.build()
    assert g.start.x == pytest.approx(2.0 * math.sqrt(2))  # level with the slot's far end
    assert (g.start.y, g.start.theta) == pytest.approx((2.0, math.radians(20)))
    assert g.target[2] == pytest.approx(math.pi / 4)


def test_geometry_invariants_on_a_grid_sample():
    """Start clear of obstacles, target inside the slot and clear, all regions convex."""
    grid = default_grid_cases()
    for sc in grid.sample(60, seed=3):
        g = sc.build()
        assert all(is_convex(p) for p in g.obstacles.polygons)
        s = g.start
        assert not g.checker.collides(s.x, s.y, s.theta)[0], sc.case_id
        tx, ty, tth = g.target
        assert not g.checker.collides(tx, ty, tth)[0], sc.case_id
        centre = np.array([tx, ty]) + g.vehicle.center_offset * np.array([math.cos(tth), math.sin(tth)])
        assert all(hp.signed_distance(centre) > 0 for _, hp in g.slot_edges)
