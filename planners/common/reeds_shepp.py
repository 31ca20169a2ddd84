"""Reeds-Shepp paths: lengths and segments, compiled, and poses sampled along them.

ompl's ``ReedsSheppStateSpace`` gives the shortest path's length, but its Python binding
hides the path's segments (sampling n poses through ``interpolate`` solves the whole problem
n times) and cannot be called from a compiled search loop. This module solves it with the
formulas of Reeds and Shepp (1990) in the form and order of ompl's ``ReedsSheppStateSpace.cpp``
(same 18 words, same comparisons), compiled with numba: ``distance`` is ompl's distance bit
for bit, ``solve`` gives the segments, ``place`` places every pose of several paths in one
vectorised pass and ``place_one`` one path's inside a compiled loop. Tests check lengths and
poses against ompl.

Lengths are in units of the turning radius inside; the public functions take metres.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

L, S, R = 1, 0, -1  # segment kinds: turn left, straight, turn right
_WORDS = (
    (L, R, L), (R, L, R), (L, R, L, R), (R, L, R, L), (L, R, S, L), (R, L, S, R),
    (L, S, R, L), (R, S, L, R), (L, R, S, R), (R, L, S, L), (R, S, R, L), (L, S, L, R),
    (L, S, R), (R, S, L), (L, S, L), (R, S, R), (L, R, S, L, R), (R, L, S, R, L),
)  # fmt: skip  # ompl's reedsSheppPathType, in its order
# The same words as an array, 9 (none) past a word's end, for the compiled ``_place``.
WORD_KINDS = np.array([list(w) + [9] * (5 - len(w)) for w in _WORDS], np.int64)
_ZERO = 10 * np.finfo(float).eps
_PI = math.pi
_HALF_PI = 0.5 * math.pi
_BIG = np.finfo(float).max  # ompl's length of "no path yet"

# ompl's order of trial: (base word, on the backward problem?, first word index, weight of
# |u| in the length, the order of the lengths from (t, u, v)); the word groups (CSC, CCC,
# CCCC, CCSC, CCSCC) start at entries 0, 2, 4, 6 and 10, each comparing against the best
# length so far less its fixed quarter turns. Orders: 0 (t,u,v), 1 (v,u,t), 2 (t,u,-u,v),
# 3 (t,u,u,v), 4 (t,-H,u,v), 5 (v,u,-H,t), 6 (t,-H,u,-H,v).
_FAMILIES = np.array(
    [
        (0, 0, 14, 1.0, 0), (1, 0, 12, 1.0, 0), (2, 0, 0, 1.0, 0), (2, 1, 0, 1.0, 1),
        (3, 0, 2, 2.0, 2), (4, 0, 2, 2.0, 3), (5, 0, 4, 1.0, 4), (6, 0, 8, 1.0, 4),
        (5, 1, 6, 1.0, 5), (6, 1, 10, 1.0, 5), (7, 0, 16, 1.0, 6),
    ]
)  # fmt: skip
_GROUP_START = np.array([0.0, -1.0, 0.0, -1.0, 0.0, -1.0, 0.5 * _PI, -1.0, -1.0, -1.0, _PI])  # -1: no new group


@njit(cache=True)
def _mod2pi(x):  # pragma: no cover - compiled
    v = np.fmod(x, 2 * _PI)
    if v < -_PI:
        v += 2 * _PI
    elif v > _PI:
        v -= 2 * _PI
    return v


@njit(cache=True)
def _polar(x, y):  # pragma: no cover - compiled
    return math.sqrt(x * x + y * y), math.atan2(y, x)


@njit(cache=True)
def _tau_omega(u, v, xi, eta, phi):  # pragma: no cover - compiled
    delta = _mod2pi(u - v)
    a = math.sin(u) - math.sin(delta)
    b = math.cos(u) - math.cos(delta) - 1.0
    t1 = math.atan2(eta * a - xi * b, xi * a + eta * b)
    t2 = 2.0 * (math.cos(delta) - math.cos(v) - math.cos(u)) + 3.0
    tau = _mod2pi(t1 + _PI) if t2 < 0 else _mod2pi(t1)
    return tau, _mod2pi(tau - u + v - phi)


@njit(cache=True)
def _word(kind, x, y, phi):  # pragma: no cover - compiled
    """The base words of Reeds & Shepp (1990), section 8 (8.1, 8.2, 8.3, 8.7-8.11, as ompl
    corrects them): (applies?, t, u, v)."""
    t = u = v = 0.0
    if kind == 0:  # 8.1 LpSpLp
        u, t = _polar(x - math.sin(phi), y - 1.0 + math.cos(phi))
        if t >= -_ZERO:
            v = _mod2pi(phi - t)
            return v >= -_ZERO, t, u, v
    elif kind == 1:  # 8.2 LpSpRp
        u1, t1 = _polar(x + math.sin(phi), y - 1.0 - math.cos(phi))
        u1 = u1 * u1
        if u1 >= 4.0:
            u = math.sqrt(u1 - 4.0)
            t = _mod2pi(t1 + math.atan2(2.0, u))
            v = _mod2pi(t - phi)
            return t >= -_ZERO and v >= -_ZERO, t, u, v
    elif kind == 2:  # 8.3 LpRmL
        u1, theta = _polar(x - math.sin(phi), y - 1.0 + math.cos(phi))
        if u1 <= 4.0:
            u = -2.0 * math.asin(0.25 * u1)
            t = _mod2pi(theta + 0.5 * u + _PI)
            v = _mod2pi(phi - t + u)
            return t >= -_ZERO and u <= _ZERO, t, u, v
    elif kind == 3:  # 8.7 LpRupLumRm
        xi, eta = x + math.sin(phi), y - 1.0 - math.cos(phi)
        rho = 0.25 * (2.0 + math.sqrt(xi * xi + eta * eta))
        if rho <= 1.0:
            u = math.acos(rho)
            t, v = _tau_omega(u, -u, xi, eta, phi)
            return t >= -_ZERO and v <= _ZERO, t, u, v
    else:
        return _word_long(kind, x, y, phi)
    return False, t, u, v


@njit(cache=True)
def _word_long(kind, x, y, phi):  # pragma: no cover - compiled
    """``_word`` for the words of four and five segments (8.8-8.11)."""
    t = u = v = 0.0
    if kind == 4:  # 8.8 LpRumLumRp
        xi, eta = x + math.sin(phi), y - 1.0 - math.cos(phi)
        rho = (20.0 - xi * xi - eta * eta) / 16.0
        if rho >= 0 and rho <= 1:
            u = -math.acos(rho)
            if u >= -0.5 * _PI:
                t, v = _tau_omega(u, u, xi, eta, phi)
                return t >= -_ZERO and v >= -_ZERO, t, u, v
    elif kind == 5:  # 8.9 LpRmSmLm
        rho, theta = _polar(x - math.sin(phi), y - 1.0 + math.cos(phi))
        if rho >= 2.0:
            r = math.sqrt(rho * rho - 4.0)
            u = 2.0 - r
            t = _mod2pi(theta + math.atan2(r, -2.0))
            v = _mod2pi(phi - 0.5 * _PI - t)
            return t >= -_ZERO and u <= _ZERO and v <= _ZERO, t, u, v
    elif kind == 6:  # 8.10 LpRmSmRm
        xi, eta = x + math.sin(phi), y - 1.0 - math.cos(phi)
        rho, theta = _polar(-eta, xi)
        if rho >= 2.0:
            t = theta
            u = 2.0 - rho
            v = _mod2pi(t + 0.5 * _PI - phi)
            return t >= -_ZERO and u <= _ZERO and v <= _ZERO, t, u, v
    else:  # 8.11 LpRmSLmRp
        xi, eta = x + math.sin(phi), y - 1.0 - math.cos(phi)
        rho, _ = _polar(xi, eta)
        if rho >= 2.0:
            u = 4.0 - math.sqrt(rho * rho - 4.0)
            if u <= _ZERO:
                t = _mod2pi(math.atan2((4 - u) * xi - 2 * eta, -2 * xi + (u - 4) * eta))
                v = _mod2pi(t - phi)
                return t >= -_ZERO and v >= -_ZERO, t, u, v
    return False, t, u, v


@njit(cache=True)
def _solve(x, y, phi):  # pragma: no cover - compiled
    """(word index, its five signed lengths, total length) of the shortest path to (x, y,
    phi) in turning radii, from the origin heading along x: ompl's words in ompl's order,
    compared as ompl compares them (the first that is strictly shorter wins), so that the
    total is ompl's distance bit for bit (a test checks it)."""
    best = np.zeros(5)
    word, total = 0, _BIG
    c, s = math.cos(phi), math.sin(phi)
    xb, yb = x * c + y * s, x * s - y * c
    lmin = _BIG
    for f in range(_FAMILIES.shape[0]):
        kind, back, index, wu, order = (
            int(_FAMILIES[f, 0]), _FAMILIES[f, 1] > 0, int(_FAMILIES[f, 2]), _FAMILIES[f, 3], int(_FAMILIES[f, 4]),
        )  # fmt: skip
        if _GROUP_START[f] >= 0:
            lmin = total - _GROUP_START[f]
        bx, by = (xb, yb) if back else (x, y)
        for var in range(4):
            flip = var == 1 or var == 3  # timeflip: the lengths negated
            refl = var >= 2  # reflect: the word's mirror image
            xx = -bx if flip else bx
            yy = -by if refl else by
            pp = phi if flip == refl else -phi
            ok, t, u, v = _word(kind, xx, yy, pp)
            if not ok:
                continue
            length = abs(t) + wu * abs(u) + abs(v)
            if not lmin > length:
                continue
            lmin = length
            sg = -1.0 if flip else 1.0
            best[:] = 0.0
            if order == 0:
                best[0], best[1], best[2] = t, u, v
            elif order == 1:
                best[0], best[1], best[2] = v, u, t
            elif order == 2:
                best[0], best[1], best[2], best[3] = t, u, -u, v
            elif order == 3:
                best[0], best[1], best[2], best[3] = t, u, u, v
            elif order == 4:
                best[0], best[1], best[2], best[3] = t, -_HALF_PI, u, v
            elif order == 5:
                best[0], best[1], best[2], best[3] = v, u, -_HALF_PI, t
            else:
                best[0], best[1], best[2], best[3], best[4] = t, -_HALF_PI, u, -_HALF_PI, v
            best *= sg
            word = index + (1 if refl else 0)
            total = abs(best[0]) + abs(best[1]) + abs(best[2]) + abs(best[3]) + abs(best[4])
    return word, best, total


