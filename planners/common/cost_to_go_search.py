"""Compiled pieces of the cost to go (``cost_to_go.py``): the lattice search, its heap, the
exact entries into the slot, and the poses between two points of V's way on."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from mirrorpark_env.angles import wrap_angle

from .kernels import _clear, _clear_far


@njit(cache=True)
def _push(hk, hv, n, key, val):  # pragma: no cover - compiled
    """Binary min-heap insert into (hk, hv)[:n]; returns the new size."""
    i = n
    hk[i] = key
    hv[i] = val
    while i > 0:
        par = (i - 1) // 2
        if hk[par] <= hk[i]:
            break
        hk[par], hk[i] = hk[i], hk[par]
        hv[par], hv[i] = hv[i], hv[par]
        i = par
    return n + 1


@njit(cache=True)
def _pop(hk, hv, n):  # pragma: no cover - compiled
    """Remove the heap's least entry; returns (key, value, new size)."""
    key, val = hk[0], hv[0]
    n -= 1
    hk[0], hv[0] = hk[n], hv[n]
    i = 0
    while True:
        c = 2 * i + 1
        if c >= n:
            break
        if c + 1 < n and hk[c + 1] < hk[c]:
            c += 1
        if hk[c] >= hk[i]:
            break
        hk[c], hk[i] = hk[i], hk[c]
        hv[c], hv[i] = hv[i], hv[c]
        i = c
    return key, val, n


@njit(cache=True)
def _arc_cs(x, y, th, c, s, kappa, length):  # pragma: no cover - compiled
    """The pose a signed arc length ``length`` along curvature ``kappa`` from (x, y, th),
    given th's cosine ``c`` and sine ``s``, with the end heading's: (x, y, theta, cos, sin)."""
    t = th + kappa * length
    if kappa != 0.0:
        ct, st = math.cos(t), math.sin(t)
        return x + (st - s) / kappa, y - (ct - c) / kappa, t, ct, st
    return x + length * c, y + length * s, t, c, s


@njit(cache=True)
def _put(out, m, row):  # pragma: no cover - compiled
    """``out`` with ``row`` at index ``m``, grown (doubled) where it is full."""
    if m >= out.shape[0]:
        bigger = np.empty((2 * out.shape[0], out.shape[1]))
        bigger[:m] = out[:m]
        out = bigger
    for c in range(len(row)):
        out[m, c] = row[c]
    return out


@njit(cache=True)
def _entry_rows(tx, ty, tth, radius, ds, max_straight, clearance, gap_args):  # pragma: no cover - compiled
    """Poses of straight-arc-straight paths driven out of the slot from the target, each
    sample clear by ``clearance`` (a branch ends at its first sample that is not), with
    each pose's path: rows (x, y, theta, out gear, s1, signed curvature, arc length, s2)."""
    front, rear, hw, normals, pmin, pmax, verts = gap_args
    n_s = int(max_straight / ds + 1e-9) + 1
    n_a = int(0.6 * math.pi * radius / ds) + 1  # arcs to 108 degrees
    out = np.empty((4096, 8))
    m = 0
    c0, s0 = math.cos(tth), math.sin(tth)

    def clear(x, y, c, s):
        return _clear(x, y, c, s, clearance, front, rear, hw, normals, pmin, pmax, verts)

    for og in (1.0, -1.0):
        for i in range(n_s):
            s1 = i * ds
            x1, y1 = tx + og * s1 * c0, ty + og * s1 * s0
            if not clear(x1, y1, c0, s0):
                break
            out = _put(out, m, (x1, y1, tth, og, s1, 0.0, 0.0, 0.0))
            m += 1
            for turn in (1.0, -1.0):
                for j in range(1, n_a):
                    a = j * ds
                    x2, y2, th2, ca, sa = _arc_cs(x1, y1, tth, c0, s0, turn / radius, og * a)
                    if not clear(x2, y2, ca, sa):
                        break
                    for k in range(n_s):
                        s2 = k * ds
                        x3, y3 = x2 + og * s2 * ca, y2 + og * s2 * sa
                        if k > 0 and not clear(x3, y3, ca, sa):
                            break
                        out = _put(out, m, (x3, y3, th2, og, s1, turn / radius, a, s2))
                        m += 1
    return out[:m]


