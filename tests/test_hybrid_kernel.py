"""Hybrid A*'s compiled loop (``planners/hybrid_astar/kernel.py``) against the Python pieces it
replaces: the heap's order, the estimate, the goal set, the cells; and searches it must keep."""

from __future__ import annotations

import hashlib
import heapq
import math

import numpy as np
import pytest

from mirrorpark_env import Scenario
from mirrorpark_env.layout import Layout
from planners.hybrid_astar import kernel
from planners.hybrid_astar.heuristic import CostToGoHeuristic
from planners.hybrid_astar.search import HybridAStar, HybridAStarConfig


def test_the_heap_pops_in_heapqs_order():
    """(f, insertion number) entries, many with equal f: the same order as ``heapq`` on
    (f, tie, node), across pushes and pops interleaved and a re-ranking heapify."""
    rng = np.random.default_rng(0)
    n = 3000
    hf, ht, hn = np.empty(n), np.empty(n, np.int64), np.empty(n, np.int64)
    ctr = np.zeros(4, np.int64)
    ref, got, want = [], [], []
    for tie in range(n):
        f = float(rng.integers(0, 50)) / 4  # many ties in f
        kernel.push(hf, ht, hn, ctr, f, tie, tie)
        heapq.heappush(ref, (f, tie, tie))
        if rng.random() < 0.4:
            got.append(kernel._pop(hf, ht, hn, ctr))
            want.append(heapq.heappop(ref)[2])
    while ref:
        got.append(kernel._pop(hf, ht, hn, ctr))
        want.append(heapq.heappop(ref)[2])
    assert got == want and ctr[kernel.N_HEAP] == 0


@pytest.mark.parametrize(
    "case_id", ["reverse_rw5.00_sl4.82_sw2.52_th-20_y3.00", "parallel_rw4.00_sl5.62_sw2.50_th+0_y1.90"]
)
def test_the_estimate_is_the_larger_of_reeds_shepp_and_the_cost_to_go_or_grid(case_id):
    """``kernel.estimate`` equals the Python composition it replaces, bit for bit: the weight
    x max(Reeds-Shepp length, the cost to go where it knows a way, else the grid distance)."""
    g = Scenario.from_case_id(case_id).build()
    search = HybridAStar(g)
    start = (g.start.x, g.start.y, g.start.theta)
    search._start, search.window = start, search._window(start)
    car = CostToGoHeuristic(g, search.lattice, start, search.cfg.lattice_stop)
    goal, w = search.goal, search.cfg.heuristic_weight
    grid = search._grid(goal)
    rng = np.random.default_rng(1)
    x0, x1, y0, y1 = search.window
    poses = np.column_stack(
        [rng.uniform(x0 - 2, x1 + 2, 3000), rng.uniform(y0 - 2, y1 + 2, 3000), rng.uniform(-7, 7, 3000)]
    )
    finite = 0
    for with_car in (None, car):
        args = search._heur_args(goal, with_car)
        for (x, y, th), gear in zip(poses, rng.integers(-1, 2, len(poses))):
            est = with_car(x, y, th, int(gear)) if with_car is not None else math.inf
            if est == math.inf:
                est = grid(x, y)
            want = w * max(search.rs.distance((x, y, th), goal), est)
            got = kernel.estimate(x, y, th, int(gear), *args)
            assert got == want or (math.isinf(got) and math.isinf(want))
            finite += math.isfinite(got)
    assert finite > 3000  # the grid's walls and the lattice's gaps leave most poses finite


def _goal_set_agrees(search: HybridAStar, n: int, spread: float, seed: int) -> int:
    rng = np.random.default_rng(seed)
    goalp, body, edges, spec = search._goal_args()
    x, y, th = search.goal
    inside = 0
    for _ in range(n):
        pose = (
            x + rng.normal(0, spread),
            y + rng.normal(0, spread),
            th + rng.normal(0, 0.03) + rng.choice([0, 2 * math.pi]),
        )
        want = search.in_goal_set(pose)
        assert kernel.in_goal_set(*pose, goalp, body, edges, spec) == want
        inside += want
    return inside


@pytest.mark.parametrize(
    "case_id",
    [
        "parallel_rw4.00_sl5.62_sw2.50_th+0_y1.90",
        "reverse_rw5.00_sl4.82_sw2.77_th-20_y3.00",
        "angle_rw4.00_sl4.82_sw2.57_th+0_y2.30",
    ],
)
def test_the_compiled_goal_set_is_the_success_criteria(case_id):
    """``kernel.in_goal_set`` decides as ``HybridAStar.in_goal_set`` (the success criteria with
    the search's margins) on poses scattered about the target, some in the set and most not."""
    search = HybridAStar(Scenario.from_case_id(case_id).build())
    inside = _goal_set_agrees(search, 3000, 0.12, 2)
    assert 100 < inside < 2900


