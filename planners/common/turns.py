"""Multi-point turns: full-lock arcs in alternating gears that keep turning one way.

The way out of a tight slot (and, reversed, the way in): each arc is driven as far as it
stays clear, at most a quarter turn. Shared by the mirror planner's guide (its in-slot
tails) and its cost to go (the exact poses near the target that its lattice cannot resolve).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from .path import arc


def turn_chains(
    pose, radius: float, sample_step: float, arcs: int, first_bad: Callable[[np.ndarray, int], int]
) -> list[tuple[np.ndarray, list[int]]]:
    """One chain per turn direction and first gear from ``pose``: its poses every
    ``sample_step`` (the first is ``pose``) and the index of the pose that ends each arc.

    ``first_bad(poses, n)``: the index of the first pose of arc ``n`` (0-based; its poses
    start at the arc's start) that is not clear, or ``len(poses)``; an arc ends one pose
    before it, and the chain ends at an arc shorter than two samples."""
    k_max = 1.0 / radius
    quarter = np.arange(0.0, 0.5 * math.pi * radius + 1e-9, sample_step)
    out = []
    for turn in (1.0, -1.0):
        for first_gear in (1.0, -1.0):
            q, acc, ends = np.asarray(pose, float)[:3], [np.asarray(pose, float)[None, :3]], []
            for n in range(arcs):
                gear = first_gear if n % 2 == 0 else -first_gear
                poses = arc(q, turn * gear * k_max, gear * quarter)
                stop = first_bad(poses, n) - 1
                if stop < 2:
                    break
                acc.append(poses[1 : stop + 1])
                ends.append(sum(len(a) for a in acc) - 1)
                q = poses[stop]
            if ends:
                out.append((np.concatenate(acc), ends))
    return out
