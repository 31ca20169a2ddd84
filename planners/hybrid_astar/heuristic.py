"""Heuristics of the hybrid A* search: Reeds-Shepp length and an obstacle-aware 2D distance.

The search takes the larger of the two (as Dolgov et al. and Autoware do): the
Reeds-Shepp length ignores obstacles, the 2D distance ignores the car's kinematics.
"""

from __future__ import annotations

import math

import numpy as np
import shapely
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import dijkstra

from mirrorpark_env.geometry import ConvexSet

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