def test_the_compiled_goal_set_without_a_slot_is_the_position_tolerance():
    """A layout with a target and no slot: the goal set is the target's position tolerance
    less ``goal_margin``, with the heading check."""
    box = np.array([[-1.0, 3.0], [1.0, 3.0], [1.0, 4.0], [-1.0, 4.0]])
    g = Layout(obstacles=(box,), start=(-6.0, 0.0, 0.0), target=(2.0, 0.0, 0.0), bounds=(-12, 12, -6, 6)).build()
    search = HybridAStar(g)
    assert search.criteria.no_slot
    inside = _goal_set_agrees(search, 2000, 0.2, 3)
    assert 50 < inside < 1950


def test_cells_are_keys_of_the_coarse_or_fine_grid():
    """Poses a hair apart share a cell; a cell's step apart does not; the fine grid is
    taken below ``fine_gap``, and the two grids never share a key."""
    search = HybridAStar(Scenario.from_case_id("parallel_rw4.00_sl5.62_sw2.50_th+0_y1.90").build())
    keyp, cfg = search._keyp, search.cfg
    far, near = cfg.fine_gap + 1.0, cfg.fine_gap / 2
    k = kernel.cell_key(1.01, -2.03, 0.3, far, keyp)
    assert k == kernel.cell_key(1.01 + 1e-6, -2.03 + 1e-6, 0.3 + 1e-6, far, keyp)
    assert k != kernel.cell_key(1.01 + cfg.xy_resolution, -2.03, 0.3, far, keyp)
    assert k != kernel.cell_key(1.01, -2.03, 0.3 + math.radians(cfg.heading_resolution_deg), far, keyp)
    assert k == kernel.cell_key(1.01, -2.03, 0.3 + 2 * math.pi, far, keyp)  # headings wrap
    assert k != kernel.cell_key(1.01, -2.03, 0.3, near, keyp)
    rng = np.random.default_rng(4)
    draws = rng.uniform(-30, 30, (2000, 4))
    keys = {kernel.cell_key(x, y, t, gp, keyp) for x, y, t, gp in draws}
    cells = {
        (gp < cfg.fine_gap, math.floor(x / r), math.floor(y / r), math.floor(t / tr + 0.5) % n)
        for x, y, t, gp in draws
        for r, tr, n in [
            (cfg.fine_xy_resolution, search.fine_th_res, search.n_fine_th)
            if gp < cfg.fine_gap
            else (cfg.xy_resolution, search.th_res, search.n_th)
        ]
    }
    assert len(keys) == len(cells)  # one key per cell: no two cells collide


@pytest.mark.parametrize(
    ("case_id", "status", "expansions", "nodes", "digest"),
    [  # recorded from the Python loop this kernel replaced (the rest of the code as now)
        ("parallel_rw4.50_sl3.92_sw2.50_th+0_y0.90", "budget", 9000, 19198, ""),
        ("parallel_rw4.50_sl4.82_sw2.50_th+20_y2.60", "ok", 1887, 4375, "fdf66b0b2b35"),
        ("parallel_rw4.50_sl4.92_sw2.50_th+80_y1.20", "ok", 5932, 12832, "a1a3d2b93257"),  # cost to go, forward
        ("parallel_rw4.50_sl4.52_sw2.50_th+0_y1.30", "ok", 101, 124, "136668fe50ee"),
    ],
)
def test_searches_are_the_python_loops(case_id, status, expansions, nodes, digest):
    """First calls on fixed cases give the Python loop's status, expansions, nodes and path,
    bit for bit (a digest of the poses; of 300 standard cases, every 5th, all 300 agreed)."""
    g = Scenario.from_case_id(case_id).build()
    sequential = HybridAStarConfig(interleave=0)  # the order the Python loop ran its two searches in
    path, stats = HybridAStar(g, sequential).plan((g.start.x, g.start.y, g.start.theta))
    assert (stats.status, stats.iterations, stats.nodes) == (status, expansions, nodes)
    got = hashlib.sha1(np.ascontiguousarray(path.poses).tobytes()).hexdigest()[:12] if path is not None else ""
    assert got == digest
