"""The hybrid A* baseline: Reeds-Shepp connection, exact clearance, closed loop, budget."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest
import shapely
from fixed_cases import EASY_CASES
from ompl import base as ob

import mirrorpark_env  # noqa: F401
from mirrorpark_env import Scenario, VehicleParams
from mirrorpark_env.vehicle import footprint
from planners.base import run_episode
from planners.common import reeds_shepp
from planners.common.path import Path
from planners.common.reeds_shepp import ReedsShepp
from planners.hybrid_astar.heuristic import GridDistance
from planners.hybrid_astar.policy import HybridAStarPolicy
from planners.hybrid_astar.search import HybridAStar, HybridAStarConfig

P = VehicleParams.table_ii()
R = P.wheelbase / math.tan(P.max_steer_rad)


def test_reeds_shepp_on_an_empty_map_stays_within_limits():
    rs = ReedsShepp(R)
    rng = np.random.default_rng(0)
    for _ in range(20):
        a = (*rng.uniform(-5, 5, 2), rng.uniform(-math.pi, math.pi))
        b = (*rng.uniform(-5, 5, 2), rng.uniform(-math.pi, math.pi))
        poses = rs.sample(a, b, 0.05)
        assert poses[0] == pytest.approx(a) and poses[-1] == pytest.approx(b)
        step = np.hypot(*np.diff(poses[:, :2], axis=0).T)
        assert step.max() <= 0.05 + 1e-9
        path = Path.from_poses(poses)
        # Chords of the arcs: never longer; shorter by at most a sample per cusp cut across.
        length = rs.distance(a, b)
        assert length - 0.05 * (path.switches + 1) <= step.sum() <= length + 1e-9
        # Curvature within the car's limit, except for chords that cut across a cusp (next
        # to a gear change, or at an end, where a segment shorter than a sample may sit).
        inner = np.ones(len(poses), dtype=bool)
        cusp = np.flatnonzero(np.diff(path.direction)) + 1
        inner[np.concatenate((cusp - 1, cusp, cusp + 1, [0, 1, len(poses) - 1])).clip(0, len(poses) - 1)] = False
        assert np.abs(path.curvature[inner]).max() <= (1 / R) * (1 + 1e-4)  # chord, not arc
    # A pure lateral shift needs turning both ways: longer than the shift itself.
    assert rs.distance((0, 0, 0), (0, 1, 0)) > 2.0


def test_reeds_shepp_segments_agree_with_ompl():
    """The segment solver (``reeds_shepp``) against ompl's state space: the same optimal
    length, paths that end at the goal with the car's curvature, and ompl's own poses
    except where two words tie for the optimum (ompl then keeps whichever rounding favours)."""
    rs = ReedsShepp(R)
    space = ob.ReedsSheppStateSpace(R)
    s_a, s_b, s_c = space.allocState(), space.allocState(), space.allocState()
    rng = np.random.default_rng(1)
    same = 0
    for n in range(400):
        a = np.array([*rng.uniform(-6, 6, 2), rng.uniform(-math.pi, math.pi)])
        b = np.array([*rng.uniform(-6, 6, 2), rng.uniform(-math.pi, math.pi)])
        if n % 4 == 0:  # short hops: the parking-scale cases
            b = a + np.array([*rng.normal(0, 0.5, 2), rng.normal(0, 0.3)])
        kinds, lengths = reeds_shepp.path(a, b, R)
        assert sum(abs(v) for v in lengths) == pytest.approx(rs.distance(a, b), abs=1e-9)
        poses = rs.sample(a, b, 0.1)
        # The unforced end: the segments' last sample lands on the goal.
        end = reeds_shepp.sample(a, b, R, 0.1)[-2]
        assert np.hypot(*(end[:2] - b[:2])) <= 0.1 + 1e-9
        dth = np.abs(np.diff(poses[:-1, 2]))
        assert dth.max() <= 0.1 / R + 1e-9  # turning at most at the car's curvature
        # ompl's poses at the same fractions of the path.
        s_a.setXY(*a[:2]), s_a.setYaw(a[2]), s_b.setXY(*b[:2]), s_b.setYaw(b[2])
        ref = []
        for t in np.linspace(0, 1, len(poses)):
            space.interpolate(s_a, s_b, t, s_c)
            ref.append((s_c.getX(), s_c.getY()))
        same += np.abs(np.array(ref)[1:-1] - poses[1:-1, :2]).max(initial=0.0) < 1e-6
    assert same >= 0.9 * 400


def test_the_compiled_distance_is_ompls_bit_for_bit_and_place_one_is_places():
    """``reeds_shepp.distance`` replays ompl's comparisons: its lengths equal ompl's exactly,
    on random poses and on the aligned and mirrored poses where words tie; ``place_one``
    (inside the compiled search) gives ``place``'s poses."""
    space = ob.ReedsSheppStateSpace(R)
    s_a, s_b = space.allocState(), space.allocState()
    rng = np.random.default_rng(2)
    cases = [np.array([*rng.uniform(-8, 8, 2), rng.uniform(-4, 4)]) for _ in range(4000)]
    cases += [
        np.array([x, y, th]) for x in (-2.0, 0.0, 1.5) for y in (-1.0, 0.0, 1.0) for th in (0.0, math.pi, -math.pi / 2)
    ]
    for n, b in enumerate(cases):
        a = np.array([0.3, -0.2, 0.1]) if n % 2 else np.zeros(3)
        s_a.setXY(*a[:2]), s_a.setYaw(a[2]), s_b.setXY(*b[:2]), s_b.setYaw(b[2])
        assert reeds_shepp.distance(*a, *b, R) == space.distance(s_a, s_b)
        word, lengths, total = reeds_shepp.solve(*a, *b, R)
        kinds, segs = reeds_shepp.path(a, b, R)
        assert total == pytest.approx(sum(abs(v) for v in segs), rel=1e-12)
        want = reeds_shepp.place(a, [b], [(kinds, segs)], R, 0.05)[0]
        got = reeds_shepp.place_one(*a, b, word, lengths, R, 0.05)
        assert got.shape == want.shape and np.abs(got - want).max() <= 1e-12


