"""The mirror planner's geometric guide (Reeds-Shepp paths through the mirror line's switch
poses), guided plans, and the hard cases that need it."""

from __future__ import annotations

import itertools
import math

import gymnasium as gym
import numpy as np
import pytest
from fixed_cases import EASY_CASES

import mirrorpark_env  # noqa: F401
from mirrorpark_env import Scenario, VehicleParams
from planners.base import run_episode
from planners.common.clearance import START_RELIEF, gaps
from planners.mirror.guide import GuideSearch
from planners.mirror.mirror_line import (
    parallel_dark_point,
)
from planners.mirror.planner import MirrorPlanner
from planners.mirror.policy import MirrorPolicy
from planners.mirror.presets import preset_config

P = VehicleParams.table_ii()
R_MIN = 2.5 / math.tan(0.6)  # 3.6542 m


# ------------------------------------------------------------------------ guide
def _shapely_gap(geometry, poses) -> float:
    import shapely

    from mirrorpark_env.vehicle import footprint

    cars = shapely.polygons(footprint(geometry.vehicle, poses[:, 0], poses[:, 1], poses[:, 2]))
    return min(float(shapely.distance(cars, shapely.Polygon(p)).min()) for p in geometry.obstacles.polygons)


@pytest.mark.parametrize("case_id", EASY_CASES)
def test_guide_runs_from_the_start_to_the_target_clear_of_obstacles(case_id):
    """The guide joins start and target and every sample keeps its gap (checked by shapely)."""
    from planners.mirror.guide import GuideSearch

    env = gym.make("MirrorPark-v0").unwrapped
    _, info = env.reset(options={"scenario": case_id})
    g = info["geometry"]
    search = GuideSearch(g)
    s = g.start
    guide = search.search((s.x, s.y, s.theta))
    assert guide is not None
    poses = guide.path.poses
    assert np.allclose(poses[0], (s.x, s.y, s.theta))
    assert np.allclose(poses[-1][:2], g.target[:2], atol=1e-6)
    assert abs(math.remainder(poses[-1][2] - g.target[2], 2 * math.pi)) < 1e-6
    steps = np.hypot(*np.diff(poses[:, :2], axis=0).T)
    assert steps.max() <= search.cfg.sample_step + 1e-6
    assert _shapely_gap(g, poses[1:]) >= search.cfg.gap - 1e-6


@pytest.mark.parametrize("case_id", EASY_CASES)
def test_guide_batches_give_the_one_by_one_result_and_the_bound_prunes(case_id):
    """Checking candidates 16 at a time returns the sequential search's guide, from the
    start and from poses along it; a bound at or below every lower bound looks at none."""
    from planners.mirror.guide import GuideSearch

    env = gym.make("MirrorPark-v0").unwrapped
    _, info = env.reset(options={"scenario": case_id})
    g = info["geometry"]
    search = GuideSearch(g)
    s = g.start
    start = np.array([s.x, s.y, s.theta])
    poses = [start] + list(search.search(start).path.poses[5::15])

    def gap(q):
        return float(gaps(g.checker, np.asarray(q)[None])[0])

    found = 0
    for q, limit in itertools.product(poses, (2, 24)):  # a binding limit, and the planner's
        one = search.connect(q, search.tails, limit, gap(q), batch=1)
        many = search.connect(q, search.tails, limit, gap(q), batch=16)
        assert (one is None) == (many is None)
        if one is not None:
            found += 1
            # (one pass places several paths on a shared arc-length axis: rounding differs)
            assert many[1] == pytest.approx(one[1], abs=1e-9)
            assert many[0].shape == one[0].shape and np.allclose(many[0], one[0], atol=1e-9)
        assert search.connect(q, search.tails, 24, gap(q), bound=0.0) is None
    assert found > 0


def test_parallel_switch_pose_is_a_forward_arc_from_the_target():
    """Theorem 1's switch pose: heading psi*, l* deeper than the target, one forward arc of
    the guide's radius (length r psi*) before it."""
    from planners.mirror.guide import GuideSearch, switch_poses

    g = Scenario.from_degrees("parallel", 4.5, 7.0, 2.5, 0, 2.0).build()
    search = GuideSearch(g)
    r = search.rs.radius
    psi, _ = parallel_dark_point(P, 2.5)
    v = switch_poses(g, r)[0]
    tx, ty, _ = g.target
    assert v[2] == pytest.approx(psi)
    assert ty - v[1] == pytest.approx(r * (1 - math.cos(psi)))
    assert tx - v[0] == pytest.approx(r * math.sin(psi))
    assert search.rs.distance(v, g.target) == pytest.approx(r * psi, abs=1e-6)


