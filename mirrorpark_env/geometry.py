"""Exact convex-polygon geometry, vectorised with numpy.

Collision between the car's footprint rectangle and a convex obstacle is decided by the
separating-axis theorem: two convex polygons overlap iff their projections overlap on
every edge normal of both. The smallest of those overlaps is the penetration depth, so
"collision" here means a positive-area overlap deeper than ``COLLISION_TOL``; a car that
only touches an obstacle (depth 0) has not collided.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

COLLISION_TOL = 1e-9  # [m]


def as_ccw(poly: np.ndarray) -> np.ndarray:
    """The polygon's vertices in counter-clockwise order; rejects degenerate input."""
    p = np.asarray(poly, dtype=float)
    if p.ndim != 2 or p.shape[1] != 2 or len(p) < 3:
        raise ValueError(f"polygon: expected (n >= 3, 2) vertices, got shape {p.shape}")
    if not np.all(np.isfinite(p)):
        raise ValueError("polygon: vertices must be finite")
    area2 = np.sum(p[:, 0] * np.roll(p[:, 1], -1) - np.roll(p[:, 0], -1) * p[:, 1])
    if abs(area2) < 1e-12:
        raise ValueError("polygon: zero area")
    return p if area2 > 0 else p[::-1].copy()


def edge_normals(poly: np.ndarray) -> np.ndarray:
    """Outward unit normals of a CCW polygon's edges (edge i runs from vertex i to i+1)."""
    e = np.roll(poly, -1, axis=0) - poly
    n = np.stack([e[:, 1], -e[:, 0]], axis=1)
    return n / np.linalg.norm(n, axis=1, keepdims=True)


def is_convex(poly: np.ndarray) -> bool:
    p = as_ccw(poly)
    e = np.roll(p, -1, axis=0) - p
    cross = e[:, 0] * np.roll(e[:, 1], -1) - e[:, 1] * np.roll(e[:, 0], -1)
    return bool(np.all(cross >= -1e-12))


@dataclass(frozen=True, eq=False)
class ConvexSet:
    """Convex polygons padded to one vertex count, with their edge normals precomputed.

    ``vertices`` (K, V, 2); ``normals`` (K, V, 2) with padded entries repeating a real
    normal (so every axis is a valid separating-axis candidate); ``proj_min/max`` (K, V)
    are each polygon's extent along its own normals.
    """

    polygons: tuple[np.ndarray, ...]
    vertices: np.ndarray
    normals: np.ndarray
    proj_min: np.ndarray
    proj_max: np.ndarray

    @classmethod
    def from_polygons(cls, polygons: list[np.ndarray]) -> ConvexSet:
        polys = []
        for i, p in enumerate(polygons):
            q = as_ccw(p)
            if not is_convex(q):
                raise ValueError(f"polygon {i}: not convex")
            polys.append(q)
        v_max = max((len(p) for p in polys), default=3)
        verts = np.empty((len(polys), v_max, 2))
        norms = np.empty((len(polys), v_max, 2))
        for k, p in enumerate(polys):
            n = edge_normals(p)
            verts[k, : len(p)] = p
            verts[k, len(p) :] = p[-1]
            norms[k, : len(p)] = n
            norms[k, len(p) :] = n[0]
        proj = np.einsum("kvd,kwd->kwv", verts, norms)  # (K, axis, vertex)
        return cls(tuple(polys), verts, norms, proj.min(axis=2), proj.max(axis=2))

    def __len__(self) -> int:
        return len(self.polygons)