def test_grid_distance_is_a_lower_bound_around_a_wall():
    g = Scenario.from_degrees("reverse", 6.0, 4.82, 2.3, 0, 2.5).build()
    window = (-10.0, 15.0, g.bounds[2], 6.0)
    grid = GridDistance(g.obstacles, window, g.target[:2], resolution=0.25)
    tx, ty = g.target[:2]
    # Straight above the target: never more than the straight line (a lower bound), and
    # within the octile discount of it.
    straight = math.hypot(0.0, 3.0 - ty)
    assert 0.85 * straight <= grid(tx, 3.0) <= straight
    # Above the left neighbour the straight line cuts through it: the rear axle must go
    # round its corner at (0, 0), kept 0.5 m away, so the distance is visibly longer.
    straight = math.hypot(-3.0 - tx, 3.0 - ty)
    around = math.hypot(-3.0 - 0.5, 3.0) + math.hypot(0.5 - tx, ty)
    assert straight + 0.1 <= grid(-3.0, 3.0) <= around
    assert math.isinf(grid(-5.0, -2.0))  # inside the left neighbour


def _swept_clear(geometry, poses, clearance):
    """Footprints at 5 mm spacing along the path, each at least ``clearance`` from every obstacle."""
    fine = [poses[0]]
    for a, b in zip(poses[:-1], poses[1:]):
        n = max(1, math.ceil(math.hypot(*(b[:2] - a[:2])) / 0.005))
        t = np.linspace(0, 1, n + 1)[1:, None]
        dth = math.remainder(b[2] - a[2], 2 * math.pi)
        fine.extend(np.hstack((a[:2] + t * (b[:2] - a[:2]), a[2] + t * dth)))
    fine = np.array(fine)
    corners = footprint(geometry.vehicle, fine[:, 0], fine[:, 1], fine[:, 2])
    cars = shapely.polygons(corners)
    obstacles = [shapely.Polygon(p) for p in geometry.obstacles.polygons]
    return min(float(shapely.distance(cars, o).min()) for o in obstacles)


@pytest.mark.parametrize(
    "case_id",
    [
        "parallel_rw3.50_sl4.82_sw2.50_th+0_y1.70",  # tight: six switches
        "reverse_rw5.00_sl4.82_sw1.87_th-40_y3.00",
        "angle_rw3.50_sl4.82_sw2.02_th+0_y1.70",
    ],
)
def test_a_path_never_comes_near_an_obstacle(case_id):
    g = Scenario.from_case_id(case_id).build()
    planner = HybridAStar(g)
    path, stats = planner.plan((g.start.x, g.start.y, g.start.theta))
    assert stats.status == "ok" and path is not None
    assert path.poses[0] == pytest.approx((g.start.x, g.start.y, g.start.theta))
    assert path.poses[-1] == pytest.approx(g.target) or planner.in_goal_set(path.poses[-1])
    # Shapely, sampled ten times finer than the planner checks: the whole sweep keeps the clearance.
    assert _swept_clear(g, path.poses, 0.0) >= planner.cfg.clearance - 0.005