@njit(cache=True)
def _search(
    kappa, gear, cost, step, grid, sources, source_pose, source_v, per_switch, clearance, gap_args, stop, stop_rule
):  # pragma: no cover - compiled
    """Backward Dijkstra over nodes (cell, gear the car arrived in), each holding the exact
    pose it was reached at (hybrid A*'s rule: a cell keeps its cheapest pose). Moves and
    switches are priced by the caller (``cost[p]``, ``per_switch``: ``cost.py``).

    A node's predecessors are the poses from which one move (curvature ``kappa[p]``, gear
    ``gear[p]``, length ``step``, priced ``cost[p]``) ends exactly at its pose; one is kept
    if it and the move's midpoint keep ``clearance`` from the obstacles. ``grid``: (res,
    dth, x0, y0, th0, i0, j0, nx, ny, nh). Returns V (S, 2) by arrival gear (0: reverse,
    1: forward), the poses (S, 2, 3), each node's successor node (2 s + g; -1: a source)
    and the largest heap the search held.

    ``stop``: states (sorted) at which the search may stop early; once the first of them is
    settled at cost c, it stops when the next cost exceeds the bound ``stop_rule[0] x c +
    stop_rule[1]``, which it returns (inf: it ran to the end). Dijkstra settles states in
    order of cost: every V at most the bound is exact, and every state above it (or inf)
    costs at least the bound.
    """
    res, dth, x0, y0, th0 = grid[0], grid[1], grid[2], grid[3], grid[4]
    i0, j0, nx, ny, nh = int(grid[5]), int(grid[6]), int(grid[7]), int(grid[8]), int(grid[9])
    front, rear, hw, normals, pmin, pmax, verts, cen, rad = gap_args
    S = nx * ny * nh
    V = np.full((S, 2), np.inf)
    P = np.zeros((S, 2, 3), np.float32)
    nxt = np.full((S, 2), -1, np.int32)
    cap = 2 * S + 2 * sources.shape[0] + 16
    hk = np.empty(cap)
    hv = np.empty(cap, dtype=np.int64)
    n, peak = 0, 0
    for k in range(sources.shape[0]):
        for gi in range(2):
            if source_v[k, gi] < V[sources[k], gi]:
                V[sources[k], gi] = source_v[k, gi]
                P[sources[k], gi] = source_pose[k]
                n = _push(hk, hv, n, source_v[k, gi], sources[k] * 2 + gi)
    bound = math.inf
    while n > 0:
        key, node, n = _pop(hk, hv, n)
        s2, g2 = node // 2, node % 2
        if key > V[s2, g2]:
            continue  # a stale entry
        if key > bound:
            break
        if bound == math.inf and stop.shape[0] > 0:
            at = np.searchsorted(stop, s2)
            if at < stop.shape[0] and stop[at] == s2:
                bound = stop_rule[0] * key + stop_rule[1]
        px, py, pth = float(P[s2, g2, 0]), float(P[s2, g2, 1]), float(P[s2, g2, 2])
        pc, ps = math.cos(pth), math.sin(pth)
        for p in range(kappa.shape[0]):
            if (gear[p] > 0) != (g2 == 1):
                continue  # p arrives at the node in its own gear
            k0 = key + cost[p]
            qx, qy, qth, qc, qs = _arc_cs(px, py, pth, pc, ps, kappa[p], -gear[p] * step)
            ix = int(math.floor((qx - x0) / res + 0.5)) - i0
            iy = int(math.floor((qy - y0) / res + 0.5)) - j0
            if ix < 0 or ix >= nx or iy < 0 or iy >= ny:
                continue
            ih = int(math.floor((qth - th0) / dth + 0.5)) % nh
            s = (ix * ny + iy) * nh + ih
            if k0 >= V[s, 0] and k0 >= V[s, 1]:
                continue  # no improvement possible: skip the check
            if not _clear_far(qx, qy, qc, qs, clearance, front, rear, hw, normals, pmin, pmax, verts, cen, rad):
                continue
            mx, my, _, mc, ms = _arc_cs(px, py, pth, pc, ps, kappa[p], -0.5 * gear[p] * step)
            if not _clear_far(mx, my, mc, ms, clearance, front, rear, hw, normals, pmin, pmax, verts, cen, rad):
                continue
            n, peak = _relax(V, P, nxt, hk, hv, n, peak, s, k0, g2, per_switch, qx, qy, qth, node)
    return V, P, nxt, peak, bound


