"""Hybrid A*'s heuristic that knows the car: the cost to go it shares with the mirror planner,
its inflation over paths the search finds, where it is finite, the turn-around it finds,
and its cache."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mirrorpark_env import Scenario
from mirrorpark_env.config import ParkingType
from mirrorpark_env.layout import Layout, Slot
from planners.common.cost_to_go import CostToGo
from planners.common.path import Path
from planners.hybrid_astar import heuristic
from planners.hybrid_astar.heuristic import CostToGoHeuristic
from planners.hybrid_astar.search import HybridAStar, HybridAStarConfig

OLD = HybridAStarConfig(heuristic="grid", goal_shots=0)  # the search before the cost to go
# V <= (1 + INFLATION) x the price of the rest of a path the search finds, + EXCESS near the
# slot, where the lattice's 0.3 m cells reach the mouth only roughly (docs/hybrid_astar.md)
INFLATION, EXCESS = 0.25, 10.0


def turn_around(aisle: float = 5.0, start=(-6.0, 0.0), box_start: bool = False) -> Layout:
    """An angled bay (60 deg) below a 5 m aisle between its parked neighbours and a wall, to be
    entered in reverse (nose out) by a car that faces the way for nose in: it must turn
    around first. ``box_start``: walls shut the start in."""
    w, depth = 2.6, 5.0
    a = math.radians(-60.0)
    d = np.array([math.cos(a), math.sin(a)])  # into the bay
    n = np.array([-d[1], d[0]])  # along the row

    def rect(e, width, length):
        c0, c1 = e - n * width / 2, e + n * width / 2
        return np.array([c0, c1, c1 + d * length, c0 + d * length])

    e = np.array([0.0, -abs(n[1]) * w / 2])  # the entrance's middle; its upper corner on y = 0
    obstacles = [rect(e + n * k * w + d * 0.3, w - 0.5, depth - 0.6) for k in (-3, -2, -1, 1, 2, 3)]
    obstacles += [
        np.array([[-20, aisle], [20, aisle], [20, aisle + 0.5], [-20, aisle + 0.5]]),
        np.array([[-20, -depth - 1.5], [20, -depth - 1.5], [20, -depth - 1.0], [-20, -depth - 1.0]]),
    ]
    sx, sy = start[0], start[1] if start[1] else aisle / 2
    if box_start:  # a pen of 6 m x 2.6 m around the start
        obstacles += [
            np.array([[sx - 3.5, sy - 1.8], [sx + 4.5, sy - 1.8], [sx + 4.5, sy - 1.3], [sx - 3.5, sy - 1.3]]),
            np.array([[sx - 3.5, sy + 1.3], [sx + 4.5, sy + 1.3], [sx + 4.5, sy + 1.8], [sx - 3.5, sy + 1.8]]),
            np.array([[sx - 3.5, sy - 1.3], [sx - 3.0, sy - 1.3], [sx - 3.0, sy + 1.3], [sx - 3.5, sy + 1.3]]),
            np.array([[sx + 4.0, sy - 1.3], [sx + 4.5, sy - 1.3], [sx + 4.5, sy + 1.3], [sx + 4.0, sy + 1.3]]),
        ]
    p = e + d * (depth - 0.91)  # the rear axle of a car nose out, its rear 0.2 m from the bay's end
    return Layout(
        obstacles=tuple(obstacles),
        start=(sx, sy, 0.0),
        target=(float(p[0]), float(p[1]), math.atan2(-d[1], -d[0])),
        slot=Slot(rect(e, w, depth), ParkingType.ANGLE, entrance=0),
        name="turn-around",
        road_width=aisle,
        bounds=(-14.0, 14.0, -depth - 0.8, aisle - 0.3),
    )


def priced(cfg: HybridAStarConfig, path: Path) -> float:
    """A path's length priced as the search prices it (forward 1, reversed ``reverse_cost``,
    ``switch_cost`` a switch), steering left out: a lower bound on the search's own cost."""
    ds = np.hypot(*np.diff(path.poses[:, :2], axis=0).T)
    rev = np.asarray(path.direction[1:]) < 0
    return float(ds[~rev].sum() + cfg.reverse_cost * ds[rev].sum() + cfg.switch_cost * path.switches)


