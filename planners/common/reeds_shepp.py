"""Reeds-Shepp paths: lengths from ompl (``ReedsShepp``), and segments for sampling with numpy.

ompl's ``ReedsSheppStateSpace`` gives the shortest path's length, but its Python binding
hides the path's segments: sampling n poses through ``interpolate`` solves the whole
problem n times (measured: most of the guide search's sampling time). This module solves
it once, with the formulas of Reeds and Shepp (1990) in the form and order of ompl's
``ReedsSheppStateSpace.cpp`` (same 18 words, same tie-breaking), and returns the segments;
``sample`` then places every pose in one vectorised pass. Tests check lengths and poses
against ompl.

Lengths are in units of the turning radius inside; ``path`` and ``sample`` take metres.
"""

from __future__ import annotations

import math

import numpy as np
from ompl import base as ob

L, S, R = 1, 0, -1  # segment kinds: turn left, straight, turn right
_WORDS = (
    (L, R, L), (R, L, R), (L, R, L, R), (R, L, R, L), (L, R, S, L), (R, L, S, R),
    (L, S, R, L), (R, S, L, R), (L, R, S, R), (R, L, S, L), (R, S, R, L), (L, S, L, R),
    (L, S, R), (R, S, L), (L, S, L), (R, S, R), (L, R, S, L, R), (R, L, S, R, L),
)  # fmt: skip  # ompl's reedsSheppPathType, in its order
_ZERO = 10 * np.finfo(float).eps
_HALF_PI = 0.5 * math.pi


def _mod2pi(x: float) -> float:
    v = math.fmod(x, 2 * math.pi)
    if v < -math.pi:
        v += 2 * math.pi
    elif v > math.pi:
        v -= 2 * math.pi
    return v


def _polar(x: float, y: float) -> tuple[float, float]:
    return math.hypot(x, y), math.atan2(y, x)


def _tau_omega(u, v, xi, eta, phi):
    delta = _mod2pi(u - v)
    a = math.sin(u) - math.sin(delta)
    b = math.cos(u) - math.cos(delta) - 1.0
    t1 = math.atan2(eta * a - xi * b, xi * a + eta * b)
    t2 = 2.0 * (math.cos(delta) - math.cos(v) - math.cos(u)) + 3.0
    tau = _mod2pi(t1 + math.pi) if t2 < 0 else _mod2pi(t1)
    return tau, _mod2pi(tau - u + v - phi)


# -- the base words (Reeds & Shepp, section 8); None when the word does not apply --------
def _lpsplp(x, y, phi):  # 8.1
    u, t = _polar(x - math.sin(phi), y - 1.0 + math.cos(phi))
    if t >= -_ZERO:
        v = _mod2pi(phi - t)
        if v >= -_ZERO:
            return t, u, v
    return None


def _lpsprp(x, y, phi):  # 8.2
    u1, t1 = _polar(x + math.sin(phi), y - 1.0 - math.cos(phi))
    u1 = u1 * u1
    if u1 >= 4.0:
        u = math.sqrt(u1 - 4.0)
        t = _mod2pi(t1 + math.atan2(2.0, u))
        v = _mod2pi(t - phi)
        if t >= -_ZERO and v >= -_ZERO:
            return t, u, v
    return None


def _lprml(x, y, phi):  # 8.3
    u1, theta = _polar(x - math.sin(phi), y - 1.0 + math.cos(phi))
    if u1 <= 4.0:
        u = -2.0 * math.asin(0.25 * u1)
        t = _mod2pi(theta + 0.5 * u + math.pi)
        v = _mod2pi(phi - t + u)
        if t >= -_ZERO and u <= _ZERO:
            return t, u, v
    return None


def _lprupluml(x, y, phi):  # 8.7 (LpRupLumRm)
    xi, eta = x + math.sin(phi), y - 1.0 - math.cos(phi)
    rho = 0.25 * (2.0 + math.hypot(xi, eta))
    if rho <= 1.0:
        u = math.acos(rho)
        t, v = _tau_omega(u, -u, xi, eta, phi)
        if t >= -_ZERO and v <= _ZERO:
            return t, u, v
    return None


