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
from .one_search import OneSearch

__all__ = ["HybridAStar", "HybridAStarConfig"]


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

        Two searches share the budget, taking turns of ``interleave`` expansions (``_turns``):
        backward, out of the slot from the target until a Reeds-Shepp curve meets the start
        (in a tight slot the few ways out are found at once, where a forward search floods
        the road), and forward from the start into the ISO goal set, on the grid distance
        for ``plain_expansions`` and then on the cost to go. Paths are reversible, so the
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
        made, last = self._turns(start, t0 + cfg.wall_clock_limit_s, counts)
        for s in made:
            counts["nodes"] += s.nodes
            if self.keep_trees:
                self.last_trees.append((s.backward, self._tree(s)))
        if last.status == "ok":
            path = Path.from_poses(last.poses[::-1] if last.backward else last.poses)
            return done(path, "ok", last.cost, "backward" if last.backward else "forward")
        return done(None, last.status)

    def _turns(self, start, deadline: float, counts: dict[str, int]) -> tuple[list[OneSearch], OneSearch]:
        """Run the two searches in turns of ``interleave`` expansions (0: the first to its end,
        then the second), the first at most its share of the budget, until one ends the call
        (``_ends_call``) or both have ended; (the searches built, in their order; the one that
        ended last)."""
        cfg = self.cfg
        total = cfg.max_expansions
        share = max(1, int(cfg.backward_share * total))
        back_first = cfg.first == "backward"
        first_cap = share if back_first else total - share
        made: list[OneSearch] = []  # each built when it first runs

        def search(k: int) -> OneSearch:
            if len(made) <= k:
                backward = back_first == (k == 0)
                origin, goal = (self.goal, start) if backward else (start, self.goal)
                made.append(OneSearch(self, origin, goal, backward, first_cap if k == 0 else total))
            return made[k]

        def expansions(k: int) -> int:
            return made[k].expansions if len(made) > k else 0

        step = cfg.interleave or total
        last = None
        while last is None or not _ends_call(last):
            live = [k for k in (0, 1) if len(made) <= k or made[k].status is None]
            if not live:
                break
            for k in live:
                s = search(k)
                cap = min(first_cap, total - expansions(1)) if k == 0 else total - expansions(0)
                target = min(cap, s.expansions + step)
                s.advance(target, deadline, final=target >= cap)
                counts["expansions"] = expansions(0) + expansions(1)
                if s.status is not None:
                    last = s
                    if _ends_call(s):
                        break
        return made, last

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
        body, edges, spec, pos_tol = cr.as_arrays()
        need = cr.min_margin + self.cfg.goal_margin
        tx, ty = self.goal[:2]
        goalp = np.array([cr.target_heading, self.goal_heading, cr.no_slot, need, pos_tol, tx, ty])
        return goalp, body, edges, spec

    @staticmethod
    def _tree(search: OneSearch) -> list[_Node]:
        """A search's nodes as ``_Node``s, for figures (``keep_trees``)."""
        fl, it = search.fl, search.it
        nodes = [_Node(tuple(fl[0, :3]), 0.0, -1, 0, 0.0, None, ())]
        nodes += [
            _Node(tuple(fl[i, :3]), float(fl[i, kernel.G]), int(it[i, kernel.PARENT]), int(it[i, kernel.GEAR]),
                  float(fl[i, kernel.STEER]), search.samples(i), (int(it[i, kernel.KEY]),))
            for i in range(1, search.nodes)
        ]  # fmt: skip
        return nodes


def _ends_call(search: OneSearch) -> bool:
    """Whether a search's end ends the call: a path, the safety net, or a forward search out
    of states (the start is boxed in: the other search cannot get there either)."""
    return search.status in ("ok", "wall_clock") or (search.status == "no_path" and not search.backward)


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
