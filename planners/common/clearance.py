"""Clearance to obstacles, with the one start-relief rule every planner applies.

Grid starts may stand closer to a kerb than a planner's working gap (a car 6.5 cm from the
far kerb swings its rear overhang ~5 cm out as it turns away). Within ``radius`` of such a
start a pose need keep only what the start itself has (less ``slack``, never more than
``floor``): the car may leave a tight spot, not tighten it.
"""

from __future__ import annotations

import math
import weakref

import numpy as np

from mirrorpark_env.geometry import FootprintChecker

from .kernels import FastGaps

START_RELIEF = 1.0  # [m] around a start closer than a planner's gap, only the start's own gap is kept ...
START_SLACK = 0.0005  # [m] ... less this much


_FAST: weakref.WeakKeyDictionary[FootprintChecker, FastGaps] = weakref.WeakKeyDictionary()


def gap_kernel(checker: FootprintChecker) -> FastGaps:
    """The compiled gap kernel of ``checker`` (its ``args`` feed other compiled loops)."""
    fast = _FAST.get(checker)
    if fast is None:
        fast = _FAST[checker] = FastGaps(checker)
    return fast


def gaps(checker: FootprintChecker, poses: np.ndarray, all_axes: bool = False) -> np.ndarray:
    """Lower bound on each pose's distance to the nearest obstacle (< 0: overlap): the
    negated ``checker.penetration(...).max(axis=1)``, bit for bit, from a compiled kernel;
    ``all_axes``: the tighter bound of ``kernels.FastGaps``, independent of the batch."""
    return gap_kernel(checker)(poses, all_axes)


def required_gap(
    poses: np.ndarray,
    start_xy,
    start_gap: float,
    need: float,
    radius: float = START_RELIEF,
    floor: float = math.inf,
    slack: float = START_SLACK,
) -> np.ndarray | float:
    """Gap each of ``poses`` must keep: ``need``, but within ``radius`` of the start (at
    ``start_xy``, ``start_gap`` from the nearest obstacle) only
    ``min(need, floor, max(start_gap, 0) - slack)``."""
    near_need = min(need, floor, max(start_gap, 0.0) - slack)
    if near_need >= need:
        return need
    near = np.hypot(poses[:, 0] - start_xy[0], poses[:, 1] - start_xy[1]) < radius
    return np.where(near, near_need, need)
