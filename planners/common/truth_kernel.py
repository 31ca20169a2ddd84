"""One control step of the truth model, compiled (numba): ``TruthModel.step_rows`` for the
planners' compiled closed loops (the brake, the seeds' rollouts, the tracker's loop).

The same operations in the same order as ``step_rows``, so each loop that calls it gives
the states of chaining ``step_rows`` bit for bit (each loop's test checks it).
"""

from __future__ import annotations

import math

from numba import njit


@njit(cache=True, nogil=True)
def truth_step(x, y, th, v, a0, d0, a_cmd, d_cmd, lags, consts, out, m):  # pragma: no cover - compiled
    """From (x, y, theta, v, a, delta) under the commands (clipped to the car's bounds):
    the sub-step states (x, y, theta, v, a, delta) written to ``out[m : m + n]`` (its first
    columns, as many as it has, up to six), and the state at the step's end."""
    h, inv_l, v_min, v_max, dv_lag, a_min, a_max, max_steer = (
        consts[0], consts[1], consts[2], consts[3], consts[4], consts[5], consts[6], consts[7]
    )  # fmt: skip
    ac = min(max(a_cmd, a_min), a_max)  # TruthModel.clip_commands
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
        row = (x, y, th, v, ac + da * lags[k, 1], dc + dd * lags[k, 3])
        for c in range(cols):
            out[m + k, c] = row[c]
    return x, y, th, v, ac + da * lags[n - 1, 1], dc + dd * lags[n - 1, 3]