class FootprintChecker:
    """Exact collision test of the car's footprint, at many rear-axle poses at once.

    The footprint is the rectangle [-rear, front] x [-half_width, half_width] in the body
    frame. Separating-axis test in two stages: the obstacles' edge normals first (the
    rectangle's extent along a normal is |u.n| * half_length + |v.n| * half_width about
    its centre), then, only for pose-obstacle pairs not yet separated, the rectangle's
    own two axes.
    """

    def __init__(self, obstacles: ConvexSet, front: float, rear: float, half_width: float):
        self.obstacles = obstacles
        self.front, self.rear, self.hw = front, rear, half_width
        self.center_offset = 0.5 * (front - rear)
        self.half_length = 0.5 * (front + rear)
        k, v = obstacles.vertices.shape[:2]
        self._k, self._v = k, v
        self._nx = obstacles.normals[..., 0].reshape(1, -1)  # (1, KV)
        self._ny = obstacles.normals[..., 1].reshape(1, -1)
        self._pmin = obstacles.proj_min.reshape(-1)
        self._pmax = obstacles.proj_max.reshape(-1)
        self._vx = obstacles.vertices[..., 0].reshape(-1, 1)  # (KV, 1)
        self._vy = obstacles.vertices[..., 1].reshape(-1, 1)

    def penetration(self, x, y, theta) -> np.ndarray:
        """Penetration depth of the footprint into each obstacle, (P, K); <= 0 when apart.

        Where the obstacle's own axes already separate a pair, the value is that (<= 0)
        overlap; otherwise it is the exact penetration depth (the SAT minimum).
        """
        # Elementwise products only (no matmul): BLAS may fuse multiply-adds on one CPU and
        # not on another, and a verdict must not depend on the machine.
        theta = np.asarray(theta, dtype=float).reshape(-1)
        n = len(theta)
        c, s = np.cos(theta)[:, None], np.sin(theta)[:, None]  # (P, 1)
        ox = self.center_offset * c + np.asarray(x, dtype=float).reshape(-1, 1)  # body centres
        oy = self.center_offset * s + np.asarray(y, dtype=float).reshape(-1, 1)
        nx, ny = self._nx, self._ny
        pc = ox * nx + oy * ny  # centre along each obstacle normal, (P, KV)
        # |u.n| and |v.n| per normal: the rectangle's half-extent along it.
        ext = np.abs(c * nx + s * ny) * self.half_length + np.abs(c * ny + s * -nx) * self.hw
        ov = np.minimum(pc + ext, self._pmax) - np.maximum(pc - ext, self._pmin)
        ov = ov.reshape(n, self._k, self._v).min(axis=2)  # (P, K)
        if not (ov > 0).any():
            return ov
        # The rectangle's own axes u = (c, s), v = (-s, c): project every obstacle vertex.
        c, s, ox, oy = c.T, s.T, ox.T, oy.T  # (1, P)
        pu = (self._vx * c + self._vy * s).reshape(self._k, self._v, n)
        pw = (self._vx * -s + self._vy * c).reshape(self._k, self._v, n)
        cu, cw = ox * c + oy * s, oy * c - ox * s  # (1, P)
        hl, hw = self.half_length, self.hw
        ov_u = np.minimum(pu.max(axis=1), cu + hl) - np.maximum(pu.min(axis=1), cu - hl)  # (K, P)
        ov_w = np.minimum(pw.max(axis=1), cw + hw) - np.maximum(pw.min(axis=1), cw - hw)
        return np.minimum(ov, np.minimum(ov_u, ov_w).T)

    def collides(self, x, y, theta, tol: float = COLLISION_TOL) -> np.ndarray:
        """For each pose: does the footprint overlap some obstacle deeper than ``tol``?"""
        if self._k == 0:
            return np.zeros(np.size(x), dtype=bool)
        return self.penetration(x, y, theta).max(axis=1) > tol


@dataclass(frozen=True)
class HalfPlane:
    """Points p with ``normal . p >= offset`` lie inside; ``normal`` is a unit vector."""

    normal: tuple[float, float]
    offset: float

    def signed_distance(self, points: np.ndarray) -> np.ndarray:
        p = np.asarray(points, dtype=float)
        return p[..., 0] * self.normal[0] + p[..., 1] * self.normal[1] - self.offset


def inward_half_plane(a: np.ndarray, b: np.ndarray, inside_point: np.ndarray) -> HalfPlane:
    """Half-plane bounded by the line through a and b that contains ``inside_point``."""
    a = np.asarray(a, float)
    d = np.asarray(b, float) - a
    n = np.array([-d[1], d[0]]) / np.hypot(*d)
    if n @ (np.asarray(inside_point, float) - a) < 0:
        n = -n
    return HalfPlane((float(n[0]), float(n[1])), float(n @ a))