@njit(cache=True)
def _local(x0, y0, th0, x1, y1, th1, radius):  # pragma: no cover - compiled
    """The goal in the start's frame, in turning radii (ompl's ``reedsShepp(s1, s2)``)."""
    dx, dy = x1 - x0, y1 - y0
    c, s = math.cos(th0), math.sin(th0)
    return (c * dx + s * dy) / radius, (-s * dx + c * dy) / radius, th1 - th0


@njit(cache=True)
def distance(x0, y0, th0, x1, y1, th1, radius):  # pragma: no cover - compiled
    """Length [m] of the shortest Reeds-Shepp path between two poses: ompl's
    ``ReedsSheppStateSpace::distance``, compiled (for search loops)."""
    x, y, phi = _local(x0, y0, th0, x1, y1, th1, radius)
    return radius * _solve(x, y, phi)[2]


@njit(cache=True)
def solve(x0, y0, th0, x1, y1, th1, radius):  # pragma: no cover - compiled
    """(word index into ``WORD_KINDS``, five signed lengths [m], total [m]) of the shortest path."""
    x, y, phi = _local(x0, y0, th0, x1, y1, th1, radius)
    word, lengths, total = _solve(x, y, phi)
    return word, lengths * radius, radius * total


def path(start, goal, radius: float) -> tuple[tuple[int, ...], tuple[float, ...]]:
    """Shortest Reeds-Shepp path: segment kinds (L, S, R) and signed lengths [m] (negative:
    reversing), ompl's choice of word."""
    word, lengths, _ = solve(*(float(v) for v in start[:3]), *(float(v) for v in goal[:3]), float(radius))
    kinds = _WORDS[word]
    return kinds, tuple(float(v) for v in lengths[: len(kinds)])


