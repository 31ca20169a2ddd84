"""The truth model's step, compiled (numba): the one place its arithmetic is written.

``truth_step`` advances one control step; ``TruthModel.step`` and ``TruthModel.rollout``
call it, and so do the planners' compiled closed loops (the brake, the seeds' rollouts, the
tracker's loop), so every caller gets the environment's states bit for bit.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def truth_step(x, y, th, v, a0, d0, a_cmd, d_cmd, lags, consts, out, m):  # pragma: no cover - compiled
    """From (x, y, theta, v, a, delta) under the commands (clipped to the car's bounds):
    the sub-step states (x, y, theta, v, a, delta, distance driven in the sub-step) written
    to ``out[m : m + n]`` (its first columns, as many as it has, up to seven), and the state
    at the step's end. ``lags``, ``consts``: ``TruthModel.lag_factors``, ``step_constants``."""
    h, inv_l, v_min, v_max, dv_lag, a_min, a_max, max_steer = (
        consts[0], consts[1], consts[2], consts[3], consts[4], consts[5], consts[6], consts[7]
    )  # fmt: skip
    ac = min(max(a_cmd, a_min), a_max)  # clipped to the bounds
    dc = min(max(d_cmd, -max_steer), max_steer)
    da = a0 - ac
    dd = d0 - dc
    n = lags.shape[0]
    cols = out.shape[1]
    for k in range(n):
        v1 = v + ac * h + da * lags[k, 0] * dv_lag
        v1 = v_min if v1 < v_min else (v_max if v1 > v_max else v1)
        ds = 0.5 * (v + v1) * h
        dth = ds * math.tan(dc + dd * lags[k, 2]) * inv_l
        half = 0.5 * dth
        chord = ds * math.sin(half) / half if abs(half) > 1e-12 else ds
        x = x + chord * math.cos(th + half)
        y = y + chord * math.sin(th + half)
        th = th + dth
        v = v1
        row = (x, y, th, v, ac + da * lags[k, 1], dc + dd * lags[k, 3], abs(chord))
        for c in range(cols):
            out[m + k, c] = row[c]
    return x, y, th, v, ac + da * lags[n - 1, 1], dc + dd * lags[n - 1, 3]


@njit(cache=True, nogil=True)
def truth_rollout(state, commands, lags, consts):  # pragma: no cover - compiled
    """``truth_step`` chained over ``commands`` (M, 2) from ``state``: (M n, 7) sub-step rows."""
    n = lags.shape[0]
    out = np.empty((commands.shape[0] * n, 7))
    x, y, th, v, a, d = state[0], state[1], state[2], state[3], state[4], state[5]
    for i in range(commands.shape[0]):
        x, y, th, v, a, d = truth_step(x, y, th, v, a, d, commands[i, 0], commands[i, 1], lags, consts, out, i * n)
    return out
