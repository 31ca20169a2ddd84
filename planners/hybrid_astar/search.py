"""Hybrid A* over (x, y, heading) for the paper's car, with Reeds-Shepp analytic expansion.

The search follows Dolgov et al. (2010) as Apollo's and Autoware's planners implement it:
arcs of fixed length at a few steering angles in both directions; costs for length,
reversing, direction switches and steering; the heuristic is the larger of the Reeds-Shepp
length and an obstacle-aware grid distance; each expanded node tries a collision-free
Reeds-Shepp connection to the target. A node also ends the search when its pose lies in
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

from mirrorpark_env.criteria import SuccessCriteria
from mirrorpark_env.scenario import ScenarioGeometry

from ..base import PlanStats
from .heuristic import GridDistance, ReedsShepp


@dataclass(frozen=True)
class HybridAStarConfig:
    """Search resolution, costs and budget. Lengths in metres, costs in metres of driving."""

    xy_resolution: float = 0.1
    heading_resolution_deg: float = 5.0
    step: float = 0.4  # arc length of one motion primitive
    min_step: float = 0.1  # shortest primitive left after cutting one short at an obstacle
    n_steer: int = 5  # steering angles per direction, odd (straight included)
    steer_fraction: float = 0.9  # plan curvature to this fraction of the car's limit
    sample_step: float = 0.05  # pose spacing of the collision checks
    clearance: float = 0.05  # gap kept to every obstacle, for tracking error
    reverse_cost: float = 1.5  # per metre reversed (forward: 1)
    switch_cost: float = 2.0  # per direction switch
    steer_cost: float = 0.2  # per metre, times |steer| / max steer
    steer_change_cost: float = 0.5  # per change of steering between primitives, times |change| / max
    heuristic_weight: float = 1.5
    analytic_every: int = 2  # try a Reeds-Shepp connection every k-th expansion
    backward_share: float = 0.5  # of the budget, for the search out of the slot
    grid_resolution: float = 0.25
    goal_margin: float = 0.05  # ISO margins plus this, for the goal set
    goal_heading_deg: float = 2.0
    window_margin: float = 10.0  # search window beyond the slot and start
    start_relief: float = 1.0  # radius about a start closer than clearance to an obstacle
    time_budget_s: float = 10.0

    def __post_init__(self) -> None:
        positive = (
            "xy_resolution",
            "heading_resolution_deg",
            "step",
            "sample_step",
            "grid_resolution",
            "time_budget_s",
            "window_margin",
            "min_step",
            "start_relief",
        )
        for name in positive:
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise ValueError(f"{name}: must be a finite number > 0, got {v!r}")
        if not (isinstance(self.n_steer, int) and self.n_steer >= 1 and self.n_steer % 2 == 1):
            raise ValueError(f"n_steer: must be an odd integer >= 1, got {self.n_steer!r}")
        if not 0 <= self.backward_share <= 1:
            raise ValueError(f"backward_share: must be in [0, 1], got {self.backward_share}")
        if not 0 < self.steer_fraction <= 1:
            raise ValueError(f"steer_fraction: must be in (0, 1], got {self.steer_fraction}")
        if self.min_step > self.step:
            raise ValueError(f"min_step: must be <= step={self.step} m, got {self.min_step}")
        if self.sample_step > self.step:
            raise ValueError(f"sample_step: must be <= step={self.step} m, got {self.sample_step}")
        for name in (
            "clearance",
            "reverse_cost",
            "switch_cost",
            "steer_cost",
            "steer_change_cost",
            "goal_margin",
            "goal_heading_deg",
        ):
            if not getattr(self, name) >= 0:
                raise ValueError(f"{name}: must be >= 0, got {getattr(self, name)!r}")
        if not self.heuristic_weight >= 1:
            raise ValueError(f"heuristic_weight: must be >= 1, got {self.heuristic_weight}")
        if not (isinstance(self.analytic_every, int) and self.analytic_every >= 1):
            raise ValueError(f"analytic_every: must be an integer >= 1, got {self.analytic_every!r}")


@dataclass(frozen=True, eq=False)
class Path:
    """A planned path: rear-axle poses ``sample_step`` or less apart.

    ``direction[i]`` is the gear (+1 forward, -1 reverse) driven from pose i - 1 to pose
    i (``direction[0]`` repeats ``direction[1]``); ``curvature[i]`` likewise.
    """

    poses: np.ndarray  # (n, 3)
    direction: np.ndarray  # (n,)
    curvature: np.ndarray  # (n,)

    @property
    def length(self) -> float:
        return float(np.hypot(*np.diff(self.poses[:, :2], axis=0).T).sum())

    @property
    def switches(self) -> int:
        return int(np.count_nonzero(np.diff(self.direction)))

    def segments(self) -> list[tuple[int, int]]:
        """Index ranges [i0, i1] (inclusive) driven in one gear, in order."""
        cuts = np.flatnonzero(np.diff(self.direction[1:])) + 1
        bounds = [0, *cuts.tolist(), len(self.poses) - 1]
        return [(bounds[k], bounds[k + 1]) for k in range(len(bounds) - 1)]

    @classmethod
    def from_poses(cls, poses: np.ndarray) -> Path:
        """Gear and curvature from consecutive poses (gear: sign of motion along the heading)."""
        poses = np.asarray(poses, dtype=float)
        d = np.diff(poses[:, :2], axis=0)
        ds = np.hypot(d[:, 0], d[:, 1])
        along = d[:, 0] * np.cos(poses[:-1, 2]) + d[:, 1] * np.sin(poses[:-1, 2])
        gear = np.where(along >= 0, 1.0, -1.0)
        dth = np.remainder(np.diff(poses[:, 2]) + math.pi, 2 * math.pi) - math.pi
        kappa = np.where(ds > 1e-9, dth / np.maximum(ds, 1e-9) * gear, 0.0)
        return cls(poses, np.concatenate(([gear[0]], gear)), np.concatenate(([kappa[0]], kappa)))


@dataclass
class _Node:
    pose: tuple[float, float, float]
    g: float
    parent: int
    gear: int  # 0 at the start
    steer: float  # normalised, in [-1, 1]
    samples: np.ndarray | None  # poses from the parent (excluded) to this node (included)


class HybridAStar:
    """Plans in one scenario geometry; ``plan(start)`` returns a path or a failure status."""

    def __init__(self, geometry: ScenarioGeometry, config: HybridAStarConfig | None = None):
        self.geometry = geometry
        self.cfg = cfg = config or HybridAStarConfig()
        car = geometry.vehicle
        self.kappa_max = cfg.steer_fraction * math.tan(car.max_steer) / car.wheelbase
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
        self.goal_heading = math.radians(cfg.goal_heading_deg)
        self._primitives = self._make_primitives()
        self._grids: dict[tuple, GridDistance] = {}
        # The slot's centre has the largest margins a pose in it can have: if the ISO check
        # fails there, no pose in the slot passes (a slot narrower than the car plus margins).
        self.goal_exists = self.criteria.verdict(*self.goal, 0.0, 0.0, False).failed is None

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
                ss = gear * s
                if abs(k) < 1e-9:
                    dx, dy = ss, np.zeros_like(ss)
                else:
                    dx, dy = np.sin(k * ss) / k, (1 - np.cos(k * ss)) / k
                offsets.append(np.stack((dx, dy, k * ss), axis=1))
                gears.append(gear)
                steer_of.append(u)
        return np.array(offsets), np.array(gears), np.array(steer_of)

    def _gaps(self, poses: np.ndarray) -> np.ndarray:
        """Lower bound on each pose's distance to the nearest obstacle (< 0: overlap)."""
        return -self.checker.penetration(poses[:, 0], poses[:, 1], poses[:, 2]).max(axis=1)

    def _in_window(self, poses: np.ndarray) -> np.ndarray:
        x0, x1, y0, y1 = self.window
        return (poses[:, 0] >= x0) & (poses[:, 0] <= x1) & (poses[:, 1] >= y0) & (poses[:, 1] <= y1)

    def path_is_clear(self, poses: np.ndarray) -> bool:
        """Whether poses at most ``sample_step`` apart certify a sweep clear by ``clearance``."""
        return bool((self._gaps(poses) >= self._required(poses)).all())

    def _required(self, poses: np.ndarray) -> np.ndarray | float:
        """Gap each sampled pose must keep: ``required_gap``, less near a tight start.

        Grid starts may touch the road's edges. Within ``start_relief`` metres of such a
        start the samples need only keep the start's own gap (at least 0: they never
        overlap an obstacle), otherwise the car could not leave its start at all.
        """
        if self._start_gap >= self.required_gap:
            return self.required_gap
        near = np.hypot(poses[:, 0] - self._start[0], poses[:, 1] - self._start[1]) < self.cfg.start_relief
        return np.where(near, max(self._start_gap, 0.0), self.required_gap)

    def in_goal_set(self, pose) -> bool:
        """ISO success at ``pose`` (standing still), with ``goal_margin`` and heading to spare."""
        x, y, th = (float(v) for v in pose)
        v = self.criteria.verdict(x, y, th, 0.0, 0.0, False)
        if not v.inside_slot or abs(v.heading_error) > self.goal_heading:
            return False
        need = self.criteria.min_margin + self.cfg.goal_margin
        return min(v.margins.values()) >= need

    def _analytic(self, pose, goal) -> np.ndarray | None:
        """A clear Reeds-Shepp path from ``pose`` to ``goal``, or None."""
        coarse = self.rs.sample(pose, goal, 4 * self.cfg.sample_step)
        if (self._gaps(coarse) < np.minimum(self._required(coarse), self.cfg.clearance)).any() or not self._in_window(
            coarse
        ).all():
            return None  # a pose that close already rules the path out
        fine = self.rs.sample(pose, goal, self.cfg.sample_step)
        return fine if self.path_is_clear(fine) else None

    # -- search ---------------------------------------------------------------------
    def _window(self, start) -> tuple[float, float, float, float]:
        g, m = self.geometry, self.cfg.window_margin
        x0 = min(float(g.slot[:, 0].min()), start[0]) - m
        x1 = max(float(g.slot[:, 0].max()), start[0]) + m
        return (x0, x1, g.bounds[2], g.road_width)

    def _key(self, pose) -> tuple[int, int, int]:
        r = self.cfg.xy_resolution
        return (
            int(math.floor(pose[0] / r)),
            int(math.floor(pose[1] / r)),
            int(math.floor(pose[2] / self.th_res + 0.5)) % self.n_th,
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
        forward from the start into the ISO goal set. Paths are reversible, so the
        backward one is driven in reverse order with the gear costs swapped.
        Status: "ok", "start_in_collision", "no_goal" (no pose in the slot passes the ISO
        check), "no_path" (the reachable space is exhausted) or "budget" (``time_budget_s``
        ran out).
        """
        t0 = time.perf_counter()
        cfg = self.cfg
        start = tuple(float(v) for v in start)
        self.window = self._window(start)
        counts = {"expansions": 0, "nodes": 0}

        def done(path: Path | None, status: str, cost: float = math.nan, direction: str = ""):
            detail = {
                "switches": path.switches if path is not None else -1,
                "length": path.length if path is not None else math.nan,
                "search": direction,
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
        deadline = t0 + cfg.backward_share * cfg.time_budget_s
        poses, status, cost = self._search(self.goal, start, backward=True, deadline=deadline, counts=counts)
        if poses is not None:
            return done(Path.from_poses(poses[::-1]), "ok", cost, "backward")
        poses, status, cost = self._search(
            start, self.goal, backward=False, deadline=t0 + cfg.time_budget_s, counts=counts
        )
        if poses is not None:
            return done(Path.from_poses(poses), "ok", cost, "forward")
        return done(None, status)

    def _search(self, origin, goal, backward: bool, deadline: float, counts: dict[str, int]):
        """One A* search from ``origin``; (poses or None, status, cost).

        Forward, a node in the ISO goal set also ends it; backward, the gear costs are
        swapped, since the path will be driven the other way.
        """
        cfg = self.cfg
        grid = self._grid(goal)
        forward_cost, reverse_cost = (cfg.reverse_cost, 1.0) if backward else (1.0, cfg.reverse_cost)

        def h(pose) -> float:
            return cfg.heuristic_weight * max(self.rs.distance(pose, goal), grid(pose[0], pose[1]))

        nodes: list[_Node] = [_Node(origin, 0.0, -1, 0, 0.0, None)]
        open_heap = [(h(origin), 0, 0)]
        best_g = {self._key(origin): 0.0}
        closed: set[tuple[int, int, int]] = set()
        offsets, gears, steers = self._primitives
        status = "no_path"
        while open_heap:
            if time.perf_counter() > deadline:
                status = "budget"
                break
            _, _, i = heapq.heappop(open_heap)
            node = nodes[i]
            key = self._key(node.pose)
            if key in closed:
                continue
            closed.add(key)
            counts["expansions"] += 1
            if not backward and i > 0 and self.in_goal_set(node.pose):
                counts["nodes"] += len(nodes)
                return self._trace(nodes, i, None), "ok", node.g
            if (len(closed) - 1) % cfg.analytic_every == 0:
                tail = self._analytic(node.pose, goal)
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
            ok = (self._gaps(flat) >= self._required(flat)) & self._in_window(flat)
            ok = ok.reshape(poses.shape[:2])
            # A primitive that runs into an obstacle is cut short at its last clear sample
            # (when it still covers min_step): the short moves of a tight manoeuvre.
            n_clear = np.where(ok.all(axis=1), ok.shape[1], ok.argmin(axis=1))
            for p in np.flatnonzero(n_clear >= self.min_samples):
                k = int(n_clear[p])
                end = poses[p, k - 1]
                child_key = self._key(end)
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
                hv = h(pose)
                if not math.isfinite(hv):
                    continue
                best_g[child_key] = g
                nodes.append(_Node(pose, g, i, gear, float(steers[p]), poses[p, :k]))
                heapq.heappush(open_heap, (g + hv, len(nodes) - 1, len(nodes) - 1))
        counts["nodes"] += len(nodes)
        return None, status, math.nan

    @staticmethod
    def _trace(nodes: list[_Node], i: int, tail: np.ndarray | None) -> np.ndarray:
        parts = [] if tail is None else [tail[1:]]
        while i > 0:
            parts.append(nodes[i].samples)
            i = nodes[i].parent
        parts.append(np.array([nodes[0].pose]))
        return np.concatenate(parts[::-1])