@pytest.mark.slow
@pytest.mark.parametrize(
    "case_id",
    [*EASY_CASES, "parallel_rw3.50_sl4.82_sw2.50_th+0_y1.70"],  # the last: tight, with switches
)
def test_easy_cases_park(case_id):
    env = gym.make("MirrorPark-v0").unwrapped
    policy = HybridAStarPolicy()
    info, _ = run_episode(env, policy, case_id)
    assert info["is_success"], (info["failed_criterion"], info["vehicle_state"])
    assert [s.status for s in policy.stats] == ["ok"]


def test_budget_exhaustion_is_a_status_not_an_exception():
    g = Scenario.from_case_id("parallel_rw3.50_sl4.82_sw2.50_th+0_y1.70").build()
    path, stats = HybridAStar(g, HybridAStarConfig(max_expansions=1)).plan((g.start.x, g.start.y, g.start.theta))
    assert path is None and stats.status == "budget"
    env = gym.make("MirrorPark-v0").unwrapped
    policy = HybridAStarPolicy(HybridAStarConfig(max_expansions=1))
    info, steps = run_episode(env, policy, "parallel_rw3.50_sl4.82_sw2.50_th+0_y1.70")
    assert policy.gave_up and policy.status == "budget" and steps == 1
    assert not info["is_success"] and not info["collision"]


def test_bad_config_is_rejected_naming_the_field():
    with pytest.raises(ValueError, match=r"n_steer: must be odd"):
        HybridAStarConfig(n_steer=4)
    with pytest.raises(ValueError, match=r"wall_clock_limit_s\n.*finite number"):
        HybridAStarConfig(wall_clock_limit_s=float("nan"))
    with pytest.raises(ValueError, match=r"max_expansions\n.*greater than or equal to 1"):
        HybridAStarConfig(max_expansions=0)
    with pytest.raises(ValueError, match=r"steer_fraction\n.*less than or equal to 1"):
        HybridAStarConfig(steer_fraction=1.5)


def test_reeds_shepp_path_placed_twice_equals_sampling_twice():
    """The search solves a connection once and samples it at two spacings: the same poses
    as solving it for each."""
    rs = ReedsShepp(4.0)
    rng = np.random.default_rng(3)
    for _ in range(50):
        a = (rng.uniform(-5, 5), rng.uniform(-5, 5), rng.uniform(-math.pi, math.pi))
        b = (rng.uniform(-5, 5), rng.uniform(-5, 5), rng.uniform(-math.pi, math.pi))
        p = rs.path(a, b)
        for step in (0.05, 0.2):
            np.testing.assert_array_equal(rs.place(a, b, p, step), rs.sample(a, b, step))


@pytest.mark.slow
@pytest.mark.parametrize(
    "case_id",
    [
        # The car reaches the last cusp 5 deg off heading (inside the tracker's tolerance) and,
        # braking, would touch the road's far edge.
        "reverse_rw5.00_sl4.82_sw2.07_th-70_y3.50",
        # A start 2 cm from the road's edge: a few centimetres of tracking error would use it up.
        "angle_rw3.50_sl4.82_sw1.97_th-30_y2.30",
    ],
)
def test_the_stopping_check_brakes_before_tracking_error_meets_an_obstacle(case_id):
    # The search as it was when these cases touched (the tuned one plans them other ways).
    first = HybridAStarConfig(
        fine_gap=0.0, heuristic_weight=1.5, start_relief=1.0, start_gap_share=1.0, max_expansions=10_000, interleave=0
    )
    env = gym.make("MirrorPark-v0").unwrapped
    unchecked = HybridAStarPolicy(first, stopping_check=False)
    info, _ = run_episode(env, unchecked, case_id)
    assert info["collision"]  # what the check is for: without it these cases touch
    policy = HybridAStarPolicy(first)
    info, _ = run_episode(env, policy, case_id)
    assert info["is_success"] and not info["collision"] and info["min_clearance"] > 0
    assert policy.safety_stops >= 1


@pytest.mark.slow
def test_the_stopping_check_lets_the_car_leave_a_tight_start():
    # The start is 7.6 mm from a neighbour; tracking away from it costs a few tenths of a
    # millimetre of that gap, which the check allows (half the start's gap), so the car leaves.
    env = gym.make("MirrorPark-v0").unwrapped
    policy = HybridAStarPolicy()
    info, _ = run_episode(env, policy, "reverse_rw6.00_sl4.82_sw2.57_th+40_y1.10")
    assert info["is_success"] and not info["collision"]
    assert policy.safety_stops == 0


# -- the two anomalies of the first full grid (docs/hybrid_astar.md, "Tuning") -------------------

TIGHT_SLOT = "parallel_rw4.50_sl4.52_sw2.50_th+0_y1.50"  # 1.18 car lengths: shuffles in the slot
STEEP_START = "parallel_rw4.50_sl5.52_sw2.50_th+70_y1.10"  # across the road, 15 cm from its far edge
WALL_START = "parallel_rw3.50_sl6.32_sw2.50_th+0_y2.60"  # along the far edge, 6.5 cm from it