def _lprumlump(x, y, phi):  # 8.8 (LpRumLumRp)
    xi, eta = x + math.sin(phi), y - 1.0 - math.cos(phi)
    rho = (20.0 - xi * xi - eta * eta) / 16.0
    if 0.0 <= rho <= 1.0:
        u = -math.acos(rho)
        if u >= -_HALF_PI:
            t, v = _tau_omega(u, u, xi, eta, phi)
            if t >= -_ZERO and v >= -_ZERO:
                return t, u, v
    return None


def _lprmsmlm(x, y, phi):  # 8.9
    rho, theta = _polar(x - math.sin(phi), y - 1.0 + math.cos(phi))
    if rho >= 2.0:
        r = math.sqrt(rho * rho - 4.0)
        u = 2.0 - r
        t = _mod2pi(theta + math.atan2(r, -2.0))
        v = _mod2pi(phi - _HALF_PI - t)
        if t >= -_ZERO and u <= _ZERO and v <= _ZERO:
            return t, u, v
    return None


def _lprmsmrm(x, y, phi):  # 8.10
    xi, eta = x + math.sin(phi), y - 1.0 - math.cos(phi)
    rho, theta = _polar(-eta, xi)
    if rho >= 2.0:
        t = theta
        u = 2.0 - rho
        v = _mod2pi(t + _HALF_PI - phi)
        if t >= -_ZERO and u <= _ZERO and v <= _ZERO:
            return t, u, v
    return None


def _lprmslmrp(x, y, phi):  # 8.11
    xi, eta = x + math.sin(phi), y - 1.0 - math.cos(phi)
    rho, _ = _polar(xi, eta)
    if rho >= 2.0:
        u = 4.0 - math.sqrt(rho * rho - 4.0)
        if u <= _ZERO:
            t = _mod2pi(math.atan2((4.0 - u) * xi - 2.0 * eta, -2.0 * xi + (u - 4.0) * eta))
            v = _mod2pi(t - phi)
            if t >= -_ZERO and v >= -_ZERO:
                return t, u, v
    return None


def _variants(x, y, phi):
    """The four symmetric problems: as is, time-flipped, reflected, both (the sign of the
    lengths and which of a word's pair applies follow from the variant)."""
    return ((x, y, phi, 1.0, 0), (-x, y, -phi, -1.0, 0), (x, -y, -phi, 1.0, 1), (-x, -y, phi, -1.0, 1))


# ompl's order of trial: (base word, on the backward problem?, first word index, weight of
# |u| in the length, fixed length, lengths from (t, u, v)). Families: CSC, CCC, CCCC, CCSC, CCSCC.
_H = _HALF_PI
_FAMILIES = (
    (_lpsplp, False, 14, 1.0, 0.0, lambda t, u, v: (t, u, v)),
    (_lpsprp, False, 12, 1.0, 0.0, lambda t, u, v: (t, u, v)),
    (_lprml, False, 0, 1.0, 0.0, lambda t, u, v: (t, u, v)),
    (_lprml, True, 0, 1.0, 0.0, lambda t, u, v: (v, u, t)),
    (_lprupluml, False, 2, 2.0, 0.0, lambda t, u, v: (t, u, -u, v)),
    (_lprumlump, False, 2, 2.0, 0.0, lambda t, u, v: (t, u, u, v)),
    (_lprmsmlm, False, 4, 1.0, _H, lambda t, u, v: (t, -_H, u, v)),
    (_lprmsmrm, False, 8, 1.0, _H, lambda t, u, v: (t, -_H, u, v)),
    (_lprmsmlm, True, 6, 1.0, _H, lambda t, u, v: (v, u, -_H, t)),
    (_lprmsmrm, True, 10, 1.0, _H, lambda t, u, v: (v, u, -_H, t)),
    (_lprmslmrp, False, 16, 1.0, 2 * _H, lambda t, u, v: (t, -_H, u, -_H, v)),
)