def test_a_start_facing_away_from_an_angled_bay_is_solved_where_the_old_heuristic_was_not():
    """The car must turn ~120 deg in a 5 m aisle first: the Reeds-Shepp length and the 2D
    distance do not see it, and the old search spends its 9,000 expansions; the cost to go
    does, and the search parks in a few hundred."""
    g = turn_around().build()
    start = turn_around().start
    _, old = HybridAStar(g, OLD).plan(start)
    assert old.status == "budget" and old.iterations == OLD.max_expansions
    alone = {"goal_shots": 0, "plain_expansions": 0}  # the heuristic alone changed
    path, new = HybridAStar(g, HybridAStarConfig(**alone)).plan(start)
    share = int(OLD.backward_share * OLD.max_expansions)  # the backward search's, spent first
    assert new.status == "ok" and new.detail["search"] == "forward" and new.iterations <= share + 1_000
    _, fwd = HybridAStar(g, HybridAStarConfig(first="forward", **alone)).plan(start)
    assert fwd.status == "ok" and fwd.iterations <= 1_000
    assert HybridAStar(g).plan(start)[1].status == "ok"  # and the default
    assert HybridAStar(g, HybridAStarConfig(goal_shots=2)).plan(start)[1].status == "ok"
    assert HybridAStar(g).in_goal_set(path.poses[-1])


def _case(case_id: str):
    g = Scenario.from_case_id(case_id).build()
    return g, (g.start.x, g.start.y, g.start.theta)


SCENES = {
    "turn-around": lambda: (turn_around().build(), turn_around().start),
    "reverse": lambda: _case("reverse_rw5.00_sl4.82_sw2.47_th+0_y2.00"),
    "parallel": lambda: _case("parallel_rw4.00_sl5.52_sw2.50_th+0_y1.60"),
    "angle": lambda: _case("angle_rw4.50_sl4.82_sw2.32_th+10_y2.60"),
}


@pytest.mark.parametrize("name", list(SCENES))
def test_the_estimate_exceeds_a_found_paths_price_by_at_most_its_inflation(name):
    """V is a lattice's shortest path (full lock or straight, 5 deg cells), so it may exceed
    the price of a finer path: at the start by at most ``INFLATION``, along the path the
    search (weight 1) finds by at most ``EXCESS`` more."""
    g, start = SCENES[name]()
    cfg = HybridAStarConfig(heuristic_weight=1.0)
    search = HybridAStar(g, cfg)
    path, stats = search.plan(start)
    assert stats.status == "ok"
    h = CostToGoHeuristic(g, search.lattice, start, cfg.lattice_stop)
    poses = path.poses
    est, price = h(*start, 0), priced(cfg, path)
    assert est <= (1 + INFLATION) * price, (est, price)
    for k in range(0, len(poses) - 1, 10):
        est, price = h(*poses[k], 0), priced(cfg, Path.from_poses(poses[k:]))
        assert est <= (1 + INFLATION) * price + EXCESS, (k, est, price)


def test_the_estimate_is_finite_exactly_where_the_goal_is_reachable():
    """From a start in the aisle V is finite; from a start walled in, where no path leaves the
    pen, V is infinite (and the search says so without spending its budget)."""
    free = turn_around()
    V = CostToGo(free.build(), HybridAStar(free.build()).lattice)
    assert math.isfinite(V.at(free.start)[0])
    shut = turn_around(box_start=True)
    g = shut.build()
    V = CostToGo(g, HybridAStar(g).lattice)
    assert V.at(shut.start)[0] == math.inf
    path, stats = HybridAStar(g).plan(shut.start)
    assert path is None and stats.status in ("no_path", "budget")


def test_the_cost_to_go_is_built_once_and_rebuilt_only_for_a_start_beyond_its_bound():
    """A second call from the same start, or from a start nearer the target, reuses the
    slot's cost to go; a start beyond the bound it was built to builds it again."""
    lay = turn_around(aisle=5.1)  # a slot no other test builds
    g = lay.build()
    search = HybridAStar(g)
    before = heuristic._CACHE.builds
    _, stats = search.plan(lay.start)
    assert stats.detail["search"] == "forward"  # the backward search alone builds nothing
    assert heuristic._CACHE.builds == before + 1
    bound = search.car_heuristic.bound
    assert math.isfinite(bound)
    search.plan(lay.start)
    nearer = (2.0, 2.5, math.radians(150))
    assert search.car_heuristic(*nearer, 0) <= bound
    CostToGoHeuristic(g, search.lattice, nearer, search.cfg.lattice_stop)  # another episode's start
    assert heuristic._CACHE.builds == before + 1
    far = (-12.0, 2.5, 0.0)
    assert search.car_heuristic(*far, 0) == bound  # beyond it: V is known to be at least the bound
    CostToGoHeuristic(g, search.lattice, far, search.cfg.lattice_stop)
    assert heuristic._CACHE.builds == before + 2


