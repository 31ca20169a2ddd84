"""The multi-start seeds' closed-loop rollouts, compiled (numba).

``ShapeSeeds.seeds`` drives K seeds at once for N control steps: a speed and heading
controller on each seed's references, then one ``TruthModel.step_batch`` on the planning
model. On numpy arrays of a few dozen rows each step was mostly call overhead. This kernel
runs the same operations in the same order, seed by seed (tests/test_mirror_planner.py
compares its rollouts with the numpy loop bit for bit), so no seed, and no plan, changes.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from mirrorpark_env.vehicle import TruthModel


@njit(cache=True, nogil=True)
def _rollouts(xi0, v_ref, th_ref, lags, consts):  # pragma: no cover - compiled
    """(K, 1 + N n, 6) sub-step states of K seeds from ``xi0`` under the seeds' controller
    (the heading error's sign by the reference speed's: the gear)."""
    h, inv_l, v_min, v_max, dv_lag, a_min, a_max, max_steer, _ = consts  # TruthModel.step_constants
    K, N = v_ref.shape
    n = lags.shape[0]
    out = np.empty((K, 1 + N * n, 6))
    for k in range(K):
        x, y, th, v, a, d = xi0[0], xi0[1], xi0[2], xi0[3], xi0[4], xi0[5]
        for c in range(6):
            out[k, 0, c] = xi0[c]
        m = 1
        for i in range(N):
            a_cmd = min(max(3.0 * (v_ref[k, i] - v) - 0.5 * a, a_min), a_max)
            sgn = 1.0 if v_ref[k, i] >= 0 else -1.0
            d_cmd = min(max(2.5 * (th_ref[k, i] - th) * sgn, -max_steer), max_steer)
            a_cmd = min(max(a_cmd, a_min), a_max)  # step_batch clips again
            d_cmd = min(max(d_cmd, -max_steer), max_steer)
            da = a - a_cmd
            dd = d - d_cmd
            for j in range(n):
                v1 = v + a_cmd * h + da * lags[j, 0] * dv_lag
                v1 = min(max(v1, v_min), v_max)
                ds = 0.5 * (v + v1) * h
                dth = ds * math.tan(d_cmd + dd * lags[j, 2]) * inv_l
                half = 0.5 * dth
                chord = ds if abs(half) <= 1e-12 else ds * math.sin(half) / half
                x = x + chord * math.cos(th + half)
                y = y + chord * math.sin(th + half)
                th = th + dth
                v = v1
                out[k, m, 0] = x
                out[k, m, 1] = y
                out[k, m, 2] = th
                out[k, m, 3] = v
                out[k, m, 4] = a_cmd + da * lags[j, 1]
                out[k, m, 5] = d_cmd + dd * lags[j, 3]
                m += 1
            a = out[k, m - 1, 4]
            d = out[k, m - 1, 5]
    return out


class SeedRollouts:
    """The seeds' rollouts on one planning model, with its sub-step constants packed once."""

    def __init__(self, model: TruthModel) -> None:
        self.lags, self.consts = model.lag_factors(), model.step_constants()

    def __call__(self, xi0: np.ndarray, v_ref: np.ndarray, th_ref: np.ndarray) -> np.ndarray:
        """(K, 1 + N n, 6): each seed's sub-step states under its references (K, N)."""
        x = np.ascontiguousarray(np.asarray(xi0, float)[:6])
        return _rollouts(x, v_ref, th_ref, self.lags, self.consts)
