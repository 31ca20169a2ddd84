"""Theorem 2's maps between the real frame and the planned (mirror) frame, as pure functions.

If the car stands at the switch point S at step s and from then on executes the negated
commands (Eq. 42), its real pose is the planned pose reflected through S,
real = (2 S - p, theta), and its lag states (v, a, delta) are the planned ones negated.
States are rows (x, y, theta, v, a, delta); a rollout at ``substeps`` per control step
holds the control steps in every ``substeps``-th row.
"""

from __future__ import annotations

import math

import numpy as np

from mirrorpark_env.vehicle import VehicleParams

from .plans import Candidate

XI_X, XI_Y, XI_TH, XI_V, XI_A, XI_D = range(6)
FLIP = np.diag([1.0, 1.0, 1.0, -1.0, -1.0, -1.0])  # planned <- real lag states at the switch


def real_commands(u_planned: np.ndarray, cand: Candidate) -> np.ndarray:
    """The commands the real car executes: the planned ones, negated from the switch on (Eq. 42)."""
    u = u_planned.copy()
    if cand.switch is not None:
        u[cand.switch :] *= -1.0
    return u


def real_pose_coeffs(i: int, cand: Candidate) -> tuple[float, float]:
    """(sign, twice) with real p_i = sign * p_i + twice * S at control step i."""
    if cand.switch is not None and i > cand.switch:
        return -1.0, 2.0
    return 1.0, 0.0


def to_planned(real_half: np.ndarray, cand: Candidate, substeps: int) -> np.ndarray:
    """Planned (mirror-frame) states at the control steps of a real rollout: the
    reflection through the switch point after the switch."""
    real = real_half[::substeps]
    pl = real.copy()
    s = cand.switch
    if s is not None:
        S = real[s, :2]
        pl[s + 1 :, :2] = 2 * S - real[s + 1 :, :2]
        pl[s + 1 :, 3:] *= -1.0
    return pl


def planned_controls(
    real_half: np.ndarray, cand: Candidate, params: VehicleParams, dt: float, substeps: int
) -> np.ndarray:
    """Commands that reproduce a rollout's lag states, in the planned frame."""
    pl = to_planned(real_half, cand, substeps)
    ea, ed = math.exp(-dt / params.tau_accel_s), math.exp(-dt / params.tau_steer_s)
    a0, a1 = pl[:-1, XI_A], pl[1:, XI_A]
    d0, d1 = pl[:-1, XI_D], pl[1:, XI_D]
    if cand.switch is not None:  # step s starts from the flipped lag states
        a0, d0 = a0.copy(), d0.copy()
        a0[cand.switch] *= -1
        d0[cand.switch] *= -1
    return np.stack([(a1 - ea * a0) / (1 - ea), (d1 - ed * d0) / (1 - ed)], axis=1)
