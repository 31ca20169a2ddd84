"""Hybrid A*'s expansion loop, compiled (numba).

A profile of a call that spends its budget (9,000 expansions, a parallel slot of 4.42 m) put
150 us an expansion in Python: numpy on batches of 80 poses, a dict and a heap entry per child,
a Reeds-Shepp solve every other expansion. This loop does the same work with the same
arithmetic (``search.py`` drives it; a test compares its searches with recorded ones):

- the open list is a binary heap on (f, insertion number), the order Python's ``heapq`` on
  (f, tie, node) gives, since the insertion numbers are unique;
- cells are int64 keys (``cell_key``), closed cells and best costs typed dicts;
- each expansion checks every primitive's samples in one ``kernels._gaps`` batch, as before
  (the batch rule of the gap bound makes the batch part of the result);
- the estimate is the weight x the larger of the Reeds-Shepp length (``reeds_shepp.distance``)
  and the cost to go (``heuristic._read``) or, where that knows no way, the grid distance.

``run`` stops at the budget, the first node in the goal set, a clear analytic shot, an empty
open list, the expansion at which the cost to go takes over (``SHARPEN``: the caller builds
it and calls ``rerank``) or the end of a slice of expansions (``SLICE``: the caller checks its
wall-clock safety net), and resumes where it stopped.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, types
from numba.typed import Dict

from ..common.kernels import _gaps
from ..common.reeds_shepp import distance, place_one, solve
from .heuristic import OCTILE, _read

FOUND, SHOT, BUDGET, NO_PATH, SHARPEN, SLICE = range(6)

# Node columns of the float table: x, y, heading, g, steer; of the int table: parent, gear,
# primitive, samples kept, cell key.
X, Y, TH, G, STEER = range(5)
PARENT, GEAR, PRIM, KEPT, KEY = range(5)
# The counters: nodes, heap size, expansions, closed cells.
N_NODES, N_HEAP, N_EXP, N_CLOSED = range(4)


@njit(cache=True)
def new_maps():  # pragma: no cover - compiled
    """(best g by cell, closed cells): empty typed dicts."""
    return Dict.empty(types.int64, types.float64), Dict.empty(types.int64, types.int64)


@njit(cache=True)
def cell_key(x, y, th, gap, keyp):  # pragma: no cover - compiled
    """The cell of a pose as one int64: coarse, or fine where its gap is below ``keyp[0]``.
    ``keyp``: (fine_gap, fine xy res, fine heading res, fine heading cells, xy res, heading
    res, heading cells)."""
    if gap < keyp[0]:
        r, th_res, n_th, level = keyp[1], keyp[2], int(keyp[3]), 1
    else:
        r, th_res, n_th, level = keyp[4], keyp[5], int(keyp[6]), 0
    i = int(math.floor(x / r)) + (1 << 20)
    j = int(math.floor(y / r)) + (1 << 20)
    h = int(math.floor(th / th_res + 0.5)) % n_th
    return ((level * (1 << 21) + i) * (1 << 21) + j) * (1 << 10) + h


@njit(cache=True)
def _less(hf, ht, a, b):  # pragma: no cover - compiled
    return hf[a] < hf[b] or (hf[a] == hf[b] and ht[a] < ht[b])


@njit(cache=True)
def _swap(hf, ht, hn, a, b):  # pragma: no cover - compiled
    hf[a], hf[b] = hf[b], hf[a]
    ht[a], ht[b] = ht[b], ht[a]
    hn[a], hn[b] = hn[b], hn[a]


@njit(cache=True)
def push(hf, ht, hn, ctr, f, tie, node):  # pragma: no cover - compiled
    """Add (f, tie) for ``node`` to the heap."""
    k = ctr[N_HEAP]
    hf[k], ht[k], hn[k] = f, tie, node
    ctr[N_HEAP] = k + 1
    while k > 0:
        parent = (k - 1) // 2
        if not _less(hf, ht, k, parent):
            break
        _swap(hf, ht, hn, k, parent)
        k = parent


@njit(cache=True)
def _sift_down(hf, ht, hn, n, k):  # pragma: no cover - compiled
    while True:
        a, b, m = 2 * k + 1, 2 * k + 2, k
        if a < n and _less(hf, ht, a, m):
            m = a
        if b < n and _less(hf, ht, b, m):
            m = b
        if m == k:
            return
        _swap(hf, ht, hn, k, m)
        k = m


@njit(cache=True)
def _pop(hf, ht, hn, ctr):  # pragma: no cover - compiled
    node = hn[0]
    n = ctr[N_HEAP] - 1
    ctr[N_HEAP] = n
    if n > 0:
        hf[0], ht[0], hn[0] = hf[n], ht[n], hn[n]
        _sift_down(hf, ht, hn, n, 0)
    return node


@njit(cache=True)
def estimate(x, y, th, gear, heur, grid, table, carp):  # pragma: no cover - compiled
    """h: ``heur`` (goal x, y, heading, turning radius, weight, 1 if the cost to go is read)
    x the larger of the Reeds-Shepp length to the goal and the cost to go (``carp``: res,
    heading res, heading cells, ny, nx, origin x, y, heading, i0, j0, bound) or, where that
    is inf, the grid distance (``grid`` with ``heur[6:9]``: x0, y0, res)."""
    est = math.inf
    if heur[5] > 0:
        i = int(math.floor((x - carp[5]) / carp[0] + 0.5)) - int(carp[8])
        j = int(math.floor((y - carp[6]) / carp[0] + 0.5)) - int(carp[9])
        if 0 <= i < int(carp[4]) and 0 <= j < int(carp[3]):
            h = int(math.floor((th - carp[7]) / carp[1] + 0.5)) % int(carp[2])
            est = _read(table, i, j, h, gear, int(carp[3]), int(carp[4]), int(carp[2]), carp[10])
        else:
            est = carp[10]
    if est == math.inf:
        gi = min(max(int(np.rint((x - heur[6]) / heur[8])), 0), grid.shape[0] - 1)
        gj = min(max(int(np.rint((y - heur[7]) / heur[8])), 0), grid.shape[1] - 1)
        d = grid[gi, gj]
        est = max(0.0, d / OCTILE - 0.71 * heur[8]) if d < math.inf else math.inf
    rs = distance(x, y, th, heur[0], heur[1], heur[2], heur[3])
    return heur[4] * (est if est > rs else rs)


@njit(cache=True)
def _required(x, y, req):  # pragma: no cover - compiled
    """``common.clearance.required_gap`` at one pose; ``req``: (need, need near the start,
    start x, y, relief radius)."""
    if req[1] >= req[0]:
        return req[0]
    return req[1] if math.hypot(x - req[2], y - req[3]) < req[4] else req[0]


@njit(cache=True)
def in_goal_set(x, y, th, goalp, body, edges, spec):  # pragma: no cover - compiled
    """``SuccessCriteria``'s inside-the-slot and margin checks with ``goal_margin`` to spare,
    and the heading within ``goal_heading``. ``goalp``: (target heading, goal heading, no
    slot?, margin needed, position tolerance, target x, y); ``spec``: (corner or -1, edge)."""
    tau = 2 * math.pi
    herr = (th - goalp[0]) - tau * np.rint((th - goalp[0]) / tau)
    if abs(herr) > goalp[1]:
        return False
    if goalp[2] > 0:
        return goalp[4] - math.hypot(x - goalp[5], y - goalp[6]) >= goalp[3]
    c, s = math.cos(th), math.sin(th)
    d = np.empty((4, edges.shape[0]))
    for k in range(4):
        px, py = x + c * body[k, 0] - s * body[k, 1], y + s * body[k, 0] + c * body[k, 1]
        for e in range(edges.shape[0]):
            d[k, e] = edges[e, 0] * px + edges[e, 1] * py - edges[e, 2]
    if d.min() < -1e-12:
        return False
    for m in range(spec.shape[0]):
        v = d[spec[m, 0], spec[m, 1]] if spec[m, 0] >= 0 else d[:, spec[m, 1]].min()
        if v < goalp[3]:
            return False
    return True


@njit(cache=True)
def _clear_path(poses, gapargs, req, window, cap, in_window):  # pragma: no cover - compiled
    """Whether every pose keeps min(its required gap, ``cap``) (and, with ``in_window``,
    lies in the window)."""
    front, rear, hw, normals, pmin, pmax, verts = gapargs
    gap = _gaps(poses, front, rear, hw, normals, pmin, pmax, verts, False)
    for q in range(poses.shape[0]):
        x, y = poses[q, 0], poses[q, 1]
        if gap[q] < min(_required(x, y, req), cap):
            return False
        if in_window and not (window[0] <= x <= window[1] and window[2] <= y <= window[3]):
            return False
    return True


@njit(cache=True)
def analytic(x, y, th, goal, radius, sample_step, clearance, gapargs, req, window):  # pragma: no cover
    """A clear Reeds-Shepp path from (x, y, th) to ``goal`` (found?, poses): a coarse look at
    4 x ``sample_step`` first (a pose closer than ``clearance`` rules it out), then the fine
    check."""
    word, lengths, _ = solve(x, y, th, goal[0], goal[1], goal[2], radius)
    coarse = place_one(x, y, th, goal, word, lengths, radius, 4 * sample_step)
    if not _clear_path(coarse, gapargs, req, window, clearance, True):
        return False, coarse
    fine = place_one(x, y, th, goal, word, lengths, radius, sample_step)
    return _clear_path(fine, gapargs, req, window, math.inf, False), fine


@njit(cache=True)
def shot(x, y, th, goals, shotp, gapargs, req, window):  # pragma: no cover - compiled
    """A clear path into the goal set: to ``goals[0]`` (the target), else, from within
    ``shotp[3]`` of it (Reeds-Shepp), to the other goal poses, nearest first. ``shotp``:
    (turning radius, sample step, clearance, shot range)."""
    ok, tail = analytic(x, y, th, goals[0], shotp[0], shotp[1], shotp[2], gapargs, req, window)
    if ok or goals.shape[0] == 1:
        return ok, tail
    g0 = goals[0]
    if distance(x, y, th, g0[0], g0[1], g0[2], shotp[0]) > shotp[3]:
        return False, tail
    dist = np.empty(goals.shape[0] - 1)
    for m in range(1, goals.shape[0]):
        dist[m - 1] = distance(x, y, th, goals[m, 0], goals[m, 1], goals[m, 2], shotp[0])
    for m in np.argsort(dist, kind="mergesort"):
        ok, tail = analytic(x, y, th, goals[m + 1], shotp[0], shotp[1], shotp[2], gapargs, req, window)
        if ok:
            return ok, tail
    return False, tail


@njit(cache=True)
def rerank(hf, ht, hn, ctr, fl, it, heur, grid, table, carp):  # pragma: no cover - compiled
    """Re-rank the open list by a new estimate (``estimate``'s arguments): f = g + h, nodes
    where h is inf dropped, the ties kept."""
    n = 0
    for k in range(ctr[N_HEAP]):
        i = hn[k]
        h = estimate(fl[i, X], fl[i, Y], fl[i, TH], it[i, GEAR], heur, grid, table, carp)
        if h < math.inf:
            hf[n], ht[n], hn[n] = fl[i, G] + h, ht[k], i
            n += 1
    ctr[N_HEAP] = n
    for k in range(n // 2 - 1, -1, -1):
        _sift_down(hf, ht, hn, n, k)


@njit(cache=True)
def _expand(
    fl, it, hf, ht, hn, ctr, best_g, closed, i, flat, prims, costs, keyp, gapargs, req, window, heur, grid, table, carp,
):  # fmt: skip  # pragma: no cover - compiled
    """Node ``i``'s children: every primitive's samples checked in one batch, each cut short
    at its first sample that is not clear (kept where it still covers ``costs[6]`` samples),
    added where it reaches its cell cheaper than before and the estimate is finite."""
    offsets, gears, steers = prims
    n_p, n_m = offsets.shape[0], offsets.shape[1]
    front, rear, hw, normals, pmin, pmax, verts = gapargs
    x, y, th = fl[i, X], fl[i, Y], fl[i, TH]
    c, s = math.cos(th), math.sin(th)
    for p in range(n_p):
        for m in range(n_m):
            o = offsets[p, m]
            flat[p * n_m + m, 0] = x + c * o[0] - s * o[1]
            flat[p * n_m + m, 1] = y + s * o[0] + c * o[1]
            flat[p * n_m + m, 2] = th + o[2]
    gap = _gaps(flat, front, rear, hw, normals, pmin, pmax, verts, False)
    for p in range(n_p):
        k = 0  # samples clear before the first that is not (a primitive is cut short there)
        while k < n_m:
            q = flat[p * n_m + k]
            inside = window[0] <= q[0] <= window[1] and window[2] <= q[1] <= window[3]
            if not (gap[p * n_m + k] >= _required(q[0], q[1], req) and inside):
                break
            k += 1
        if k < costs[6]:
            continue
        end = flat[p * n_m + k - 1]
        child = cell_key(end[0], end[1], end[2], gap[p * n_m + k - 1], keyp)
        if child in closed:
            continue
        gear = gears[p]
        length = k * costs[5]
        g = fl[i, G] + length * (costs[0] if gear > 0 else costs[1])
        g += length * costs[2] * abs(steers[p])
        if it[i, GEAR] != 0:
            g += costs[3] * abs(steers[p] - fl[i, STEER])
            if gear != it[i, GEAR]:
                g += costs[4]
        if g >= best_g.get(child, math.inf):
            continue
        h = estimate(end[0], end[1], end[2], gear, heur, grid, table, carp)
        if not h < math.inf:
            continue
        best_g[child] = g
        n = ctr[N_NODES]
        fl[n, X], fl[n, Y], fl[n, TH], fl[n, G], fl[n, STEER] = end[0], end[1], end[2], g, steers[p]
        it[n, PARENT], it[n, GEAR], it[n, PRIM], it[n, KEPT], it[n, KEY] = i, gear, p, k, child
        ctr[N_NODES] = n + 1
        push(hf, ht, hn, ctr, g + h, n, n)


@njit(cache=True)
def run(
    fl, it, hf, ht, hn, ctr, best_g, closed, stops, backward, prims, costs, keyp,
    gapargs, req, window, heur, grid, table, carp, goalp, body, edges, spec, goals, shotp,
):  # fmt: skip  # pragma: no cover - compiled
    """Expand until one of the stops (``FOUND``, ``SHOT``, ``BUDGET``, ``NO_PATH``,
    ``SHARPEN``, ``SLICE``); (code, node, tail poses). ``stops``: (budget, slice end, the
    expansion that sharpens or -1, analytic every k-th). ``fl``: ``X`` ... ``STEER`` of each
    node; ``it``: ``PARENT`` ... ``KEY``. ``prims``: (offsets (P, m, 3), gears, steers);
    ``costs``: (forward and reverse per metre, steering per metre, per steering change, per
    switch, sample spacing, min samples)."""
    offsets = prims[0]
    flat = np.empty((offsets.shape[0] * offsets.shape[1], 3))
    empty = np.empty((0, 3))
    h_args = (heur, grid, table, carp)
    while ctr[N_HEAP] > 0:
        if ctr[N_EXP] >= stops[0]:
            return BUDGET, -1, empty
        if ctr[N_EXP] >= stops[1]:
            return SLICE, -1, empty
        if ctr[N_EXP] == stops[2]:
            return SHARPEN, -1, empty
        i = _pop(hf, ht, hn, ctr)
        key = it[i, KEY]
        if key in closed:
            continue
        closed[key] = 1
        ctr[N_CLOSED] += 1
        ctr[N_EXP] += 1
        x, y, th = fl[i, X], fl[i, Y], fl[i, TH]
        if not backward and i > 0 and in_goal_set(x, y, th, goalp, body, edges, spec):
            return FOUND, i, empty
        if (ctr[N_CLOSED] - 1) % stops[3] == 0:
            ok, tail = shot(x, y, th, goals, shotp, gapargs, req, window)
            if ok:
                return SHOT, i, tail
        _expand(fl, it, hf, ht, hn, ctr, best_g, closed, i, flat, prims, costs, keyp, gapargs, req, window, *h_args)
    return NO_PATH, -1, empty