@pytest.mark.parametrize("case_id", [TIGHT_SLOT, STEEP_START])
def test_coarse_cells_close_the_shuffles_of_a_tight_manoeuvre(case_id):
    """Cells of 5 deg everywhere close each short shuffle (1-2 deg of turn) as a state already
    seen: the tight slot spent its budget and the wedged start ran out of states. Finer cells
    where the car is tight find both."""
    g = Scenario.from_case_id(case_id).build()
    start = (g.start.x, g.start.y, g.start.theta)
    _, coarse = HybridAStar(g, HybridAStarConfig(fine_gap=0.0)).plan(start)
    assert coarse.status in ("budget", "no_path")
    path, stats = HybridAStar(g).plan(start)
    assert stats.status == "ok" and path is not None and path.switches >= 3


def test_a_car_along_a_wall_may_use_half_its_gap_to_turn_away():
    """Turning away from a wall swings the car's far corner toward it first: keeping the
    whole start gap within 1 m of the start (the first search) leaves no way out; half of
    it within 2.5 m does (the stopping check also keeps half)."""
    g = Scenario.from_case_id(WALL_START).build()
    start = (g.start.x, g.start.y, g.start.theta)
    _, whole = HybridAStar(g, HybridAStarConfig(start_relief=1.0, start_gap_share=1.0)).plan(start)
    assert whole.status == "no_path"
    path, stats = HybridAStar(g).plan(start)
    assert stats.status == "ok" and path is not None


@pytest.mark.slow
@pytest.mark.parametrize("case_id", [TIGHT_SLOT, STEEP_START, WALL_START])
def test_the_anomalies_park_in_closed_loop(case_id):
    env = gym.make("MirrorPark-v0").unwrapped
    info, _ = run_episode(env, HybridAStarPolicy(), case_id)
    assert info["is_success"] and not info["collision"]


def test_the_search_is_deterministic():
    g = Scenario.from_case_id(TIGHT_SLOT).build()
    start = (g.start.x, g.start.y, g.start.theta)
    (p1, s1), (p2, s2) = HybridAStar(g).plan(start), HybridAStar(g).plan(start)
    assert (s1.status, s1.iterations, s1.nodes) == (s2.status, s2.iterations, s2.nodes)
    np.testing.assert_array_equal(p1.poses, p2.poses)


def test_the_reeds_shepp_part_never_exceeds_a_path_of_primitives():
    """The non-holonomic part of the heuristic is the Reeds-Shepp length at the search's own
    curvature limit: no chain of the search's primitives (arcs at most that curved, either
    gear) joins two poses in less."""
    g = Scenario.from_case_id(TIGHT_SLOT).build()
    hs = HybridAStar(g)
    offsets, _, _ = hs._primitives
    rng = np.random.default_rng(7)
    for _ in range(200):
        pose = np.array([0.0, 0.0, rng.uniform(-math.pi, math.pi)])
        start, length = pose.copy(), 0.0
        for p in rng.integers(0, len(offsets), rng.integers(1, 12)):
            k = int(rng.integers(1, offsets.shape[1] + 1))  # a primitive, maybe cut short
            c, s = math.cos(pose[2]), math.sin(pose[2])
            dx, dy, dth = offsets[p, k - 1]
            pose = np.array([pose[0] + c * dx - s * dy, pose[1] + s * dx + c * dy, pose[2] + dth])
            length += k * hs.sample_spacing
        assert hs.rs.distance(tuple(start), tuple(pose)) <= length + 1e-6


def test_the_grid_part_never_exceeds_a_finer_grids_shortest_path():
    """The holonomic part (0.25 m cells, octile and rounding taken off) stays below the
    shortest path of a grid five times finer, wherever the rear axle can be (0.71 m from
    every obstacle: the disc about it that the footprint always holds)."""
    g = Scenario.from_case_id(TIGHT_SLOT).build()
    window = (-8.0, 14.0, g.bounds[2], g.bounds[3])
    coarse = GridDistance(g.obstacles, window, g.target[:2], resolution=0.25)
    fine = GridDistance(g.obstacles, window, g.target[:2], resolution=0.05)
    rng = np.random.default_rng(11)
    obstacles = [shapely.Polygon(p) for p in g.obstacles.polygons]
    checked = 0
    while checked < 300:
        x, y = rng.uniform(window[0], window[1]), rng.uniform(window[2], window[3])
        if min(o.distance(shapely.Point(x, y)) for o in obstacles) < 0.71:
            continue
        reference = fine.dist[fine._cell(x, y)]  # the finer grid's own path length, undiscounted
        assert coarse(x, y) <= reference + 0.05, (x, y)
        checked += 1