@njit(cache=True)
def _relax(V, P, nxt, hk, hv, n, peak, s, k0, g2, per_switch, qx, qy, qth, node):  # pragma: no cover - compiled
    """Lower both arrival columns of state ``s`` reached from ``node`` at ``k0`` (plus a
    switch where the column's gear is not the move's); (heap size, peak; past the heap's
    capacity: capacity + 1)."""
    cap = hk.shape[0]
    for gp in range(2):  # the gear the car arrived at q in: a switch if not p's
        k = k0 + (per_switch if gp != g2 else 0.0)
        if k < V[s, gp]:
            V[s, gp] = k
            P[s, gp, 0], P[s, gp, 1], P[s, gp, 2] = qx, qy, qth
            nxt[s, gp] = node
            if n >= cap:
                peak = cap + 1
                continue
            n = _push(hk, hv, n, k, s * 2 + gp)
            peak = max(peak, n)
    return n, peak


@njit(cache=True, nogil=True)
def _between(a, b, gear, d, sample_step):  # pragma: no cover - compiled
    """Poses after each ``a[m]`` up to ``b[m]`` (rows (x, y, theta)), end to end, along the
    arc from ``a[m]`` through ``b[m]`` (or the straight line) in gear ``gear[m]``, about
    ``sample_step`` apart; ``d[m]``: the distance from a[m] to b[m]. The moves of V's way
    on, or tail steps, resampled: ``common.path.arc``'s arithmetic, compiled (a test
    compares it with the numpy form bit for bit)."""
    counts = np.empty(len(d), np.int64)
    for m in range(len(d)):
        counts[m] = max(1, math.ceil(d[m] / sample_step - 1e-9))
    out = np.empty((counts.sum(), 3))
    r = 0
    for m in range(len(d)):
        n = counts[m]
        x0, y0, th0 = a[m, 0], a[m, 1], a[m, 2]
        dth = b[m, 2] - th0
        if abs(dth) < 1e-9 or d[m] < 1e-12:
            for i in range(1, n + 1):
                t = i / n
                out[r, 0] = x0 + t * (b[m, 0] - x0)
                out[r, 1] = y0 + t * (b[m, 1] - y0)
                out[r, 2] = b[m, 2]
                r += 1
            continue
        sh = math.sin(0.5 * dth)
        s = gear[m] * d[m] * (0.5 * dth) / sh if abs(sh) > 1e-12 else gear[m] * d[m]
        kappa = dth / s
        s0, c0 = math.sin(th0), math.cos(th0)
        for i in range(1, n + 1):
            out[r, 0], out[r, 1], out[r, 2], _, _ = _arc_cs(x0, y0, th0, c0, s0, kappa, s * i / n)
            r += 1
    return out


def _ahead(pose: np.ndarray, way: list, min_along: float) -> list:
    """``way`` ((pose, gear) steps) from its first pose that lies at least ``min_along``
    ahead of ``pose`` in that step's gear; empty where none does."""
    c, s = math.cos(pose[2]), math.sin(pose[2])
    for k, (q, gr) in enumerate(way):
        if gr * ((q[0] - pose[0]) * c + (q[1] - pose[1]) * s) >= min_along:
            return way[k:]
    return []


def _straight(a: np.ndarray, b: np.ndarray, d: float, sample_step: float) -> np.ndarray:
    """Poses after ``a`` up to ``b``, ``d`` apart, on the straight line, headings turning the
    short way between (a cell's stored heading may differ from the car's by a full turn:
    22 of 554 joins on every 25th standard case), the last one ``b``'s own."""
    n = max(1, math.ceil(d / sample_step - 1e-9))
    t = np.arange(1, n + 1) / n
    b = np.asarray(b[:3], float)
    out = np.empty((n, 3))
    out[:, 0] = a[0] + t * (b[0] - a[0])
    out[:, 1] = a[1] + t * (b[1] - a[1])
    out[:, 2] = a[2] + t * wrap_angle(b[2] - a[2])
    out[-1, 2] = b[2]
    return out


def _first_gear(chain: np.ndarray) -> float:
    """The gear a chain leaves its first pose in (sign of the motion along the heading)."""
    d = chain[1, :2] - chain[0, :2]
    return 1.0 if d[0] * math.cos(chain[0, 2]) + d[1] * math.sin(chain[0, 2]) >= 0 else -1.0