def sample(start, goal, radius: float, step: float) -> np.ndarray:
    """Poses (n, 3) along the shortest path at equal spacing of at most ``step`` metres,
    ends included (the end exactly ``goal``)."""
    return place(start, [goal], [path(start, goal, radius)], radius, step)[0]


def place(start, goals, paths, radius: float, step: float) -> list[np.ndarray]:
    """Poses along ``paths`` (as ``path`` returns them) from ``start`` to each of ``goals``,
    at most ``step`` apart, in one vectorised pass (a path solved once can be sampled at
    several spacings)."""
    if not paths:
        return []
    rows, bounds = [], [0]  # per segment: global arc length at its start, sign, heading,
    offset = 0.0  # curvature, and x = A + P sin(th) + Qc d, y = B - P cos(th) + Qs d
    s_all = []
    x0, y0, th0 = (float(v) for v in start[:3])
    for kinds, segs in paths:
        x, y, th, s0 = x0, y0, th0, offset
        for kind, ln in zip(kinds, segs):
            sign = 1.0 if ln >= 0 else -1.0
            if kind == S:
                c, s = math.cos(th), math.sin(th)
                rows.append((s0, sign, th, 0.0, x, y, 0.0, c, s))
                x, y = x + ln * c, y + ln * s
            else:
                k = kind / radius
                rows.append((s0, sign, th, k, x - math.sin(th) / k, y + math.cos(th) / k, 1.0 / k, 0.0, 0.0))
                th1 = th + k * ln
                x, y, th = x + (math.sin(th1) - math.sin(th)) / k, y - (math.cos(th1) - math.cos(th)) / k, th1
            s0 += abs(ln)
        total = s0 - offset
        n = max(1, math.ceil(total / step))
        s_all.append((offset, total / n, n + 1))
        bounds.append(bounds[-1] + n + 1)
        offset = s0 + 1.0  # paths a metre apart on the common arc-length axis
    coef = np.array(rows)
    offsets, spacing, counts = (np.array(v) for v in zip(*s_all))
    first = np.asarray(bounds[:-1])
    s_all = np.repeat(offsets, counts) + (np.arange(bounds[-1]) - np.repeat(first, counts)) * np.repeat(spacing, counts)
    c = coef[np.searchsorted(coef[1:, 0], s_all, side="right")]
    d = (s_all - c[:, 0]) * c[:, 1]
    out = np.empty((len(s_all), 3))
    out[:, 2] = th = c[:, 2] + c[:, 3] * d
    out[:, 0] = c[:, 4] + c[:, 6] * np.sin(th) + c[:, 7] * d
    out[:, 1] = c[:, 5] - c[:, 6] * np.cos(th) + c[:, 8] * d
    out[first] = np.asarray(start, float)[:3]  # exact ends
    out[np.asarray(bounds[1:]) - 1] = np.asarray(goals, float)[:, :3]
    return np.split(out, bounds[1:-1])


