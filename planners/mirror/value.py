"""A cost to go over the slot's free space: the terminal cost of a plan with one switch.

A plan holds one direction switch; most manoeuvres need more. Pulled toward the target
alone, a plan settles at the clear pose nearest the target and stays there (measured,
docs/mirror_planner.md). What the optimisation needs beyond its horizon is what an MPC
designer puts there: a cost to go. This module computes one by dynamic programming on a
lattice of poses, once per slot: V(x, y, theta) is the cheapest way to the target in
driven metres (reversing dearer, each direction switch priced), over moves of full lock
either way or straight, in both gears, that keep a small gap to every obstacle.

It is a value, not a path: nothing here says where a plan goes. The planner compares its
own optimised plans by plan cost plus V at their ends, and pulls each plan's end down V.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from pydantic import Field

from mirrorpark_env.config import StrictModel
from mirrorpark_env.scenario import ScenarioGeometry

from ..common.clearance import gaps
from ..common.path import arc
from ..common.slot_cache import SlotCache


class ValueConfig(StrictModel):
    """Lattice and prices of the cost to go (lengths in m)."""

    xy_resolution: float = Field(0.15, gt=0.01, le=2)
    headings: int = Field(72, ge=8, le=360)  # heading cells in a full turn
    steer_fraction: float = Field(0.9, gt=0, le=1)  # moves turn at this fraction of the curvature limit
    clearance: float = Field(0.05, ge=0, le=1)  # gap every lattice pose and move midpoint keeps
    reverse_cost: float = Field(0.5, ge=0)  # extra per metre reversed
    switch_cost: float = Field(3.0, ge=0)  # per direction switch
    margin: float = Field(10.0, gt=0, le=50)  # [m] along the road beyond the slot
    # Near the target, where the cells are too coarse to rank poses: the pose error priced
    # in metres of driving (per m, per rad), at most this much above V.
    finish_position: float = Field(50.0, ge=0)
    finish_heading: float = Field(30.0, ge=0)
    finish_cap: float = Field(20.0, ge=0)


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
def _dijkstra(valid, mid_ok, off, dih, cost, gear, nx, ny, nh, target, switch_cost):  # pragma: no cover
    """Backward Dijkstra from ``target`` over nodes (state, gear the car arrived in).

    valid: (S,) states; mid_ok: (S, P) moves clear at their midpoint; off: (nh, P, 2) cell
    offsets of each move by heading; dih: (P,) heading-cell change; cost: (nh, P) by the
    heading it starts from; gear: (P,).
    Returns V (S, 2): cost to go after arriving in gear -1 (col 0) or +1 (col 1), and the
    largest heap the search held (past ``cap`` entries would be lost: the caller checks).
    """
    S = nx * ny * nh
    V = np.full((S, 2), np.inf)
    cap = S + 16
    hk = np.empty(cap)
    hv = np.empty(cap, dtype=np.int64)
    n, peak = 0, 0
    for gi in range(2):
        V[target, gi] = 0.0
        n = _push(hk, hv, n, 0.0, target * 2 + gi)
    while n > 0:
        key, node, n = _pop(hk, hv, n)
        s2, g2 = node // 2, node % 2
        if key > V[s2, g2]:
            continue  # a stale entry
        ih2, iy2, ix2 = s2 % nh, (s2 // nh) % ny, s2 // (nh * ny)
        for p in range(cost.shape[1]):
            if (gear[p] > 0) != (g2 == 1):
                continue  # p arrives at s2 in its own gear
            ih = (ih2 - dih[p]) % nh
            ix, iy = ix2 - off[ih, p, 0], iy2 - off[ih, p, 1]
            if ix < 0 or ix >= nx or iy < 0 or iy >= ny:
                continue
            s = (ix * ny + iy) * nh + ih
            if not valid[s] or not mid_ok[s, p]:
                continue
            for gp in range(2):  # the gear the car arrived at s in: a switch if not p's
                k = key + cost[ih, p] + (switch_cost if gp != g2 else 0.0)
                if k < V[s, gp]:
                    V[s, gp] = k
                    if n >= cap:
                        peak = cap + 1
                        continue
                    n = _push(hk, hv, n, k, s * 2 + gp)
                    peak = max(peak, n)
    return V, peak


class CostToGo:
    """V over a lattice aligned on the target (the target is a lattice pose, V = 0 there)."""

    def __init__(self, geometry: ScenarioGeometry, config: ValueConfig | None = None):
        self.g = geometry
        self.cfg = cfg = config or ValueConfig()
        p = geometry.vehicle
        res, nh = cfg.xy_resolution, cfg.headings
        self.dth = 2 * math.pi / nh
        radius = p.r_min / cfg.steer_fraction
        self.step = radius * self.dth  # a full-lock move turns one heading cell
        tx, ty, tth = (float(v) for v in geometry.target)
        self.origin = (tx, ty, tth)
        slot = np.asarray(geometry.slot, float)
        bx0, bx1, by0, by1 = geometry.bounds
        x0 = max(bx0, slot[:, 0].min() - cfg.margin)
        x1 = min(bx1, slot[:, 0].max() + cfg.margin)
        y0 = max(by0, slot[:, 1].min() - 1.0)
        y1 = min(by1, geometry.road_width + 1.0)
        self.i0 = math.floor((x0 - tx) / res)
        self.j0 = math.floor((y0 - ty) / res)
        self.nx = math.floor((x1 - tx) / res) - self.i0 + 1
        self.ny = math.floor((y1 - ty) / res) - self.j0 + 1
        self.nh = nh
        xs = tx + (self.i0 + np.arange(self.nx)) * res
        ys = ty + (self.j0 + np.arange(self.ny)) * res
        ths = tth + np.arange(nh) * self.dth
        X, Y, T = np.meshgrid(xs, ys, ths, indexing="ij")
        poses = np.stack([X.ravel(), Y.ravel(), T.ravel()], axis=1)
        checker = geometry.checker
        valid = gaps(checker, poses, all_axes=True) >= cfg.clearance
        # Moves: (gear, curvature) with the same offsets from every cell of a heading.
        k = 1.0 / radius
        moves = [(gr, kk) for gr in (1.0, -1.0) for kk in (0.0, k, -k)]  # straight first: it wins ties
        P = len(moves)
        off = np.zeros((nh, P, 2), np.int64)
        dih = np.zeros(P, np.int64)
        chord = np.zeros((nh, P))  # the snapped move's length
        cost = np.zeros((nh, P))  # ... reversing dearer: V is a length
        gear = np.zeros(P, np.int64)
        mid_ok = np.zeros((len(poses), P), np.bool_)
        for m, (gr, kk) in enumerate(moves):
            dih[m] = int(round(gr * kk * self.step / self.dth))
            gear[m] = int(gr)
            for h in range(nh):
                end = arc((0.0, 0.0, ths[h]), kk, np.array([gr * self.step]))[0]
                off[h, m] = (round(end[0] / res), round(end[1] / res))
                chord[h, m] = max(res * math.hypot(*off[h, m]), 0.5 * res)
                cost[h, m] = chord[h, m] * (1.0 + (cfg.reverse_cost if gr < 0 else 0.0))
            mids = np.empty_like(poses)
            for h in range(nh):
                d = arc((0.0, 0.0, ths[h]), kk, np.array([0.5 * gr * self.step]))[0]
                sel = slice(h, None, nh)
                mids[sel, 0] = poses[sel, 0] + d[0]
                mids[sel, 1] = poses[sel, 1] + d[1]
                mids[sel, 2] = d[2]
            todo = np.flatnonzero(valid)
            mid_ok[todo, m] = gaps(checker, mids[todo], all_axes=True) >= cfg.clearance
        target = ((-self.i0) * self.ny + (-self.j0)) * nh
        valid[target] = True  # the target itself (the planner's exact checks judge it)
        self.valid, self.mid_ok, self.off, self.dih, self.cost, self.gear = valid, mid_ok, off, dih, cost, gear
        self.chord = chord
        self.target_state = target
        self.V, peak = _dijkstra(valid, mid_ok, off, dih, cost, gear, self.nx, self.ny, nh, target, cfg.switch_cost)
        if peak > valid.size + 16:  # never seen; a wrong V would be silent, so say so
            raise RuntimeError(f"CostToGo: the search's heap overflowed ({peak} entries)")
        self.heap_peak = int(peak)

    def index(self, poses: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Nearest lattice cell (i, j, h) of each pose, and whether it lies in the lattice."""
        poses = np.atleast_2d(np.asarray(poses, float))
        res = self.cfg.xy_resolution
        tx, ty, tth = self.origin
        i = np.rint((poses[:, 0] - tx) / res).astype(np.int64) - self.i0
        j = np.rint((poses[:, 1] - ty) / res).astype(np.int64) - self.j0
        h = np.rint((poses[:, 2] - tth) / self.dth).astype(np.int64) % self.nh
        inside = (i >= 0) & (i < self.nx) & (j >= 0) & (j < self.ny)
        return np.clip(i, 0, self.nx - 1), np.clip(j, 0, self.ny - 1), h, inside

    def pose(self, i: int, j: int, h: int) -> np.ndarray:
        res = self.cfg.xy_resolution
        tx, ty, tth = self.origin
        return np.array([tx + (self.i0 + i) * res, ty + (self.j0 + j) * res, tth + h * self.dth])

    # -- lookups used by the planner ------------------------------------------------------
    def _state(self, i, j, h) -> int:
        return int((i * self.ny + j) * self.nh + h)

    def at(self, pose, gear: int | None = None) -> tuple[float, int]:
        """(V, state) at ``pose`` having arrived in ``gear`` (+1, -1; None: at rest, either):
        the lowest over the lattice neighbours (one cell each way)."""
        i, j, h, inside = self.index(np.asarray(pose, float)[None, :3])
        if not inside[0]:
            return math.inf, -1
        cols = [0, 1] if gear is None else [1 if gear > 0 else 0]
        s0 = self._state(int(i[0]), int(j[0]), int(h[0]))
        v0 = min(self.V[s0, c] for c in cols)
        if math.isfinite(v0):  # the pose's own cell; its neighbours only where that is blocked
            return v0, s0
        best, arg = math.inf, -1
        for di in (0, -1, 1):
            for dj in (0, -1, 1):
                for dh in (0, -1, 1):
                    ii, jj = int(i[0]) + di, int(j[0]) + dj
                    if not (0 <= ii < self.nx and 0 <= jj < self.ny):
                        continue
                    s = self._state(ii, jj, (int(h[0]) + dh) % self.nh)
                    v = min(self.V[s, c] for c in cols)
                    if v < best:
                        best, arg = v, s
        return best, arg

    def _cell(self, s: int) -> tuple[int, int, int]:
        return s // (self.nh * self.ny), (s // self.nh) % self.ny, s % self.nh

    def _best_move(self, s: int, g: int, only: int | None = None) -> tuple[float, int, int]:
        """V's choice at state ``s`` arrived in gear index ``g`` (0: reverse, 1: forward):
        (value, next state, move), moves restricted to gear index ``only`` if given."""
        ix, iy, ih = self._cell(s)
        best, nxt, mv = math.inf, -1, -1
        for p in range(self.cost.shape[1]):
            gp = 1 if self.gear[p] > 0 else 0
            if only is not None and gp != only:
                continue
            ii, jj = ix + self.off[ih, p, 0], iy + self.off[ih, p, 1]
            if not (0 <= ii < self.nx and 0 <= jj < self.ny) or not self.mid_ok[s, p]:
                continue
            s2 = self._state(ii, jj, (ih + self.dih[p]) % self.nh)
            if not self.valid[s2]:
                continue
            val = self.cost[ih, p] + (self.cfg.switch_cost if gp != g else 0.0) + self.V[s2, gp]
            if val < best:
                best, nxt, mv = val, s2, p
        return best, nxt, mv

    def descend(self, pose, gear: int, max_length: float = math.inf) -> np.ndarray | None:
        """The lattice pose where V's cheapest way on from ``pose`` (arrived in ``gear``)
        first changes gear, reaches the target or has run ``max_length`` metres. None where
        V is infinite."""
        v, s = self.at(pose, gear)
        if not math.isfinite(v):
            return None
        g = 1 if gear > 0 else 0
        length = 0.0
        while s != self.target_state:
            best, nxt, mv = self._best_move(s, g)
            if nxt < 0 or (1 if self.gear[mv] > 0 else 0) != g:
                break
            length += self.chord[s % self.nh, mv]
            if length > max_length + 1e-9:
                break
            s = nxt
        return self.pose(*self._cell(s))

    def policy_path(
        self, pose, first_gear: int, changes: int, max_length: float, sample_step: float = 0.1
    ) -> np.ndarray | None:
        """Poses along V's cheapest way on from ``pose``, first in ``first_gear``, through at
        most ``changes`` gear changes and ``max_length`` metres: its moves replayed from the
        pose itself (a warm start for a plan; None where V is infinite)."""
        v, s = self.at(pose, None)
        if not math.isfinite(v):
            return None
        g = 1 if first_gear > 0 else 0
        out = [np.asarray(pose, float)[None, :3]]
        m = max(1, round(self.step / sample_step))
        length, n_changes, first = 0.0, 0, True
        while length + 1e-9 < max_length and s != self.target_state:
            best, nxt, mv = self._best_move(s, g, g if first else None)
            if nxt < 0 or not math.isfinite(best):
                break
            gp = 1 if self.gear[mv] > 0 else 0
            if gp != g and not first:
                n_changes += 1
                if n_changes > changes:
                    break
            first, g = False, gp
            kappa = self.dih[mv] * self.dth / self.step * self.gear[mv]
            seg = arc(out[-1][-1], kappa, self.gear[mv] * self.step * np.arange(1, m + 1) / m)
            out.append(seg)
            length += self.chord[s % self.nh, mv]
            s = nxt
        poses = np.concatenate(out)
        return poses if len(poses) > 1 else None


_CACHE: SlotCache[CostToGo] = SlotCache(16)


def cost_to_go(geometry: ScenarioGeometry, config: ValueConfig | None = None) -> CostToGo:
    """A ``CostToGo`` shared by the episodes of one process in the same slot."""
    cfg = config or ValueConfig()
    return _CACHE.get(geometry, cfg.model_dump_json(), lambda: CostToGo(geometry, cfg))
