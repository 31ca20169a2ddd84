"""Heuristics of the hybrid A* search: the cost to go that knows the car, the Reeds-Shepp
length and an obstacle-aware 2D distance.

The search takes the larger of the Reeds-Shepp length and either the cost to go over
(x, y, heading) (``CostToGoHeuristic``, the default) or the 2D distance (``GridDistance``,
Dolgov et al.'s and Autoware's, kept for the ablation). The Reeds-Shepp length ignores
obstacles and the 2D distance the car's kinematics: neither sees that a car facing away from
its slot in an aisle about its own length wide must first turn around. The cost to go does:
it is a shortest path on a lattice of the car's own moves among the obstacles.
"""

from __future__ import annotations

import math

import numpy as np
import shapely
from numba import njit
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import dijkstra

from mirrorpark_env.geometry import ConvexSet
from mirrorpark_env.scenario import ScenarioGeometry

from ..common.cost_to_go import CostToGo
from ..common.cost_to_go_config import CostToGoConfig
from ..common.slot_cache import SlotCache

OCTILE = 1.0 / math.cos(math.pi / 8)  # worst ratio of 8-connected to straight distance


class GridDistance:
    """Shortest 8-connected grid distance from the goal, for a disc around the rear axle.

    A disc of radius ``clearance`` about the rear axle always lies inside the car's
    footprint, so cells closer than that to an obstacle can never hold the rear axle:
    the distance stays a lower bound on how far the rear axle must travel.
    """

    def __init__(
        self,
        obstacles: ConvexSet,
        window: tuple[float, float, float, float],
        goal_xy: tuple[float, float],
        resolution: float = 0.25,
        clearance: float = 0.5,
    ) -> None:
        x0, x1, y0, y1 = window
        self.x0, self.y0, self.res = x0, y0, resolution
        nx = int(math.ceil((x1 - x0) / resolution)) + 1
        ny = int(math.ceil((y1 - y0) / resolution)) + 1
        self.shape = (nx, ny)
        gx, gy = np.meshgrid(x0 + resolution * np.arange(nx), y0 + resolution * np.arange(ny), indexing="ij")
        blocked = np.zeros((nx, ny), dtype=bool)
        for poly in obstacles.polygons:
            grown = shapely.Polygon(poly).buffer(clearance)
            blocked |= shapely.contains_xy(grown, gx, gy)
        gi, gj = self._cell(*goal_xy)
        blocked[gi, gj] = False
        idx = np.arange(nx * ny).reshape(nx, ny)
        rows, cols, w = [], [], []
        for di, dj in ((1, 0), (0, 1), (1, 1), (1, -1)):
            j0, j1 = max(0, -dj), ny - max(0, dj)
            a = idx[: nx - di, j0:j1]
            b = idx[di:, j0 + dj : j1 + dj]
            ok = ~blocked.reshape(-1)[a] & ~blocked.reshape(-1)[b]
            rows.append(a[ok])
            cols.append(b[ok])
            w.append(np.full(ok.sum(), resolution * math.hypot(di, dj)))
        graph = coo_matrix(
            (np.concatenate(w), (np.concatenate(rows), np.concatenate(cols))), shape=(nx * ny, nx * ny)
        ).tocsr()
        dist = dijkstra(graph, directed=False, indices=gi * ny + gj)
        self.dist = dist.reshape(nx, ny)

    def _cell(self, x: float, y: float) -> tuple[int, int]:
        i = min(max(int(round((x - self.x0) / self.res)), 0), self.shape[0] - 1)
        j = min(max(int(round((y - self.y0) / self.res)), 0), self.shape[1] - 1)
        return i, j

    def __call__(self, x: float, y: float) -> float:
        """Grid distance [m] from (x, y) to the goal; inf where the rear axle cannot be.

        An 8-connected grid path is up to OCTILE times the Euclidean one, and rounding to
        a cell moves the point by up to half a diagonal: both are taken off, so that the
        value stays a lower bound.
        """
        d = self.dist[self._cell(x, y)]
        return max(0.0, d / OCTILE - 0.71 * self.res) if math.isfinite(d) else math.inf


_CACHE: SlotCache[CostToGo] = SlotCache(8)