@njit(cache=True)
def place_one(x0, y0, th0, goal, word, lengths, radius, step):  # pragma: no cover - compiled
    """``place`` for one path (``solve``'s word and lengths [m]) from (x0, y0, th0) to
    ``goal``, compiled, with ``place``'s arithmetic (a test compares them)."""
    kinds = WORD_KINDS[word]
    coef = np.zeros((5, 9))
    nseg = 0
    x, y, th, s0 = x0, y0, th0, 0.0
    for m in range(5):
        if kinds[m] == 9:
            break
        ln = lengths[m]
        sign = 1.0 if ln >= 0 else -1.0
        if kinds[m] == S:
            c, s = math.cos(th), math.sin(th)
            coef[m, 0], coef[m, 1], coef[m, 2], coef[m, 4], coef[m, 5], coef[m, 7], coef[m, 8] = (
                s0,
                sign,
                th,
                x,
                y,
                c,
                s,
            )
            x, y = x + ln * c, y + ln * s
        else:
            k = kinds[m] / radius
            coef[m, 0], coef[m, 1], coef[m, 2], coef[m, 3] = s0, sign, th, k
            coef[m, 4], coef[m, 5], coef[m, 6] = x - math.sin(th) / k, y + math.cos(th) / k, 1.0 / k
            th1 = th + k * ln
            x, y, th = x + (math.sin(th1) - math.sin(th)) / k, y - (math.cos(th1) - math.cos(th)) / k, th1
        s0 += abs(ln)
        nseg += 1
    n = max(1, math.ceil(s0 / step))
    spacing = s0 / n
    out = np.empty((n + 1, 3))
    seg = 0
    for i in range(n + 1):
        sa = 0.0 + i * spacing
        while seg + 1 < nseg and coef[seg + 1, 0] <= sa:
            seg += 1
        d = (sa - coef[seg, 0]) * coef[seg, 1]
        t = coef[seg, 2] + coef[seg, 3] * d
        out[i, 2] = t
        out[i, 0] = coef[seg, 4] + coef[seg, 6] * math.sin(t) + coef[seg, 7] * d
        out[i, 1] = coef[seg, 5] - coef[seg, 6] * math.cos(t) + coef[seg, 8] * d
    out[0, 0], out[0, 1], out[0, 2] = x0, y0, th0  # exact ends
    out[n, 0], out[n, 1], out[n, 2] = goal[0], goal[1], goal[2]
    return out


class ReedsShepp:
    """Reeds-Shepp paths for one turning radius: lengths and sampled poses."""

    def __init__(self, turning_radius: float):
        if not turning_radius > 0:
            raise ValueError(f"turning_radius: must be > 0 m, got {turning_radius}")
        self.radius = float(turning_radius)

    def distance(self, start, goal) -> float:
        """Length [m] of the shortest Reeds-Shepp path from ``start`` to ``goal`` (x, y, theta)."""
        return distance(*(float(v) for v in start[:3]), *(float(v) for v in goal[:3]), self.radius)

    def path(self, start, goal) -> tuple[tuple[int, ...], tuple[float, ...]]:
        """The shortest path's segment kinds and signed lengths [m], for ``place``."""
        return path(start, goal, self.radius)

    def place(self, start, goal, rs_path, step: float) -> np.ndarray:
        """Poses (n, 3) along ``rs_path`` (from ``path``), about ``step`` metres apart: one
        solution sampled at several spacings."""
        return place(start, [goal], [rs_path], self.radius, step)[0]

    def sample(self, start, goal, step: float) -> np.ndarray:
        """Poses (n, 3) along the shortest path, about ``step`` metres apart, ends included.

        Sampled from the path's segments: ompl's binding would solve the whole problem
        again for every pose.
        """
        return self.place(start, goal, self.path(start, goal), step)
