"""Hybrid A* over (x, y, heading) for the paper's car, with Reeds-Shepp analytic expansion.

The search follows Dolgov et al. (2010) as Apollo's and Autoware's planners implement it:
arcs of fixed length at a few steering angles in both directions; costs for length,
reversing, direction switches and steering; the heuristic is the larger of the Reeds-Shepp
length and an obstacle-aware grid distance, and where the forward search stalls, the cost to
go over (x, y, heading) that knows the car (``heuristic.CostToGoHeuristic``); each expanded
node tries a collision-free Reeds-Shepp connection to the target. A node also ends the search when its pose lies in
the ISO goal set (inside the slot with margins and heading to spare).

Collision checks are exact for the swept footprint: poses are sampled ``sample_step``
apart along every arc, and each sampled pose must clear every obstacle polygon by
``clearance`` plus half the farthest any point of the car travels between samples, which
bounds the sweep in between (no corner can clip an obstacle between samples).
"""

from __future__ import annotations

import heapq
import math
import time
from dataclasses import dataclass

import numpy as np

from mirrorpark_env.angles import wrap_angle
from mirrorpark_env.criteria import SuccessCriteria
from mirrorpark_env.scenario import ScenarioGeometry

from ..base import PlanStats
from ..common.clearance import gaps, required_gap
from ..common.cost_to_go_config import PriceConfig
from ..common.path import Path, arc
from ..common.reeds_shepp import ReedsShepp
from .config import HybridAStarConfig
from .heuristic import CostToGoHeuristic, GridDistance

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

    def _in_window(self, poses: np.ndarray) -> np.ndarray:
        x0, x1, y0, y1 = self.window
        return (poses[:, 0] >= x0) & (poses[:, 0] <= x1) & (poses[:, 1] >= y0) & (poses[:, 1] <= y1)

    def path_is_clear(self, poses: np.ndarray) -> bool:
        """Whether poses at most ``sample_step`` apart certify a sweep clear by ``clearance``."""
        return bool((self._gaps(poses) >= self._required(poses)).all())

    def _required(self, poses: np.ndarray) -> np.ndarray | float:
        """Gap each sampled pose must keep: ``required_gap``, but within ``start_relief`` of a
        start that is closer only ``start_gap_share`` of the start's gap (``common.clearance``;
        grid starts may touch the road's edges, and the car must be able to leave them)."""
        cfg = self.cfg
        floor = cfg.start_gap_share * self._start_gap if cfg.start_gap_share < 1 else math.inf
        return required_gap(poses, self._start, self._start_gap, self.required_gap, cfg.start_relief, floor)

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
        """A clear Reeds-Shepp path from ``pose`` into the goal set: to the target, else (from
        within ``goal_shot_range`` of it) to the other goal poses, nearest first."""
        tail = self._analytic(pose, self.goal)
        if tail is not None or len(self.goal_poses) == 1:
            return tail
        if self.rs.distance(pose, self.goal) > self.cfg.goal_shot_range:
            return None
        for goal in sorted(self.goal_poses[1:], key=lambda g: self.rs.distance(pose, g)):
            tail = self._analytic(pose, goal)
            if tail is not None:
                return tail
        return None

    def _analytic(self, pose, goal) -> np.ndarray | None:
        """A clear Reeds-Shepp path from ``pose`` to ``goal``, or None."""
        rs_path = self.rs.path(pose, goal)  # solved once, sampled at two spacings
        coarse = self.rs.place(pose, goal, rs_path, 4 * self.cfg.sample_step)
        if (self._gaps(coarse) < np.minimum(self._required(coarse), self.cfg.clearance)).any() or not self._in_window(
            coarse
        ).all():
            return None  # a pose that close already rules the path out
        fine = self.rs.place(pose, goal, rs_path, self.cfg.sample_step)
        return fine if self.path_is_clear(fine) else None

    # -- search ---------------------------------------------------------------------
    def _window(self, start) -> tuple[float, float, float, float]:
        """The slot (or target) and the start, ``window_margin`` around, inside the scene's
        bounds."""
        g, m = self.geometry, self.cfg.window_margin
        pts = np.vstack([g.slot if g.slot is not None else np.asarray(g.target[:2])[None], np.asarray(start[:2])[None]])
        lo, hi = pts.min(axis=0) - m, pts.max(axis=0) + m
        sb = g.bounds
        return (max(sb[0], lo[0]), min(sb[1], hi[0]), max(sb[2], lo[1]), min(sb[3], hi[1]))

    def _key(self, pose, gap: float) -> tuple[int, int, int, int]:
        """The cell of ``pose``: coarse, or fine where its gap to the nearest obstacle is
        below ``fine_gap`` (the first entry tells the two apart)."""
        if gap < self.cfg.fine_gap:
            r, th_res, n_th, level = self.cfg.fine_xy_resolution, self.fine_th_res, self.n_fine_th, 1
        else:
            r, th_res, n_th, level = self.cfg.xy_resolution, self.th_res, self.n_th, 0
        return (
            level,
            int(math.floor(pose[0] / r)),
            int(math.floor(pose[1] / r)),
            int(math.floor(pose[2] / th_res + 0.5)) % n_th,
        )

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
        """One A* search from ``origin``, until the call's expansions reach ``limit``; (poses or
        None, status, cost).

        Forward, a node in the ISO goal set also ends it; backward, the gear costs are
        swapped, since the path will be driven the other way.
        """
        cfg = self.cfg
        h = self._heuristic(goal, None)
        # Forward, after ``plain_expansions`` the cost to go takes over (built then, if not yet)
        sharpen = not backward and cfg.heuristic == "cost_to_go"
        sharpen_at = counts["expansions"] + cfg.plain_expansions if sharpen else -1
        forward_cost, reverse_cost = (cfg.reverse_cost, 1.0) if backward else (1.0, cfg.reverse_cost)

        origin_key = self._key(origin, float(self._gaps(np.array([origin]))[0]))
        nodes: list[_Node] = [_Node(origin, 0.0, -1, 0, 0.0, None, origin_key)]
        self._keep_tree(backward, nodes)
        open_heap = [(h(origin), 0, 0)]
        best_g = {origin_key: 0.0}
        closed: set[tuple[int, ...]] = set()
        offsets, gears, steers = self._primitives
        status = "no_path"
        while open_heap:
            if counts["expansions"] >= limit:
                status = "budget"
                break
            if time.perf_counter() > deadline:
                status = "wall_clock"
                break
            if counts["expansions"] == sharpen_at:
                h, open_heap = self._sharpen(origin, goal, nodes, open_heap)
            _, _, i = heapq.heappop(open_heap)
            node = nodes[i]
            key = node.key
            if key in closed:
                continue
            closed.add(key)
            counts["expansions"] += 1
            if not backward and i > 0 and self.in_goal_set(node.pose):
                counts["nodes"] += len(nodes)
                return self._trace(nodes, i, None), "ok", node.g
            if (len(closed) - 1) % cfg.analytic_every == 0:
                tail = self._analytic(node.pose, goal) if backward else self._shot(node.pose)
                if tail is not None:
                    counts["nodes"] += len(nodes)
                    return self._trace(nodes, i, tail), "ok", node.g
            # Expand: every primitive's samples at once, one collision call.
            x, y, th = node.pose
            c, s = math.cos(th), math.sin(th)
            wx = x + c * offsets[..., 0] - s * offsets[..., 1]
            wy = y + s * offsets[..., 0] + c * offsets[..., 1]
            wt = th + offsets[..., 2]
            poses = np.stack((wx, wy, wt), axis=-1)  # (P, m, 3)
            flat = poses.reshape(-1, 3)
            gap = self._gaps(flat)
            ok = (gap >= self._required(flat)) & self._in_window(flat)
            ok = ok.reshape(poses.shape[:2])
            gap = gap.reshape(poses.shape[:2])
            # A primitive that runs into an obstacle is cut short at its last clear sample
            # (when it still covers min_step): the short moves of a tight manoeuvre.
            n_clear = np.where(ok.all(axis=1), ok.shape[1], ok.argmin(axis=1))
            for p in np.flatnonzero(n_clear >= self.min_samples):
                k = int(n_clear[p])
                end = poses[p, k - 1]
                child_key = self._key(end, float(gap[p, k - 1]))
                if child_key in closed:
                    continue
                gear = int(gears[p])
                length = k * self.sample_spacing
                g = node.g + length * (forward_cost if gear > 0 else reverse_cost)
                g += length * cfg.steer_cost * abs(steers[p])
                if node.gear != 0:
                    g += cfg.steer_change_cost * abs(steers[p] - node.steer)
                    if gear != node.gear:
                        g += cfg.switch_cost
                if g >= best_g.get(child_key, math.inf):
                    continue
                pose = (float(end[0]), float(end[1]), float(end[2]))
                hv = h(pose, gear)
                if not math.isfinite(hv):
                    continue
                best_g[child_key] = g
                nodes.append(_Node(pose, g, i, gear, float(steers[p]), poses[p, :k], child_key))
                heapq.heappush(open_heap, (g + hv, len(nodes) - 1, len(nodes) - 1))
        counts["nodes"] += len(nodes)
        return None, status, math.nan

    def _sharpen(self, start, goal, nodes: list[_Node], open_heap: list):
        """The cost to go's h, and the open nodes ranked by it (``CostToGoHeuristic``, built
        here by the call that first needs it: a call that ends before builds nothing)."""
        self.car_heuristic = CostToGoHeuristic(self.geometry, self.lattice, start, self.cfg.lattice_stop)
        h = self._heuristic(goal, self.car_heuristic)
        ranked = []
        for _, tie, i in open_heap:
            hv = h(nodes[i].pose, nodes[i].gear)
            if math.isfinite(hv):
                ranked.append((nodes[i].g + hv, tie, i))
        heapq.heapify(ranked)
        return h, ranked

    def _heuristic(self, goal, car: CostToGoHeuristic | None):
        """h(pose, gear): the weight x the larger of the Reeds-Shepp length to ``goal`` and
        ``car``'s cost to go (where it knows a way) or else the 2D grid distance."""
        grid, w = self._grid(goal), self.cfg.heuristic_weight

        def h(pose, gear: int = 0) -> float:
            est = car(pose[0], pose[1], pose[2], gear) if car is not None else math.inf
            if est == math.inf:
                est = grid(pose[0], pose[1])
            return w * max(self.rs.distance(pose, goal), est)

        return h

    def _keep_tree(self, backward: bool, nodes: list[_Node]) -> None:
        if self.keep_trees:  # the list grows as the search runs: the figure sees all of it
            self.last_trees.append((backward, nodes))

    @staticmethod
    def _trace(nodes: list[_Node], i: int, tail: np.ndarray | None) -> np.ndarray:
        parts = [] if tail is None else [tail[1:]]
        while i > 0:
            parts.append(nodes[i].samples)
            i = nodes[i].parent
        parts.append(np.array([nodes[0].pose]))
        return np.concatenate(parts[::-1])