def test_guided_plan_has_one_switch_standing_and_ends_at_rest():
    env = gym.make("MirrorPark-v0").unwrapped
    _, info = env.reset(options={"scenario": "reverse_rw6.00_sl4.82_sw2.37_th+0_y1.20"})
    planner = MirrorPlanner(info["geometry"], preset_config("mirror-guided"))
    plan = planner.plan(info["vehicle_state"])
    assert plan is not None and plan.stats.detail["progress"] == pytest.approx(
        planner.strategy.guide.search(info["vehicle_state"].as_array()[:3]).cost
    )  # the guide's cost: its progress
    v = plan.states[:, 3]
    moving = np.sign(v[np.abs(v) > 1e-3])
    assert np.count_nonzero(np.diff(moving)) <= 1  # one plan, at most one direction switch
    if plan.candidate.switch is not None:
        assert abs(v[plan.candidate.switch]) < 1e-3
    assert abs(v[-1]) < 0.05


@pytest.mark.slow
@pytest.mark.parametrize(
    "case_id",
    [
        "parallel_rw4.00_sl5.02_sw2.50_th+0_y2.10",  # 1.31 car lengths: back and forth inside
        "parallel_rw4.50_sl5.72_sw2.50_th+0_y3.60",  # starts 6.5 cm from the far kerb
        "angle_rw4.00_sl4.82_sw2.42_th+0_y1.30",  # its second plan ends millimetres from a side
    ],
)
def test_hard_cases_park_with_the_guide(case_id):
    env = gym.make("MirrorPark-v0").unwrapped
    policy = MirrorPolicy(preset_config("mirror-guided"))  # the registry's "mirror-guided"
    info, _ = run_episode(env, policy, case_id)
    assert info["is_success"], (info["failed_criterion"], [s.status for s in policy.stats])
    assert policy.setup_time_s > 0  # the slot's tables are built at reset, not in a call


def _guide_from_start(case_id, config=None):
    from planners.mirror.guide import GuideSearch

    env = gym.make("MirrorPark-v0").unwrapped
    _, info = env.reset(options={"scenario": case_id})
    g = info["geometry"]
    search = GuideSearch(g, config)
    s = g.start
    return g, search, search.search((s.x, s.y, s.theta))


def test_short_parallel_slot_needs_the_in_slot_tails():
    """1.31 car lengths: no single arc gets in; only back and forth inside the slot does."""
    case = "parallel_rw4.00_sl5.02_sw2.50_th+0_y2.10"
    from planners.mirror.config import GuideConfig

    assert _guide_from_start(case, GuideConfig(in_slot_turns=False))[2] is None
    g, search, guide = _guide_from_start(case)
    assert guide is not None and guide.path.switches >= 2
    assert _shapely_gap(g, guide.path.poses[1:]) >= search.cfg.gap - 1e-6


def test_a_car_at_the_kerb_may_leave_it_closer_than_the_gap():
    """6.5 cm from the far kerb, turning away swings the rear overhang ~5 cm out: with the
    full 4 cm gap near the start there is no guide; with the relief there is, and it keeps
    1 cm within 1 m of the start and 4 cm beyond."""
    from planners.mirror.config import GuideConfig

    case = "parallel_rw4.50_sl5.72_sw2.50_th+0_y3.60"
    assert _guide_from_start(case, GuideConfig(start_gap=0.04))[2] is None
    g, search, guide = _guide_from_start(case)
    assert guide is not None
    poses = guide.path.poses
    near = np.hypot(poses[:, 0] - poses[0, 0], poses[:, 1] - poses[0, 1]) < START_RELIEF
    assert _shapely_gap(g, poses[1:][near[1:]]) >= search.cfg.start_gap - 1e-6
    assert _shapely_gap(g, poses[~near]) >= search.cfg.gap - 1e-6


def test_a_prepared_search_is_shared_within_a_slot_and_searches_as_a_fresh_one():
    from planners.mirror.guide import prepared_search

    a = Scenario.from_case_id("reverse_rw5.00_sl4.82_sw2.37_th+20_y2.00").build()
    b = Scenario.from_case_id("reverse_rw5.00_sl4.82_sw2.37_th-40_y3.20").build()  # same slot, other start
    c = Scenario.from_case_id("reverse_rw5.50_sl4.82_sw2.37_th-40_y3.20").build()  # another road
    shared = prepared_search(a)
    assert prepared_search(b) is shared and prepared_search(c) is not shared
    fresh = GuideSearch(b)
    fresh.road_tails()
    pose = np.array([b.start.x, b.start.y, b.start.theta])
    got, want = shared.search(pose), fresh.search(pose)
    assert np.array_equal(got.path.poses, want.path.poses) and got.cost == want.cost


def test_a_guide_that_starts_in_the_other_gear_than_the_car_moves_pays_a_switch():
    """A DAgger expert asked at a moving state (``TrackingPolicy.markov``) must stop before it
    can drive the other way: the guide's cost counts that stop as a direction switch."""
    g = Scenario.from_case_id("reverse_rw6.00_sl4.82_sw2.32_th+40_y3.00").build()
    search = GuideSearch(g)
    forward = np.array([[x, 3.0, 0.0] for x in np.arange(0.0, 2.01, 0.1)])  # 2 m straight ahead
    cost = search._cost(forward)
    assert cost == pytest.approx(2.0)
    assert search._cost(forward, gear=1) == cost
    assert search._cost(forward, gear=-1) == pytest.approx(cost + search.cfg.price.switch_cost)
