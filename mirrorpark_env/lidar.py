"""A ring of range readings to the obstacles, like highway-env's ``LidarObservation``.

An agent that must act in a layout it has not seen needs to perceive the obstacles; the
grid's observation vector names the scene by its sizes instead. Rays leave the body
centre at equal angles from the heading (ray 0 straight ahead, then counter-clockwise);
each reads the distance to the nearest obstacle edge, at most ``max_range``, divided by
it (so 1.0 is "nothing in range").
"""

from __future__ import annotations

import math

import numpy as np

from .geometry import ConvexSet


class Lidar:
    """Ray casting against every edge of a scene's convex obstacle parts, vectorised."""

    def __init__(self, obstacles: ConvexSet, rays: int, max_range: float):
        if rays < 1:
            raise ValueError(f"lidar rays: must be >= 1, got {rays}")
        if not (max_range > 0 and math.isfinite(max_range)):
            raise ValueError(f"lidar max_range: must be a positive number, got {max_range}")
        self.rays, self.max_range = rays, float(max_range)
        a = obstacles.vertices.reshape(-1, 2)
        b = np.roll(obstacles.vertices, -1, axis=1).reshape(-1, 2)
        keep = np.hypot(*(b - a).T) > 1e-12  # padded vertices repeat: drop their empty edges
        self._a, self._e = a[keep], (b - a)[keep]
        self._angles = 2 * math.pi * np.arange(rays) / rays

    def read_body(self, x: float, y: float, heading: float, centre_offset: float) -> np.ndarray:
        """``read`` from the body centre of a car whose rear axle stands at (x, y): what the
        env observes, and what a policy trained on it measures for itself."""
        return self.read(x + centre_offset * math.cos(heading), y + centre_offset * math.sin(heading), heading)

    def read(self, x: float, y: float, heading: float) -> np.ndarray:
        """Normalised distances (rays,) from the point (x, y), ray 0 along ``heading``."""
        if not len(self._a):
            return np.ones(self.rays, dtype=np.float32)
        ang = heading + self._angles
        d = np.stack([np.cos(ang), np.sin(ang)], axis=1)  # (R, 2)
        w = self._a - np.array([x, y])  # (E, 2)
        denom = d[:, :1] * self._e[:, 1] - d[:, 1:] * self._e[:, 0]  # cross(d, e): (R, E)
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (w[:, 0] * self._e[:, 1] - w[:, 1] * self._e[:, 0]) / denom  # along the ray
            s = (w[:, 0] * d[:, 1:] - w[:, 1] * d[:, :1]) / denom  # along the edge
        hit = (np.abs(denom) > 1e-12) & (t >= 0) & (s >= 0) & (s <= 1)
        dist = np.where(hit, t, np.inf).min(axis=1)
        return (np.minimum(dist, self.max_range) / self.max_range).astype(np.float32)
