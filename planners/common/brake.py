"""The brake on the truth model, compiled (numba): the safety filter's look-ahead (one step
of a command, then the brake until the car stands) and the mirror planner's brake tail
after a plan (a fixed number of brake steps).

Both ran ``TruthModel.step`` one Python float at a time: in a profile of ``rl-shield``
on the smoke sample, 56 % of a decision's time was the filter. This kernel runs the same
sub-steps with the same operations in the same order (tests/test_shield.py and
tests/test_mirror_planner.py compare its poses with chained ``TruthModel.step`` bit for bit), so
no verdict changes.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from mirrorpark_env.truth_kernel import truth_step
from mirrorpark_env.vehicle import TruthModel


@njit(cache=True, nogil=True)
def _brake_poses(state, a_cmd, d_cmd, brake_steps, lags, consts, lead, stop):  # pragma: no cover - compiled
    """Rear-axle poses (m, 3) at every sub-step of one step of (a_cmd, d_cmd) (``lead``;
    else of the brake), then of the brake (steering held) for ``brake_steps`` control steps,
    or until the car stands (``stop``)."""
    a_min, a_max, tau_a = consts[5], consts[6], consts[8]  # TruthModel.step_constants
    n = lags.shape[0]
    out = np.empty(((brake_steps + 1) * n, 3))
    x, y, th, v, a0, d0 = state[0], state[1], state[2], state[3], state[4], state[5]
    m = 0
    for step in range(brake_steps + 1):
        if step > 0 and stop and abs(v) < 1e-3 and abs(a0) < 1e-2:
            break
        if step > 0 or not lead:
            a_cmd = max(a_min, min(a_max, -(v / tau_a + a0)))  # tracker.hold_accel
            d_cmd = d0
        x, y, th, v, a0, d0 = truth_step(x, y, th, v, a0, d0, a_cmd, d_cmd, lags, consts, out, m)
        m += n
    return out[:m]


class BrakeRollout:
    """The brake on one truth model, with its sub-step constants packed once."""

    def __init__(self, model: TruthModel) -> None:
        self.lags, self.consts = model.lag_factors(), model.step_constants()

    def __call__(self, state, a_cmd: float, d_cmd: float, brake_steps: int) -> np.ndarray:
        """Poses (m, 3) of one step of the commands from ``state`` (x, y, theta, v, a,
        delta), then of ``tracker.hold_accel`` with the steering held, until the speed and
        acceleration die away (|v| < 1 mm/s, |a| < 1 cm/s^2) or ``brake_steps`` steps pass."""
        s = np.asarray(state, dtype=float)[:6]
        return _brake_poses(s, float(a_cmd), float(d_cmd), int(brake_steps), self.lags, self.consts, True, True)

    def tail(self, state, steps: int) -> np.ndarray:
        """Poses (steps * n, 3) of ``steps`` control steps of the brake from ``state``, standing
        or not (a car that nearly stands creeps on, and its creep is part of the check)."""
        s = np.asarray(state, dtype=float)[:6]
        return _brake_poses(s, 0.0, 0.0, int(steps) - 1, self.lags, self.consts, False, False)


def clearest_stop(geometry, state, steps: int = 40) -> float:
    """The steering command to hold while braking to a stand (``tracker.emergency_accel``) that
    keeps the footprint farthest from ``geometry``'s obstacles: the wheels as they are,
    straight, or at either lock. For a scene that changed under a moving car (a late
    obstacle), where holding a turn may swing a corner into what appeared."""
    from .clearance import gaps
    from .tracker import emergency_accel

    p = geometry.vehicle
    model = TruthModel(p)
    s0 = np.asarray(state, dtype=float)[:6]
    best, best_gap = float(s0[5]), -np.inf
    for d_cmd in (float(s0[5]), 0.0, p.max_steer_rad, -p.max_steer_rad):
        s, poses = s0, []
        for _ in range(steps):
            rows = model.step(s, emergency_accel(p, s[3], s[4]), d_cmd)
            poses.append(rows[:, :3])
            s = rows[-1, :6]
            if abs(s[3]) < 1e-3 and abs(s[4]) < 1e-2:
                break
        gap = float(gaps(geometry.checker, np.concatenate(poses), all_axes=True).min())
        if gap > best_gap + 1e-9:
            best, best_gap = d_cmd, gap
    return best
