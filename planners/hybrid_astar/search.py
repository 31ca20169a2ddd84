"""Hybrid A* over (x, y, heading) for the paper's car, with Reeds-Shepp analytic expansion.

The search follows Dolgov et al. (2010) as Apollo's and Autoware's planners implement it:
arcs of fixed length at a few steering angles in both directions; costs for length,
reversing, direction switches and steering; the heuristic is the larger of the Reeds-Shepp
length and an obstacle-aware grid distance, and where the forward search stalls, the cost to
go over (x, y, heading) that knows the car (``heuristic.CostToGoHeuristic``); each expanded
node tries a collision-free Reeds-Shepp connection to the target. A node also ends the
search when its pose lies in the ISO goal set (inside the slot with margins and heading to
spare). This module sets a search up and reads its result; the expansion loop itself is
compiled (``kernel.py``).

Collision checks are exact for the swept footprint: poses are sampled ``sample_step``
apart along every arc, and each sampled pose must clear every obstacle polygon by
``clearance`` plus half the farthest any point of the car travels between samples, which
bounds the sweep in between (no corner can clip an obstacle between samples).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from mirrorpark_env.angles import wrap_angle
from mirrorpark_env.criteria import SuccessCriteria
from mirrorpark_env.scenario import ScenarioGeometry

from ..base import PlanStats
from ..common.clearance import START_SLACK, gap_kernel, gaps
from ..common.cost_to_go_config import PriceConfig
from ..common.path import Path, arc
from ..common.reeds_shepp import ReedsShepp
from . import kernel
from .config import HybridAStarConfig
from .heuristic import CostToGoHeuristic, GridDistance

__all__ = ["HybridAStar", "HybridAStarConfig"]

_SLICE = 500  # expansions between looks at the wall-clock safety net


@dataclass
class _Node:
    pose: tuple[float, float, float]
    g: float
    parent: int
    gear: int  # 0 at the start
    steer: float  # normalised, in [-1, 1]
    samples: np.ndarray | None  # poses from the parent (excluded) to this node (included)
    key: tuple[int, ...]  # the cell that closes it


class HybridAStar:
    """Plans in one scenario geometry; ``plan(start)`` returns a path or a failure status."""

    def __init__(self, geometry: ScenarioGeometry, config: HybridAStarConfig | None = None, keep_trees: bool = False):
        self.geometry = geometry
        self.cfg = cfg = config or HybridAStarConfig()
        car = geometry.vehicle
        self.kappa_max = cfg.steer_fraction * math.tan(car.max_steer_rad) / car.wheelbase
        self.rs = ReedsShepp(1.0 / self.kappa_max)
        self.checker = geometry.checker
        self.criteria = SuccessCriteria(geometry)
        self.goal = tuple(float(v) for v in geometry.target)
        # Farthest any body point moves per metre of rear-axle travel at the largest curvature.
        corners = car.body_corners()
        k = self.kappa_max
        stretch = float(np.max(np.hypot(1 + k * np.abs(corners[:, 1]), k * corners[:, 0])))
        self.sweep_bound = 0.5 * cfg.sample_step * stretch
        self.required_gap = cfg.clearance + self.sweep_bound
        self.th_res = math.radians(cfg.heading_resolution_deg)
        self.n_th = int(round(2 * math.pi / self.th_res))
        self.fine_th_res = math.radians(cfg.fine_heading_resolution_deg)
        self.n_fine_th = int(round(2 * math.pi / self.fine_th_res))
        self.goal_heading = math.radians(cfg.goal_heading_deg)
        self._primitives = self._make_primitives()
        self._keyp = np.array(
            [cfg.fine_gap, cfg.fine_xy_resolution, self.fine_th_res, self.n_fine_th]
            + [cfg.xy_resolution, self.th_res, self.n_th]
        )
        self._gapargs = _gap_args(self.checker)
        _warm_up()
        self._grids: dict[tuple, GridDistance] = {}
        price = PriceConfig(reverse_cost=cfg.reverse_cost - 1.0, steer_cost=cfg.steer_cost, switch_cost=cfg.switch_cost)
        self.lattice = cfg.lattice.model_copy(update={"price": price})
        self.car_heuristic: CostToGoHeuristic | None = None  # built by the first call that needs it
        # With ``keep_trees``, (backward, nodes) of the last call's searches, for figures.
        self.keep_trees = keep_trees
        self.last_trees: list[tuple[bool, list[_Node]]] = []
        # The slot's centre has the largest margins a pose in it can have: if the ISO check
        # fails there, no pose in the slot passes (a slot narrower than the car plus margins).
        self.goal_exists = self.criteria.verdict(*self.goal, 0.0, 0.0, False).failed is None
        self.goal_poses = self._goal_poses() if self.goal_exists else [self.goal]

    # -- primitives and checks ----------------------------------------------------------
    def _make_primitives(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Body-frame sample offsets (P, m, 3) of every primitive, their gears and steers."""
        cfg = self.cfg
        m = max(1, int(round(cfg.step / cfg.sample_step)))
        self.sample_spacing = cfg.step / m
        self.min_samples = max(1, int(math.ceil(cfg.min_step / self.sample_spacing - 1e-9)))
        s = cfg.step * np.arange(1, m + 1) / m
        steers = np.linspace(-1.0, 1.0, cfg.n_steer) if cfg.n_steer > 1 else np.zeros(1)
        offsets, gears, steer_of = [], [], []
        for gear in (1, -1):
            for u in steers:
                k = u * self.kappa_max
                offsets.append(arc((0.0, 0.0, 0.0), k if abs(k) >= 1e-9 else 0.0, gear * s))
                gears.append(gear)
                steer_of.append(u)
        return np.array(offsets), np.array(gears), np.array(steer_of)

    def _gaps(self, poses: np.ndarray) -> np.ndarray:
        return gaps(self.checker, poses)

    def in_goal_set(self, pose) -> bool:
        """ISO success at ``pose`` (standing still), with ``goal_margin`` and heading to spare."""
        x, y, th = (float(v) for v in pose)
        if abs(wrap_angle(th - self.criteria.target_heading)) > self.goal_heading:
            return False  # the verdict's own heading error, without its margins
        v = self.criteria.verdict(x, y, th, 0.0, 0.0, False)
        if not v.inside_slot:
            return False
        need = self.criteria.min_margin + self.cfg.goal_margin
        return min(v.margins.values()) >= need

    def _goal_poses(self) -> list[tuple[float, float, float]]:
        """The target, then up to ``goal_shots`` poses of the goal set along the slot's axis:
        halfway to the farthest each way that passes ``in_goal_set`` (1 cm steps up to
        1.5 m), then those farthest."""
        x, y, th = self.goal
        c, s = math.cos(th), math.sin(th)
        ends = []
        for sign in (1.0, -1.0):
            last = 0.0
            for k in range(1, 151):
                if not self.in_goal_set((x + sign * 0.01 * k * c, y + sign * 0.01 * k * s, th)):
                    break
                last = 0.01 * k
            if last >= 0.05:
                ends.append(sign * last)
        offsets = [0.5 * e for e in ends] + ends
        return [self.goal] + [(x + d * c, y + d * s, th) for d in offsets[: self.cfg.goal_shots]]

    def _shot(self, pose) -> np.ndarray | None:
        """A clear Reeds-Shepp path from ``pose`` into the goal set (``kernel.shot``), with the
        call's window and required gaps (``plan`` sets them)."""
        ok, tail = kernel.shot(*(float(v) for v in pose[:3]), *self._shot_args())
        return tail if ok else None

    def _shot_args(self) -> tuple:
        cfg = self.cfg
        shotp = np.array([self.rs.radius, cfg.sample_step, cfg.clearance, cfg.goal_shot_range])
        return np.array(self.goal_poses, float), shotp, self._gapargs, self._req(), np.array(self.window, float)

    def _req(self) -> np.ndarray:
        """``kernel._required``'s (need, need near the start, start x, y, relief radius)."""
        cfg = self.cfg
        floor = cfg.start_gap_share * self._start_gap if cfg.start_gap_share < 1 else math.inf
        near = min(self.required_gap, floor, max(self._start_gap, 0.0) - START_SLACK)
        return np.array([self.required_gap, near, self._start[0], self._start[1], cfg.start_relief])

    # -- search ---------------------------------------------------------------------
    def _window(self, start) -> tuple[float, float, float, float]:
        """The slot (or target) and the start, ``window_margin`` around, inside the scene's
        bounds."""
        g, m = self.geometry, self.cfg.window_margin
        pts = np.vstack([g.slot if g.slot is not None else np.asarray(g.target[:2])[None], np.asarray(start[:2])[None]])
        lo, hi = pts.min(axis=0) - m, pts.max(axis=0) + m
        sb = g.bounds
        return (max(sb[0], lo[0]), min(sb[1], hi[0]), max(sb[2], lo[1]), min(sb[3], hi[1]))

    def _grid(self, goal) -> GridDistance:
        key = (self.window, goal)
        if key not in self._grids:
            if len(self._grids) >= 8:
                self._grids.clear()
            self._grids[key] = GridDistance(self.geometry.obstacles, self.window, goal[:2], self.cfg.grid_resolution)
        return self._grids[key]

    def plan(self, start) -> tuple[Path | None, PlanStats]:
        """Search from ``start`` (x, y, theta); the path (None on failure) and the call's stats.

        Two searches share the budget: first backward, out of the slot from the target
        until a Reeds-Shepp curve meets the start (in a tight slot the few ways out are
        found at once, where a forward search floods the road); then, if that fails,
        forward from the start into the ISO goal set, on the grid distance for
        ``plain_expansions`` and then on the cost to go. Paths are reversible, so the
        backward one is driven in reverse order with the gear costs swapped.
        Status: "ok", "start_in_collision", "no_goal" (no pose in the slot passes the ISO
        check), "no_path" (the reachable space is exhausted), "budget" (``max_expansions``
        spent: the same on any machine) or "wall_clock" (the safety net fired; the call's
        ``detail["safety_net"]`` is True).
        """
        t0 = time.perf_counter()
        cfg = self.cfg
        start = tuple(float(v) for v in start)
        self.window = self._window(start)
        counts = {"expansions": 0, "nodes": 0}
        self.last_trees = []

        def done(path: Path | None, status: str, cost: float = math.nan, direction: str = ""):
            detail = {
                "switches": path.switches if path is not None else -1,
                "length": path.length if path is not None else math.nan,
                "search": direction,
                "safety_net": status == "wall_clock",
            }
            return path, PlanStats(
                time.perf_counter() - t0,
                status,
                iterations=counts["expansions"],
                nodes=counts["nodes"],
                cost=cost,
                detail=detail,
            )

        self._start = start
        self._start_gap = float(self._gaps(np.array([start]))[0])
        if self._start_gap < -1e-9:
            return done(None, "start_in_collision")
        if not self.goal_exists:
            return done(None, "no_goal")
        deadline = t0 + cfg.wall_clock_limit_s
        share = max(1, int(cfg.backward_share * cfg.max_expansions))
        if cfg.first == "backward":
            order, limits = (True, False), (share, cfg.max_expansions)
        else:
            order, limits = (False, True), (cfg.max_expansions - share, cfg.max_expansions)
        for backward, limit in zip(order, limits):
            origin, goal = (self.goal, start) if backward else (start, self.goal)
            poses, status, cost = self._search(origin, goal, backward, limit, deadline, counts)
            if poses is not None:
                path = Path.from_poses(poses[::-1] if backward else poses)
                return done(path, "ok", cost, "backward" if backward else "forward")
            if status == "wall_clock":
                break
        return done(None, status)

    def _search(self, origin, goal, backward: bool, limit: int, deadline: float, counts: dict[str, int]):
        """One A* search from ``origin`` (``kernel.run``), until the call's expansions reach
        ``limit``; (poses or None, status, cost).

        Forward, a node in the ISO goal set also ends it; backward, the gear costs are
        swapped, since the path will be driven the other way. Forward, after
        ``plain_expansions`` the cost to go takes over (built then, if not yet).
        """
        cfg = self.cfg
        sharpen_at = counts["expansions"] + cfg.plain_expansions
        if backward or cfg.heuristic != "cost_to_go":
            sharpen_at = -1
        forward_cost, reverse_cost = (cfg.reverse_cost, 1.0) if backward else (1.0, cfg.reverse_cost)
        offsets, gears, steers = self._primitives
        cap = 1 + (limit - counts["expansions"]) * len(gears)  # each expansion adds one node a primitive at most
        fl, it = np.empty((cap, 5)), np.empty((cap, 5), np.int64)
        hf, ht, hn = np.empty(cap), np.empty(cap, np.int64), np.empty(cap, np.int64)
        ctr = np.array([1, 0, counts["expansions"], 0], np.int64)
        best_g, closed = kernel.new_maps()
        gap = float(self._gaps(np.array([origin]))[0])
        key = kernel.cell_key(*origin, gap, self._keyp)
        fl[0], it[0] = (*origin, 0.0, 0.0), (-1, 0, -1, 0, key)
        best_g[key] = 0.0
        heur = self._heur_args(goal, None)
        kernel.push(hf, ht, hn, ctr, kernel.estimate(*origin, 0, *heur), 0, 0)
        costs = np.array([forward_cost, reverse_cost, cfg.steer_cost, cfg.steer_change_cost, cfg.switch_cost])
        costs = np.append(costs, [self.sample_spacing, self.min_samples])
        goals, shotp, gapargs, req, window = self._shot_args()
        if backward:  # shots to the start alone
            goals = np.array([goal[:3]], float)
        goalp, body, edges, spec = self._goal_args()
        status = "no_path"
        while True:
            stops = np.array([limit, ctr[kernel.N_EXP] + _SLICE, sharpen_at, cfg.analytic_every], np.int64)
            code, i, tail = kernel.run(
                fl, it, hf, ht, hn, ctr, best_g, closed, stops, backward, self._primitives, costs, self._keyp,
                gapargs, req, window, *heur, goalp, body, edges, spec, goals, shotp,
            )  # fmt: skip
            counts["expansions"] = int(ctr[kernel.N_EXP])
            if code == kernel.SLICE and time.perf_counter() <= deadline:
                continue
            if code == kernel.SHARPEN:
                self.car_heuristic = CostToGoHeuristic(self.geometry, self.lattice, origin, cfg.lattice_stop)
                heur = self._heur_args(goal, self.car_heuristic)
                kernel.rerank(hf, ht, hn, ctr, fl, it, *heur)
                sharpen_at = -1
                continue
            break
        n = int(ctr[kernel.N_NODES])
        counts["nodes"] += n
        self._keep_tree(backward, fl[:n], it[:n])
        if code in (kernel.FOUND, kernel.SHOT):
            return self._trace(fl, it, i, tail if code == kernel.SHOT else None), "ok", float(fl[i, kernel.G])
        status = {kernel.BUDGET: "budget", kernel.NO_PATH: "no_path", kernel.SLICE: "wall_clock"}[code]
        return None, status, math.nan

    def _heur_args(self, goal, car: CostToGoHeuristic | None) -> tuple:
        """``kernel.estimate``'s (heur, grid, table, carp): the weight x the larger of the
        Reeds-Shepp length to ``goal`` and ``car``'s cost to go (where it knows a way) or else
        the 2D grid distance."""
        grid = self._grid(goal)
        w = self.cfg.heuristic_weight
        heur = np.array([*goal[:3], self.rs.radius, w, car is not None, grid.x0, grid.y0, grid.res])
        if car is None:
            return heur, grid.dist, np.zeros((1, 2)), np.zeros(11)
        carp = (car.res, car.dth, car.nh, car.ny, car.nx, car.tx, car.ty, car.tth, car.i0, car.j0, car.bound)
        return heur, grid.dist, car.table, np.array(carp, float)

    def _goal_args(self) -> tuple:
        """``kernel.in_goal_set``'s (goalp, body, edges, spec), from the success criteria."""
        cr = self.criteria
        need = cr.min_margin + self.cfg.goal_margin
        tx, ty = self.goal[:2]
        goalp = np.array([cr.target_heading, self.goal_heading, cr.no_slot, need, getattr(cr, "_pos_tol", 0.0), tx, ty])
        if cr.no_slot:
            return goalp, np.zeros((4, 2)), np.zeros((1, 3)), np.zeros((1, 2), np.int64)
        spec = np.array([(-1 if c is None else c, e) for c, e in cr._spec], np.int64)
        return goalp, np.array(cr._body, float), np.array(cr._edges, float), spec

    def _keep_tree(self, backward: bool, fl: np.ndarray, it: np.ndarray) -> None:
        """With ``keep_trees``, the search's nodes as ``_Node``s, for figures."""
        if not self.keep_trees:
            return
        nodes = [_Node(tuple(fl[0, :3]), 0.0, -1, 0, 0.0, None, ())]
        nodes += [
            _Node(tuple(fl[i, :3]), float(fl[i, kernel.G]), int(it[i, kernel.PARENT]), int(it[i, kernel.GEAR]),
                  float(fl[i, kernel.STEER]), self._samples(fl, it, i), (int(it[i, kernel.KEY]),))
            for i in range(1, len(fl))
        ]  # fmt: skip
        self.last_trees.append((backward, nodes))

    def _samples(self, fl: np.ndarray, it: np.ndarray, i: int) -> np.ndarray:
        """Node ``i``'s poses from its parent (excluded) to it (included), as the kernel made them."""
        x, y, th = fl[it[i, kernel.PARENT], :3]
        c, s = math.cos(th), math.sin(th)
        o = self._primitives[0][it[i, kernel.PRIM], : it[i, kernel.KEPT]]
        return np.stack((x + c * o[:, 0] - s * o[:, 1], y + s * o[:, 0] + c * o[:, 1], th + o[:, 2]), axis=-1)

    def _trace(self, fl: np.ndarray, it: np.ndarray, i: int, tail: np.ndarray | None) -> np.ndarray:
        parts = [] if tail is None else [tail[1:]]
        while i > 0:
            parts.append(self._samples(fl, it, i))
            i = int(it[i, kernel.PARENT])
        parts.append(fl[:1, :3])
        return np.concatenate(parts[::-1])


def _gap_args(checker) -> tuple:
    """``kernels._gaps``'s obstacle arguments, with arrays of the right rank for no obstacles."""
    args = gap_kernel(checker).args
    if len(checker.obstacles) == 0:
        return (*args[:3], np.zeros((0, 1, 2)), np.zeros((0, 1)), np.zeros((0, 1)), np.zeros((0, 1, 2)))
    return args


_WARM = [False]


def _warm_up() -> None:
    """Load the compiled kernels once per process (about 0.8 s from numba's cache, measured),
    so that no plan call pays for it: a short search on a small scene that takes every
    compiled path (the cost to go from the first forward expansion). Counted where the
    planner is built: ``setup_ms`` of a process's first episode."""
    if _WARM[0]:
        return
    _WARM[0] = True
    from mirrorpark_env import Scenario

    g = Scenario.from_degrees("parallel", 5.0, 6.0, 2.5, 0.0, 1.5).build()
    cfg = HybridAStarConfig(first="forward", plain_expansions=0, max_expansions=40, goal_shots=1)
    HybridAStar(g, cfg).plan((g.start.x, g.start.y, g.start.theta))
