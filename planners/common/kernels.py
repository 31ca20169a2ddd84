"""Compiled inner loops of the planners' collision checks (numba).

A profile of a hybrid A* call that spends its budget (10,000 expansions in a parallel slot
of 1.13 car lengths) put a third of its time in ``FootprintChecker.penetration`` on small
batches (80 poses per expansion): numpy's per-call overhead, not arithmetic. These
kernels compute the same separating-axis values pose by pose, with the same operations in
the same order, so that planners get the same gaps as from the numpy checker (a test
compares them bit for bit on random batches). The environment's own verdicts keep using
the numpy checker.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from mirrorpark_env.geometry import FootprintChecker


@njit(cache=True, nogil=True)
def _obstacle_axes(ox, oy, c, s, hl, hw, normals, pmin, pmax, k):  # pragma: no cover - compiled
    """The least overlap of the footprint (centre (ox, oy), heading cosine ``c`` and sine
    ``s``, half length ``hl``, half width ``hw``) with obstacle ``k`` along the obstacle's
    own edge normals (<= 0: separated)."""
    m = math.inf
    for v in range(normals.shape[1]):
        nx = normals[k, v, 0]
        ny = normals[k, v, 1]
        pc = ox * nx + oy * ny
        ext = abs(c * nx + s * ny) * hl + abs(c * ny + s * (-nx)) * hw
        hi = min(pc + ext, pmax[k, v])
        lo = max(pc - ext, pmin[k, v])
        d = hi - lo
        if d < m:
            m = d
    return m


@njit(cache=True, nogil=True)
def _own_axes(ox, oy, c, s, hl, hw, verts, k):  # pragma: no cover - compiled
    """The least overlap of the same footprint with obstacle ``k`` along the footprint's
    own two axes."""
    umin = math.inf
    umax = -math.inf
    wmin = math.inf
    wmax = -math.inf
    for v in range(verts.shape[1]):
        vx = verts[k, v, 0]
        vy = verts[k, v, 1]
        pu = vx * c + vy * s
        pw = vx * (-s) + vy * c
        umin = min(umin, pu)
        umax = max(umax, pu)
        wmin = min(wmin, pw)
        wmax = max(wmax, pw)
    cu = ox * c + oy * s
    cw = oy * c - ox * s
    du = min(umax, cu + hl) - max(umin, cu - hl)
    dw = min(wmax, cw + hw) - max(wmin, cw - hw)
    return min(du, dw)


@njit(cache=True, nogil=True)
def _penetration(poses, front, rear, hw, normals, pmin, pmax, verts, all_axes=False):  # pragma: no cover - compiled
    """Penetration (P, K) of the footprint at rear-axle poses (P, 3) into obstacles given
    as (K, V, 2) arrays: ``FootprintChecker.penetration``, including its batch rule (the
    rectangle's own axes are tested for every pair as soon as one pair of the batch is not
    separated by an obstacle's axes; ``all_axes``: always)."""
    n = poses.shape[0]
    k_n = normals.shape[0]
    co = 0.5 * (front - rear)
    hl = 0.5 * (front + rear)
    ov = np.empty((n, k_n))
    cs = np.empty((n, 2))
    oc = np.empty((n, 2))
    overlap = False
    for p in range(n):
        c = math.cos(poses[p, 2])
        s = math.sin(poses[p, 2])
        cs[p, 0] = c
        cs[p, 1] = s
        ox = co * c + poses[p, 0]
        oy = co * s + poses[p, 1]
        oc[p, 0] = ox
        oc[p, 1] = oy
        for k in range(k_n):
            m = _obstacle_axes(ox, oy, c, s, hl, hw, normals, pmin, pmax, k)
            ov[p, k] = m
            if m > 0:
                overlap = True
    if overlap or all_axes:
        for p in range(n):
            for k in range(k_n):
                ov[p, k] = min(ov[p, k], _own_axes(oc[p, 0], oc[p, 1], cs[p, 0], cs[p, 1], hl, hw, verts, k))
    return ov


@njit(cache=True, nogil=True)
def _gaps(poses, front, rear, hw, normals, pmin, pmax, verts, all_axes=False):  # pragma: no cover - compiled
    """Gaps (P,) of the footprint at rear-axle poses (P, 3): ``_penetration``'s largest
    value per pose, negated (``FootprintChecker.penetration(...).max(axis=1)``)."""
    ov = _penetration(poses, front, rear, hw, normals, pmin, pmax, verts, all_axes)
    out = np.empty(ov.shape[0])
    for p in range(ov.shape[0]):
        best = -math.inf
        for k in range(ov.shape[1]):
            if ov[p, k] > best:
                best = ov[p, k]
        out[p] = -best
    return out


@njit(cache=True, nogil=True)
def _clear(x, y, c, s, clearance, front, rear, hw, normals, pmin, pmax, verts):  # pragma: no cover - compiled
    """Whether ``_gaps`` with ``all_axes`` gives the rear-axle pose (x, y, heading with
    cosine ``c`` and sine ``s``) a gap of at least ``clearance``: the same values from
    the same operations, so the same verdict bit for bit (a test checks it), without
    allocating, and stopping at the first obstacle that decides it. For search loops that
    test one pose at a time and already hold the heading's cosine and sine."""
    co = 0.5 * (front - rear)
    hl = 0.5 * (front + rear)
    ox = co * c + x
    oy = co * s + y
    # gap = -max_k m_k >= clearance  <=>  every m_k <= -clearance (negation is exact)
    lim = -clearance
    for k in range(normals.shape[0]):
        m = _obstacle_axes(ox, oy, c, s, hl, hw, normals, pmin, pmax, k)
        if m <= lim:
            continue  # m_k = min(m, the footprint's axes) <= m: this obstacle is clear
        if min(m, _own_axes(ox, oy, c, s, hl, hw, verts, k)) > lim:
            return False
    return True


@njit(cache=True, nogil=True)
def _clear_far(x, y, c, s, clearance, front, rear, hw, normals, pmin, pmax, verts, cen, rad):  # pragma: no cover
    """``_clear``'s verdict bit for bit, with a broad phase: obstacle ``k`` (its vertices
    within ``rad[k]`` of ``cen[k]``) is passed over where its vertices' projections on the
    footprint's own axes lie ``clearance`` (and 1e-9 m) clear of the footprint's, so that
    ``_own_axes``, and with it ``_clear``'s value, is certainly past the clearance. Most of
    a large lattice is far from most obstacles: the cost to go's search runs on this."""
    co = 0.5 * (front - rear)
    hl = 0.5 * (front + rear)
    ox = co * c + x
    oy = co * s + y
    lim = -clearance
    need = clearance + 1e-9
    for k in range(normals.shape[0]):
        dx = cen[k, 0] - ox
        dy = cen[k, 1] - oy
        if max(abs(dx * c + dy * s) - hl, abs(dy * c - dx * s) - hw) - rad[k] >= need:
            continue
        m = _obstacle_axes(ox, oy, c, s, hl, hw, normals, pmin, pmax, k)
        if m <= lim:
            continue
        if min(m, _own_axes(ox, oy, c, s, hl, hw, verts, k)) > lim:
            return False
    return True


def broad_phase(verts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(centre (K, 2), radius (K,)) of each obstacle's vertices (K, V, 2), the radius
    rounded up, for ``_clear_far``."""
    cen = verts.mean(axis=1)
    rad = np.sqrt(((verts - cen[:, None, :]) ** 2).sum(axis=2)).max(axis=1)
    return np.ascontiguousarray(cen), rad * (1 + 1e-12) + 1e-12


class FastGaps:
    """``gaps`` for one checker: lower bounds on each pose's distance to the nearest
    obstacle (< 0: overlap), compiled."""

    def __init__(self, checker: FootprintChecker) -> None:
        obs = checker.obstacles
        self.empty = len(obs) == 0
        self.args = (
            float(checker.front),
            float(checker.rear),
            float(checker.hw),
            np.ascontiguousarray(obs.normals, dtype=float),
            np.ascontiguousarray(obs.proj_min, dtype=float),
            np.ascontiguousarray(obs.proj_max, dtype=float),
            np.ascontiguousarray(obs.vertices, dtype=float),
        )

    def __call__(self, poses: np.ndarray, all_axes: bool = False) -> np.ndarray:
        """``all_axes``: test the footprint's own two axes for every pair, not only once some
        pair of the batch needs them: the largest separation over all six axes, a lower
        bound on the distance that does not depend on the other poses of the batch (near an
        obstacle edge's extension line the obstacle's axes alone can report millimetres
        where the car is half a metre away)."""
        if self.empty:
            return np.full(len(poses), np.inf)
        return _gaps(np.ascontiguousarray(poses, dtype=float), *self.args, all_axes)

    def penetration(self, poses: np.ndarray) -> np.ndarray:
        """``FootprintChecker.penetration`` at rear-axle poses (P, 3), (P, K), bit for bit."""
        if self.empty:
            return np.empty((len(poses), 0))
        return _penetration(np.ascontiguousarray(poses[:, :3], dtype=float), *self.args, False)
