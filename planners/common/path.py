"""A path with gears, and the circular arcs that paths are built of.

Shared by every planner: hybrid A* searches over arcs and returns a ``Path``; the mirror
planner's guide builds one from Reeds-Shepp samples; ``PathTracker`` drives one.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from mirrorpark_env.angles import wrap_angles


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
        dth = wrap_angles(np.diff(poses[:, 2]))
        kappa = np.where(ds > 1e-9, dth / np.maximum(ds, 1e-9) * gear, 0.0)
        return cls(poses, np.concatenate(([gear[0]], gear)), np.concatenate(([kappa[0]], kappa)))


def arc(pose, kappa: float, s: np.ndarray) -> np.ndarray:
    """Poses (n, 3) at signed arc lengths ``s`` (negative: in reverse) along a circle of
    curvature ``kappa`` (0: a straight line) from ``pose`` (x, y, theta)."""
    x0, y0, th0 = (float(v) for v in pose[:3])
    th = th0 + kappa * s
    if kappa:
        x = x0 + (np.sin(th) - math.sin(th0)) / kappa
        y = y0 - (np.cos(th) - math.cos(th0)) / kappa
    else:
        x, y = x0 + s * math.cos(th0), y0 + s * math.sin(th0)
    return np.stack([x, y, th], axis=1)