def _solve(x: float, y: float, phi: float, target: float | None):
    """(word index, lengths in radius units) of the shortest path: every word that applies,
    in ompl's order (ties go to the first); with the optimal length ``target`` known, the
    first word that attains it."""
    c, s = math.cos(phi), math.sin(phi)
    forward = _variants(x, y, phi)
    backward = _variants(x * c + y * s, x * s - y * c, phi)
    best, best_total = None, math.inf
    for word, back, index, wu, fixed, order in _FAMILIES:
        for xx, yy, pp, sg, refl in backward if back else forward:
            r = word(xx, yy, pp)
            if r is None:
                continue
            t, u, v = r
            total = abs(t) + wu * abs(u) + abs(v) + fixed
            if total < best_total:
                best, best_total = (index + refl, tuple(sg * w for w in order(t, u, v))), total
                if target is not None and abs(total - target) <= 1e-9 * (1.0 + target):
                    return best
    return best


def path(start, goal, radius: float, length: float | None = None) -> tuple[tuple[int, ...], tuple[float, ...]]:
    """Shortest Reeds-Shepp path: segment kinds (L, S, R) and signed lengths [m] (negative:
    reversing). Given the optimal ``length`` (ompl's distance), the first word in ompl's
    order that attains it is taken without trying the rest."""
    x0, y0, th0 = (float(v) for v in start[:3])
    dx, dy = (float(goal[0]) - x0) / radius, (float(goal[1]) - y0) / radius
    c, s = math.cos(th0), math.sin(th0)
    best = _solve(c * dx + s * dy, -s * dx + c * dy, float(goal[2]) - th0, None if length is None else length / radius)
    if best is None:  # cannot happen for finite input: some CSC or CCC word always applies
        raise ValueError(f"no Reeds-Shepp path from {tuple(start)} to {tuple(goal)}")
    return _WORDS[best[0]], tuple(radius * v for v in best[1])


def sample(start, goal, radius: float, step: float, length: float | None = None) -> np.ndarray:
    """Poses (n, 3) along the shortest path at equal spacing of at most ``step`` metres,
    ends included (the end exactly ``goal``). ``length``: as for ``path``."""
    return place(start, [goal], [path(start, goal, radius, length)], radius, step)[0]


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


class ReedsShepp:
    """Reeds-Shepp paths for one turning radius: lengths (ompl) and sampled poses."""

    def __init__(self, turning_radius: float):
        if not turning_radius > 0:
            raise ValueError(f"turning_radius: must be > 0 m, got {turning_radius}")
        self.radius = turning_radius
        self.space = ob.ReedsSheppStateSpace(turning_radius)
        self._a, self._b = self.space.allocState(), self.space.allocState()

    def _set(self, state, pose) -> None:
        state.setXY(float(pose[0]), float(pose[1]))
        state.setYaw(float(pose[2]))

    def distance(self, start, goal) -> float:
        """Length [m] of the shortest Reeds-Shepp path from ``start`` to ``goal`` (x, y, theta)."""
        self._set(self._a, start)
        self._set(self._b, goal)
        return self.space.distance(self._a, self._b)

    def path(self, start, goal) -> tuple[tuple[int, ...], tuple[float, ...]]:
        """The shortest path's segment kinds and signed lengths [m] (ompl's length picks the
        word), for ``place``."""
        return path(start, goal, self.radius, self.distance(start, goal))

    def place(self, start, goal, rs_path, step: float) -> np.ndarray:
        """Poses (n, 3) along ``rs_path`` (from ``path``), about ``step`` metres apart: one
        solution sampled at several spacings."""
        return place(start, [goal], [rs_path], self.radius, step)[0]

    def sample(self, start, goal, step: float) -> np.ndarray:
        """Poses (n, 3) along the shortest path, about ``step`` metres apart, ends included.

        Sampled from the path's segments (``reeds_shepp``): ompl's binding would solve the
        whole problem again for every pose. ompl's length picks the word.
        """
        return self.place(start, goal, self.path(start, goal), step)