def scene_box(geometry: ScenarioGeometry, config: CostToGoConfig) -> tuple[float, float, float, float]:
    """(x0, x1, y0, y1) the heuristic's lattice covers: the slot (or the target) and
    ``margin`` around it, and the episode's start and ``start_margin`` around it, within the
    scene's bounds. Unlike ``lattice_box`` (the road beside a grid slot, the mirror
    planner's) it assumes no road along x: a generated lot lies turned anywhere in the world."""
    pts = np.asarray(geometry.slot, float) if geometry.slot is not None else np.asarray(geometry.target[:2])[None]
    lo, hi = pts.min(axis=0) - config.margin, pts.max(axis=0) + config.margin
    s, m = np.array([geometry.start.x, geometry.start.y]), config.start_margin
    lo, hi = np.minimum(lo, s - m), np.maximum(hi, s + m)
    bx0, bx1, by0, by1 = geometry.bounds
    return (max(bx0, float(lo[0])), min(bx1, float(hi[0])), max(by0, float(lo[1])), min(by1, float(hi[1])))


class CostToGoHeuristic:
    """V(x, y, heading) arrived in a gear, from the cost to go shared with the mirror planner
    (``planners/common/cost_to_go.py``), priced in the search's own costs.

    V is a lattice's shortest path (moves of full lock or straight, 5 deg heading cells), so
    it may exceed the cheapest path a finer search finds: it is an estimate, not a bound
    (its measured inflation: docs/hybrid_astar.md, tests/test_hybrid_heuristic.py).

    Built once per slot and kept for the process's later calls (``_CACHE``), it is built only
    as far as the search needs it: its Dijkstra stops at ``rule[0]`` x V(start) + ``rule[1]``
    (``CostToGo.bound``), beyond which it reads the bound (V is at least that there). A call
    reads a V built for another start only up to its own start's bound (``own_bound``), so
    that it reads what a V built for it would give: the search never depends on which calls
    the process made before. A start beyond a V's bound builds it again. Where the lattice
    finds no way at all (inf), the caller falls back to a 2D distance.
    """

    def __init__(self, geometry: ScenarioGeometry, config: CostToGoConfig, start, rule: tuple[float, float]) -> None:
        box = scene_box(geometry, config)
        settings = (config.model_dump_json(), box, rule)
        self.V = V = _CACHE.get(
            geometry,
            settings,
            lambda: CostToGo(geometry, config, stop_near=start, stop_rule=rule, box=box),
            lambda held: own_bound(held, start, rule) <= held.bound,
        )
        self.table, self.bound = V.V, own_bound(V, start, rule)
        self.res, self.dth, self.nh, self.ny, self.nx = V.cfg.xy_resolution, V.dth, V.nh, V.ny, V.nx
        self.tx, self.ty, self.tth = V.origin
        self.i0, self.j0 = V.i0, V.j0

    def __call__(self, x: float, y: float, th: float, gear: int) -> float:
        """V at the pose, arrived in ``gear`` (+1, -1; 0: standing, either); beyond the bound,
        the bound; inf where the lattice finds no way."""
        i = math.floor((x - self.tx) / self.res + 0.5) - self.i0
        j = math.floor((y - self.ty) / self.res + 0.5) - self.j0
        if not (0 <= i < self.nx and 0 <= j < self.ny):
            return self.bound
        h = math.floor((th - self.tth) / self.dth + 0.5) % self.nh
        return float(_read(self.table, i, j, h, gear, self.ny, self.nx, self.nh, self.bound))


def own_bound(V: CostToGo, start, rule: tuple[float, float]) -> float:
    """The bound a V built for ``start`` would have: ``rule[0]`` x the least V of the cells
    near the start + ``rule[1]`` (the cost at which its Dijkstra settles the first of them;
    inf where none is reached: it would run to the end). Exact from a V whose own bound is at
    least that: its values up to its bound are exact."""
    near = V._near(start)
    c = float(V.V[near].min()) if len(near) else math.inf
    return rule[0] * c + rule[1] if c < math.inf else math.inf


@njit(cache=True)
def _read(table, i, j, h, gear, ny, nx, nh, bound):  # pragma: no cover - compiled
    """``CostToGo.at``'s value at cell (i, j, h) arrived in ``gear`` (0: either), read up
    to ``bound``: its own cell's, or where that is above the bound (or inf) the lowest of its
    neighbours (one cell each way); at most ``bound`` (V is at least that beyond it). Values
    above the bound are ignored, not read: they depend on how far the V was built."""
    lo, hi = (0, 1) if gear == 0 else ((1, 1) if gear > 0 else (0, 0))
    best = math.inf
    for c in range(lo, hi + 1):
        best = min(best, table[(i * ny + j) * nh + h, c])
    if best <= bound:
        return best
    for di in (0, -1, 1):
        for dj in (0, -1, 1):
            ii, jj = i + di, j + dj
            if ii < 0 or ii >= nx or jj < 0 or jj >= ny:
                continue
            for dh in (0, -1, 1):
                s = (ii * ny + jj) * nh + (h + dh) % nh
                for c in range(lo, hi + 1):
                    best = min(best, table[s, c])
    return min(best, bound)
