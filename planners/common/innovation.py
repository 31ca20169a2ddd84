"""How far the world disagrees with the planner's model, measured from the car's own motion.

Each step the state measured last step is driven one step, with the command the policy sent,
through the told car's truth model (``TruthModel``), and compared with the state measured now:
the innovation. Where the world is the model (no perturbation) the prediction is the
measurement to the last bit, the innovation is exactly zero and nothing here changes what a
policy does. Measurement noise, actuator and model errors show in it. ``Innovation`` keeps its
running RMS in position (``position_rms``) and, once that is above ``noise_floor``, blends
prediction and measurement into a smoothed estimate of the state (a complementary filter).
The speed leans on the prediction more than the pose does: a brake's hold law acting on a
speed reading that drifts (odometry noise correlated over a second) holds the car at that
drift, and the truth model has no friction to stop such a creep (measured: docs/robustness.md).
"""

from __future__ import annotations

import math

import numpy as np

from mirrorpark_env.vehicle import TruthModel, VehicleParams, VehicleState, from_action

NOISE_FLOOR = 0.002  # [m] RMS position innovation above which the measurement counts as noisy


class Innovation:
    """The running disagreement between the measured states and the model's one-step predictions."""

    def __init__(
        self,
        params: VehicleParams,
        dt: float = 0.1,
        gain: float = 0.5,
        speed_gain: float = 0.1,
        noise_floor: float = NOISE_FLOOR,
    ):
        self.params = params
        self.model = TruthModel(params, dt)
        self.gain = gain  # the measurement's weight in the estimated pose, where it is noisy
        self.speed_gain = speed_gain  # ... and in the estimated speed
        self.noise_floor = noise_floor
        self._sum2 = 0.0
        self._n = 0
        self._last: np.ndarray | None = None  # the estimate of the last step
        self._command: tuple[float, float] | None = None

    @property
    def position_rms(self) -> float:
        """RMS of the position innovation so far [m] (per axis)."""
        return math.sqrt(self._sum2 / (2 * self._n)) if self._n else 0.0

    @property
    def noisy(self) -> bool:
        return self.position_rms > self.noise_floor

    def observe(self, measured: VehicleState) -> VehicleState:
        """Take this step's measurement; return the state to plan from: ``measured`` itself
        while the innovation stays below the noise floor, else the blend of the prediction
        from the last estimate and ``measured`` (pose with ``gain``, speed with ``speed_gain``;
        acceleration and steering as measured)."""
        z = measured.as_array()
        pred = None
        if self._last is not None and self._command is not None:
            pred = self.model.step(self._last, *self._command)[-1, :6]
            e = z[:2] - pred[:2]
            self._sum2 += float(e @ e)
            self._n += 1
        if pred is None or not self.noisy:
            self._last = z
            return measured
        est = z.copy()
        est[:3] = pred[:3] + self.gain * (z[:3] - pred[:3])
        est[3] = pred[3] + self.speed_gain * (z[3] - pred[3])
        self._last = est
        return VehicleState(*(float(q) for q in est))

    def sent(self, action) -> None:
        """The normalised action the policy sent this step (the next prediction's command)."""
        self._command = from_action(self.params, action)
