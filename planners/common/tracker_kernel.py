"""The path tracker's closed loop on a truth model, compiled (numba).

The mirror planner's guided seed drives the tracker on the planning model for a whole
horizon (N steps of ``PathTracker.command_at`` then ``TruthModel.step``) several times
per planning call; in Python that loop was about 4 % of an episode. This kernel runs the
same operations in the same order (tests/test_tracker.py compares its states, segments and
samples reached with the Python loop bit for bit), so no seed, and no plan, changes.

Two details keep it bit for bit: ``wrap_angle``'s IEEE remainder is computed exactly (as
CPython does), and squares go through ``pow`` with the exponent passed in at run time, as
Python's ``**`` does (a constant exponent lets LLVM turn ``pow(d, 2)`` into ``d * d``, which
rounds differently for about one value in a thousand).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from mirrorpark_env.truth_kernel import truth_step
from mirrorpark_env.vehicle import TruthModel

from .tracker import PathTracker

_STEER, _DRIVE, _STOP = 0, 1, 2


@njit(cache=True, nogil=True)
def _remainder(x, y):  # pragma: no cover - compiled
    """IEEE 754 remainder of x by y (``math.remainder``; CPython's algorithm, exact)."""
    absx = abs(x)
    absy = abs(y)
    m = np.fmod(absx, absy)
    c = absy - m
    if m < c:
        r = m
    elif m > c:
        r = -c
    else:
        r = m - 2.0 * np.fmod(0.5 * (absx - m), absy)
    return math.copysign(1.0, x) * r


@njit(cache=True, nogil=True)
def _kappa_at(s_arr, kappa, s, i0, i1):  # pragma: no cover - compiled
    """``PathTracker._kappa_at``: ``bisect_left`` over s_arr[i0 : i1 + 1]."""
    lo = i0
    hi = i1 + 1
    while lo < hi:
        mid = (lo + hi) // 2
        if s_arr[mid] < s:
            lo = mid + 1
        else:
            hi = mid
    return kappa[min(max(lo, i0 + 1), i1)]


@njit(cache=True, nogil=True)
def _hold(v, a, delta, a_min, a_max, tau_a, max_steer):  # pragma: no cover - compiled
    """``PathTracker._hold``: brake to a stand (``hold_accel``) while steering to ``delta``."""
    return max(a_min, min(a_max, -(v / tau_a + a))), max(-max_steer, min(max_steer, delta))


@njit(cache=True, nogil=True)
def _track(xi0, xs, ys, ths, s_arr, kappa, gears, seg_i0, seg_i1, tc, vc, lags, consts, steps, two):  # pragma: no cover
    """(1 + steps n, 6) sub-step states, and per control step the tracker's segment (-1 once
    done) and the path sample reached, from ``xi0`` under the tracker.

    ``tc``: cruise speed, accel, decel, preview, speed gain, steer tolerance; ``vc``: the
    tracker's car (a_min, a_max, max steer, wheelbase, tau_a, tau_delta); ``lags``,
    ``consts``: the truth model's (``lag_factors``, ``step_constants``); ``two``: 2.0.
    """
    cruise, accel, decel, preview, gain, steer_tol = tc[0], tc[1], tc[2], tc[3], tc[4], tc[5]
    a_min, a_max, max_steer, wheelbase, tau_a, tau_d = vc[0], vc[1], vc[2], vc[3], vc[4], vc[5]
    tau_a2 = tau_a**two
    preview2 = preview**two
    n = lags.shape[0]
    n_seg = seg_i0.shape[0]
    out = np.empty((1 + steps * n, 6))
    segs = np.empty(steps + 1, np.int64)
    reached = np.empty(steps + 1, np.int64)
    x, y, th, v, a, d = xi0[0], xi0[1], xi0[2], xi0[3], xi0[4], xi0[5]
    for c in range(6):
        out[0, c] = xi0[c]
    seg = 0
    j = seg_i0[0] if n_seg > 0 else 0
    phase = _STEER
    done = n_seg == 0
    segs[0] = 0
    reached[0] = 0
    row = 1
    for step in range(steps):
        # PathTracker.command_at(x, y, th, v, a, d); a segment's end continues into the next.
        while True:
            if done:
                a_cmd, d_cmd = _hold(v, a, d, a_min, a_max, tau_a, max_steer)
                break
            i0 = seg_i0[seg]
            i1 = seg_i1[seg]
            gear = gears[i1]
            if phase == _STEER:
                delta0 = max(
                    -max_steer, min(max_steer, math.atan(wheelbase * _kappa_at(s_arr, kappa, s_arr[i0] + 0.1, i0, i1)))
                )
                if abs(d - delta0) < steer_tol and abs(v) < 0.02:
                    phase = _DRIVE
                else:
                    a_cmd, d_cmd = _hold(v, a, delta0, a_min, a_max, tau_a, max_steer)
                    break
            hi = min(i1, j + 40)
            best = (xs[j] - x) ** two + (ys[j] - y) ** two
            for k in range(j + 1, hi + 1):
                d2 = (xs[k] - x) ** two + (ys[k] - y) ** two
                if d2 < best:
                    best = d2
                    j = k
            xr, yr, thr = xs[j], ys[j], ths[j]
            c = math.cos(thr)
            s = math.sin(thr)
            dx = x - xr
            dy = y - yr
            along = gear * (c * dx + s * dy)
            e_y = -s * dx + c * dy
            e_theta = _remainder(th - thr, math.tau)
            s_now = s_arr[j] + along
            remaining = s_arr[i1] - s_now
            speed = abs(v)
            if phase == _DRIVE:
                roll = 2.0 * tau_a * speed + tau_a2 * gear * a
                if remaining <= max(roll, 0.005):
                    phase = _STOP
            if phase == _STOP:
                if speed < 0.01 and abs(a) < 0.2:
                    if seg + 1 >= n_seg:
                        done = True
                    else:
                        seg += 1
                        j = seg_i0[seg]
                        phase = _STEER
                    continue
                a_cmd, d_cmd = _hold(v, a, d, a_min, a_max, tau_a, max_steer)
                break
            kappa_ref = _kappa_at(s_arr, kappa, s_now + speed * tau_d + 0.05, i0, i1)
            kap = kappa_ref - e_y / preview2 - gear * 2.0 * e_theta / preview
            d_cmd = max(-max_steer, min(max_steer, math.atan(wheelbase * kap)))
            room = max(remaining - 2.0 * tau_a * speed, 0.0)
            v_ref = min(cruise, math.sqrt(2.0 * decel * room), speed + accel * 0.5 + 0.1)
            acc = gain * (gear * v_ref - v)
            a_cmd = max(a_min, min(a_max, acc))
            break
        x, y, th, v, a, d = truth_step(x, y, th, v, a, d, a_cmd, d_cmd, lags, consts, out, row)  # TruthModel.step
        row += n
        segs[step + 1] = -1 if done else seg
        reached[step + 1] = j
    return out, segs, reached


class TrackedRollout:
    """``PathTracker`` driving one truth model for a number of control steps, compiled."""

    def __init__(self, model: TruthModel) -> None:
        self.lags, self.consts = model.lag_factors(), model.step_constants()

    def __call__(self, tracker: PathTracker, state, steps: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """From ``state`` (x, y, theta, v, a, delta) under a fresh ``tracker`` for ``steps``
        control steps: the sub-step states (1 + steps n, 6), and per step (``steps`` + 1, the
        start first) the tracker's segment (-1 once done) and the path sample reached."""
        if tracker.seg != 0 or tracker.phase != "steer":
            raise ValueError("tracker: must be fresh (segment 0, steering phase)")
        p, cfg, path = tracker.params, tracker.cfg, tracker.path
        poses = np.ascontiguousarray(path.poses[:, :3], dtype=float)
        segments = np.array(tracker.segments, np.int64).reshape(-1, 2)
        tc = np.array([cfg.cruise_speed, cfg.accel, cfg.decel, cfg.preview, cfg.speed_gain, cfg.steer_tolerance], float)
        vc = np.array([p.accel_min, p.accel_max, p.max_steer_rad, p.wheelbase, p.tau_accel_s, p.tau_steer_s], float)
        return _track(
            np.array([float(v) for v in state[:6]]),
            poses[:, 0].copy(),
            poses[:, 1].copy(),
            poses[:, 2].copy(),
            np.asarray(tracker.s, float),
            np.asarray(path.curvature, float),
            np.asarray(path.direction, float),
            segments[:, 0].copy(),
            segments[:, 1].copy(),
            tc,
            vc,
            self.lags,
            self.consts,
            int(steps),
            2.0,
        )
