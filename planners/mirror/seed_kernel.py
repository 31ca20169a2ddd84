"""The multi-start seeds' references and closed-loop rollouts, compiled (numba).

``ShapeSeeds.seeds`` drives K seeds at once for N control steps: a speed and heading
controller on each seed's references, then one ``TruthModel.step`` per seed on the planning
model. On numpy arrays of a few dozen rows each step was mostly call overhead, and the
references, element by element in Python, cost about as much. These kernels run the same
operations in the same order, seed by seed (tests/test_mirror_planner.py compares the
references with the Python loop and the rollouts with the numpy loop, bit for bit), so no
seed, and no plan, changes.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from mirrorpark_env.truth_kernel import truth_step
from mirrorpark_env.vehicle import TruthModel


@njit(cache=True, nogil=True)
def _rollouts(xi0, v_ref, th_ref, lags, consts):  # pragma: no cover - compiled
    """(K, 1 + N n, 6) sub-step states of K seeds from ``xi0`` under the seeds' controller
    (the heading error's sign by the reference speed's: the gear)."""
    a_min, a_max, max_steer = consts[5], consts[6], consts[7]  # TruthModel.step_constants
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
            x, y, th, v, a, d = truth_step(x, y, th, v, a, d, a_cmd, d_cmd, lags, consts, out[k], m)
            m += n
    return out


@njit(cache=True, nogil=True)
def seed_references(
    dirs, switches, swings, N, dt, to_switch, to_target, d2, tth, th0, line_psi, fixed, parallel, first_dir
):  # pragma: no cover
    """(v_ref, th_ref), each (K, N): ``ShapeSeeds.seeds``' speed and heading references of K
    seeds, given each seed's direction, switch step (-1: none) and swing (NaN: none; inf:
    ``TURN``), in the operations and order of the Python loop they replaced (a test
    compares them bit for bit).

    Speed: a sine over each segment, sized to the distance it covers. Heading: for parallel
    parking an S-curve reversing to the mirror line then forward to the target heading; for
    reverse and angle parking forward toward the switch heading, then full lock back; with
    a swing, a heading excursion before the switch; with ``TURN``, toward the target
    heading in both segments (a 3-point turn)."""
    K = dirs.shape[0]
    v_ref = np.empty((K, N))
    th_ref = np.empty((K, N))
    psi = line_psi if fixed else 0.0
    for k in range(K):
        direction, sw, swing = dirs[k], switches[k], swings[k]
        has_switch = sw >= 0
        s = sw if has_switch else N
        d1 = to_switch if has_switch else to_target
        T1 = max(s, 1) * dt
        T2 = max(N - s, 1) * dt
        vc1 = min(1.5, d1 * math.pi / (2 * T1))
        vc2 = min(1.5, d2 * math.pi / (2 * T2))
        first = direction == first_dir
        for i in range(N):
            seg1 = (not has_switch) or i < s
            tau = (i + 1) / s if seg1 else (i + 1 - s) / max(N - s, 1)
            d = direction if seg1 else -direction
            v_ref[k, i] = d * (vc1 if seg1 else vc2) * math.sin(math.pi * min(tau, 1.0))
            # the heading reference
            if not has_switch:
                th = tth
            elif seg1 and swing == math.inf:
                th = tth
            elif seg1 and not math.isnan(swing):
                th = th0 + swing * math.sin(0.5 * math.pi * min(tau, 1.0))
            elif seg1:
                if parallel and first:
                    th = tth + 0.7 * math.sin(math.pi * tau) + psi * tau
                elif first:
                    th = th0 + (tth - line_psi - th0) * tau
                else:
                    th = th0
            elif first and fixed:
                th = tth + psi * (1 - tau)
            else:
                th = tth
            th_ref[k, i] = th
    return v_ref, th_ref


class SeedRollouts:
    """The seeds' rollouts on one planning model, with its sub-step constants packed once."""

    def __init__(self, model: TruthModel) -> None:
        self.lags, self.consts = model.lag_factors(), model.step_constants()

    def __call__(self, xi0: np.ndarray, v_ref: np.ndarray, th_ref: np.ndarray) -> np.ndarray:
        """(K, 1 + N n, 6): each seed's sub-step states under its references (K, N)."""
        x = np.ascontiguousarray(np.asarray(xi0, float)[:6])
        return _rollouts(x, v_ref, th_ref, self.lags, self.consts)
