"""Exact footprint collision: against shapely and on hand-made poses."""

from __future__ import annotations

import math

import numpy as np
import pytest
from shapely.geometry import Polygon

from mirrorpark_env import Scenario, VehicleParams, footprint
from mirrorpark_env.geometry import ConvexSet, FootprintChecker

P = VehicleParams.table_ii()
SCENES = [
    Scenario.from_degrees("parallel", 3.5, 4.5, 2.5, 0, 1.2),
    Scenario.from_degrees("reverse", 5.0, 4.82, 2.0, 0, 2.0),
    Scenario.from_degrees("angle", 3.5, 4.82, 1.9, 0, 1.5),
]


@pytest.mark.parametrize("sc", SCENES, ids=lambda s: s.parking_type.value)
def test_collision_verdict_matches_shapely(sc):
    g = sc.build()
    polys = [Polygon(p) for p in g.obstacles.polygons]
    rng = np.random.default_rng(7)
    n = 2000
    x, y = rng.uniform(-6, 8, n), rng.uniform(-2.0, 3.0, n)
    th = rng.uniform(-math.pi, math.pi, n)
    got = g.checker.collides(x, y, th, tol=1e-7)
    corners = footprint(P, x, y, th)
    want = np.array([max(Polygon(c).intersection(p).area for p in polys) > 1e-9 for c in corners])
    depth = g.checker.penetration(x, y, th).max(axis=1)
    unsure = np.abs(depth) < 1e-6  # grazing contacts: shapely's area test cannot decide them
    assert want[~unsure].sum() > 100 and (~want[~unsure]).sum() > 50
    np.testing.assert_array_equal(got[~unsure], want[~unsure])


def test_penetration_depth_is_exact_on_an_axis_aligned_block():
    block = ConvexSet.from_polygons([np.array([[0, 0], [10, 0], [10, 5], [0, 5]])])
    ch = FootprintChecker(block, P.front_length, P.rear_overhang, P.width / 2)
    # Car heading +X with its rear at X = -0.05 - ... front end 0.05 m into the block.
    x = -P.front_length + 0.05
    assert ch.penetration(x, 2.0, 0.0)[0, 0] == pytest.approx(0.05)
    assert ch.collides(x, 2.0, 0.0)[0]
    touching = -P.front_length
    assert ch.penetration(touching, 2.0, 0.0)[0, 0] == pytest.approx(0.0, abs=1e-12)
    assert not ch.collides(touching, 2.0, 0.0)[0]
    # Rotated 90 deg: now the side must reach the block.
    assert not ch.collides(-P.width / 2 - 0.01, 2.0, math.pi / 2)[0]
    assert ch.collides(-P.width / 2 + 0.01, 2.0, math.pi / 2)[0]


def test_corner_piercing_the_side_is_found():
    """A sharp obstacle corner entering the car's long side, between the feature points."""
    wedge = ConvexSet.from_polygons([np.array([[1.0, 0.7], [1.5, -3.0], [0.5, -3.0]])])
    ch = FootprintChecker(wedge, P.front_length, P.rear_overhang, P.width / 2)
    assert ch.collides(0.0, 0.0, 0.0)[0]  # side of the car at y = -0.835; tip at y = 0.7
    assert not ch.collides(0.0, 1.6, 0.0)[0]


def test_non_convex_polygon_is_rejected():
    with pytest.raises(ValueError, match="not convex"):
        ConvexSet.from_polygons([np.array([[0, 0], [2, 0], [1, 0.2], [2, 2], [0, 2]])])


@pytest.mark.parametrize("sc", SCENES, ids=lambda s: s.parking_type.value)
def test_compiled_gaps_equal_the_checker_bit_for_bit(sc):
    """The planners' kernels return exactly the numpy checker's ``penetration`` (P, K)
    and (``clearance.gaps``) its negated ``max(axis=1)``: batches with and without an
    overlapping pose (the own-axes stage runs for a whole batch), of every size."""
    from planners.common.clearance import gap_kernel, gaps

    g = sc.build()
    rng = np.random.default_rng(11)
    tx, ty, _ = g.target
    overlapping = 0
    for n in (1, 2, 7, 80, 400):
        for spread in (0.3, 3.0):
            poses = np.column_stack(
                [tx + rng.normal(0, spread, n), ty + rng.normal(0, spread, n), rng.uniform(-4, 4, n)]
            )
            pen = g.checker.penetration(poses[:, 0], poses[:, 1], poses[:, 2])
            np.testing.assert_array_equal(gap_kernel(g.checker).penetration(poses), pen)
            want = -pen.max(axis=1)
            got = gaps(g.checker, poses)
            np.testing.assert_array_equal(got, want)
            overlapping += int((want < 0).any())
    assert overlapping >= 3  # the own-axes stage was exercised


@pytest.mark.parametrize("sc", SCENES, ids=lambda s: s.parking_type.value)
def test_compiled_single_pose_verdict_equals_the_batch_kernel(sc):
    """The search loops' ``_clear`` (one pose, early exit) and ``_clear_far`` (with a broad
    phase) say "clear by c" exactly where ``gaps(..., all_axes=True) >= c``: checked at each
    pose's own gap and the next float above it, so a verdict that differed by one rounding
    would fail."""
    from planners.common.clearance import gap_kernel, gaps
    from planners.common.kernels import _clear, _clear_far, broad_phase

    g = sc.build()
    args = gap_kernel(g.checker).args
    far = broad_phase(args[-1])
    rng = np.random.default_rng(12)
    tx, ty, _ = g.target
    n = 30000
    poses = np.column_stack([tx + rng.normal(0, 4.0, n), ty + rng.uniform(-3.0, 6.0, n), rng.uniform(-4, 4, n)])
    want = gaps(g.checker, poses, all_axes=True)
    near = (want >= 0) & (want < 0.1)
    pick = np.r_[np.flatnonzero(want < 0)[:1000], np.flatnonzero(near)[:500], np.flatnonzero(want >= 0.1)[:1000]]
    assert len(pick) > 2000  # both verdicts, and gaps near the usual clearances
    poses, want = poses[pick], want[pick]
    for (x, y, th), gap in zip(poses, want):
        c, s = math.cos(th), math.sin(th)
        for clearance in (gap, np.nextafter(gap, np.inf), 0.05, -0.2):
            assert _clear(x, y, c, s, clearance, *args) == (gap >= clearance)
            assert _clear_far(x, y, c, s, clearance, *args, *far) == (gap >= clearance)