def test_a_cost_to_go_built_for_another_start_reads_as_one_built_for_this_start():
    """The search must not depend on the calls a process made before: a start that reuses a
    V built for a farther start reads, at every pose, what a V built for itself gives
    (values up to its own bound, the bound beyond), and a fresh V's bound is the one
    ``own_bound`` computes."""
    lay = turn_around(aisle=5.2)  # a slot no other test builds
    g = lay.build()
    cfg, rule = HybridAStar(g).lattice, HybridAStarConfig().lattice_stop
    far, near = (-6.0, 0.0, 0.0), (1.5, 2.0, math.radians(160))
    box = heuristic.scene_box(g, cfg)
    fresh_far = CostToGo(g, cfg, stop_near=far, stop_rule=rule, box=box)
    fresh_near = CostToGo(g, cfg, stop_near=near, stop_rule=rule, box=box)
    for V, start in ((fresh_far, far), (fresh_near, near)):
        assert heuristic.own_bound(V, start, rule) == V.bound
    assert fresh_near.bound < fresh_far.bound
    heuristic._CACHE._items.clear()
    built_far = CostToGoHeuristic(g, cfg, far, rule)
    reused = CostToGoHeuristic(g, cfg, near, rule)
    assert reused.V is built_far.V and reused.bound == fresh_near.bound
    heuristic._CACHE._items.clear()
    own = CostToGoHeuristic(g, cfg, near, rule)
    assert own.V is not built_far.V
    rng = np.random.default_rng(5)
    x0, x1, y0, y1 = box
    poses = np.column_stack([rng.uniform(x0, x1, 4000), rng.uniform(y0, y1, 4000), rng.uniform(-4, 4, 4000)])
    values = [(reused(*p, gear), own(*p, gear)) for p in poses for gear in (-1, 0, 1)]
    assert all(a == b for a, b in values)
    assert sum(a < reused.bound for a, _ in values) > 1000  # most poses read exact values


@pytest.mark.parametrize(
    "case_id",
    [
        "parallel_rw4.00_sl5.62_sw2.50_th+0_y1.90",
        "reverse_rw6.00_sl4.82_sw2.52_th-20_y4.90",
        "angle_rw4.00_sl4.82_sw2.57_th+0_y2.30",
    ],
)
def test_shots_go_to_poses_of_the_goal_set_along_the_slot(case_id):
    """The analytic shots' goals: the target first, then poses shifted along its heading, each
    in the goal set (ISO-valid with the search's margin); a shot from a pose in the aisle ends
    on one of them."""
    g = Scenario.from_case_id(case_id).build()
    search = HybridAStar(g, HybridAStarConfig(goal_shots=2))
    goals = np.array(search.goal_poses)
    assert len(goals) == 1 + search.cfg.goal_shots
    assert tuple(goals[0]) == search.goal
    x, y, th = search.goal
    for gx, gy, gth in goals[1:]:
        assert gth == th and abs(-(gx - x) * math.sin(th) + (gy - y) * math.cos(th)) < 1e-9  # on the axis
        assert search.in_goal_set((gx, gy, gth)) and math.hypot(gx - x, gy - y) >= 0.025
    search._start, search._start_gap = (g.start.x, g.start.y, g.start.theta), 1.0
    search.window = search._window(search._start)
    tail = search._shot(search._start)
    if tail is not None:
        assert any(np.allclose(tail[-1], goal) for goal in goals)


def test_the_lattice_covers_a_lot_turned_anywhere_in_the_world():
    """A generated lot lies turned and shifted in the world: the mirror planner's box (the road
    beside a grid slot, along x from y = 0) misses its target there, and V would be infinite
    everywhere; the heuristic's own box (around the slot and the start) holds both."""
    from mirrorpark_env.lots import generate_lot
    from mirrorpark_env.vehicle import vehicle_named
    from planners.common.cost_to_go import lattice_box

    lay = generate_lot(1049, 2, vehicle_named("tpcap"))
    g = lay.build()
    cfg = HybridAStar(g).lattice
    x0, x1, y0, y1 = lattice_box(g, cfg)
    assert not (x0 <= g.target[0] <= x1 and y0 <= g.target[1] <= y1)
    h = CostToGoHeuristic(g, cfg, lay.start, HybridAStarConfig().lattice_stop)
    assert math.isfinite(h(*lay.start, 0)) and h(*lay.start, 0) < h.bound
