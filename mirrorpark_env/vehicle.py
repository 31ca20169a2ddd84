"""The paper's vehicle: parameters, footprint and the truth model.

Truth model: the rear-axle kinematic bicycle of Eq. (10) with the first-order actuator
lags of Eqs. (28)-(29). Over one control step the commands are held; the lags are
integrated exactly (they are linear), and the pose is advanced over sub-steps by an
exact circular arc using the sub-step's mean speed and mid-step steering angle, which is
exact whenever speed and steering are constant.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from functools import cache

import numpy as np

from .config import VehicleConfig, default_vehicle
from .truth_kernel import truth_rollout, truth_step

# Body-frame corners (rear-axle origin, x forward, y left) in this fixed order.
CORNER_NAMES = ("front_left", "front_right", "rear_right", "rear_left")


@dataclass(frozen=True)
class VehicleParams:
    """Geometry and limits of the car (Table II); SI units, radians. The fields are
    ``VehicleConfig``'s (``configs/vehicle.yaml``'s names), one name each."""

    wheelbase: float
    rear_overhang: float
    front_length: float
    width: float
    max_steer_rad: float
    accel_min: float
    accel_max: float
    speed_min: float
    speed_max: float
    tau_accel_s: float
    tau_steer_s: float

    @classmethod
    def from_config(cls, cfg: VehicleConfig) -> VehicleParams:
        return cls(**cfg.model_dump())

    def as_config(self) -> dict[str, float]:
        """The fields of ``VehicleConfig``: the inverse of ``from_config``."""
        return dataclasses.asdict(self)

    @classmethod
    def table_ii(cls) -> VehicleParams:
        """The paper's car as shipped in ``configs/vehicle.yaml`` (read once)."""
        return _table_ii()

    @property
    def length(self) -> float:
        return self.rear_overhang + self.front_length

    @property
    def r_min(self) -> float:
        """Minimum turning radius of the rear-axle centre."""
        return self.wheelbase / math.tan(self.max_steer_rad)

    @property
    def center_offset(self) -> float:
        """Distance from the rear axle forward to the body centre."""
        return 0.5 * (self.front_length - self.rear_overhang)

    def body_corners(self) -> np.ndarray:
        """Corners in the body frame, (4, 2), ordered as ``CORNER_NAMES``."""
        h = 0.5 * self.width
        return np.array(
            [
                [self.front_length, h],
                [self.front_length, -h],
                [-self.rear_overhang, -h],
                [-self.rear_overhang, h],
            ]
        )


def footprint(params: VehicleParams, x, y, theta) -> np.ndarray:
    """World corners of the footprint for one or many rear-axle poses: (..., 4, 2)."""
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    theta = np.asarray(theta, dtype=float)
    c, s = np.cos(theta)[..., None], np.sin(theta)[..., None]
    b = params.body_corners()
    bx, by = b[:, 0], b[:, 1]
    wx = x[..., None] + c * bx - s * by
    wy = y[..., None] + s * bx + c * by
    return np.stack([wx, wy], axis=-1)


@dataclass(frozen=True)
class VehicleState:
    """Rear-axle pose, speed, actual acceleration and front-wheel angle."""

    x: float
    y: float
    theta: float
    v: float = 0.0
    a: float = 0.0
    delta: float = 0.0

    def as_array(self) -> np.ndarray:
        return np.array([self.x, self.y, self.theta, self.v, self.a, self.delta])


class TruthModel:
    """Propagates the truth model over one control step with constant commands.

    Holds the per-step constants so that ``step`` does no repeated set-up work; the step
    itself is ``truth_kernel.truth_step``, compiled, the one place its arithmetic is written.
    """

    def __init__(self, params: VehicleParams, dt: float = 0.1, substep: float = 0.01):
        n = round(dt / substep)
        if n < 1 or abs(n * substep - dt) > 1e-9:
            raise ValueError(f"substep ({substep}) must divide dt ({dt}) evenly")
        self.params = params
        self.dt = dt
        self.n = n
        self.h = h = dt / n
        ta, td = params.tau_accel_s, params.tau_steer_s
        # Per sub-step: the acceleration lag's decay at its start and end, the steering lag's
        # at its middle and end (exact lags: they relax exponentially toward the commands).
        self._lags = np.array(
            [
                [
                    math.exp(-k * h / ta),
                    math.exp(-(k + 1) * h / ta),
                    math.exp(-(k + 0.5) * h / td),
                    math.exp(-(k + 1) * h / td),
                ]
                for k in range(n)
            ]
        )
        self._consts = (
            float(h),
            1.0 / params.wheelbase,
            float(params.speed_min),
            float(params.speed_max),
            float(ta * (1.0 - math.exp(-h / ta))),  # the speed gained from the acceleration's lag
            float(params.accel_min),
            float(params.accel_max),
            float(params.max_steer_rad),
            float(ta),
        )

    def lag_factors(self) -> np.ndarray:
        """(n, 4): ``truth_kernel.truth_step``'s ``lags`` (a copy)."""
        return self._lags.copy()

    def step_constants(self) -> tuple[float, ...]:
        """(h, 1 / wheelbase, v_min, v_max, dv_lag, a_min, a_max, max_steer, tau_a): the scalars
        ``truth_kernel.truth_step`` and the brake's hold law use."""
        return self._consts

    def step(self, state, a_cmd: float, delta_cmd: float) -> np.ndarray:
        """States at the end of each sub-step, (n, 7); commands are clipped to bounds.

        Columns: x, y, theta, v, a, delta, and the distance travelled in the sub-step.
        """
        out = np.empty((self.n, 7))
        truth_step(*(float(v) for v in state[:6]), float(a_cmd), float(delta_cmd), self._lags, self._consts, out, 0)
        return out

    def rollout(self, state, commands) -> np.ndarray:
        """States at the end of every sub-step under a sequence of (a_cmd, delta_cmd), one
        per control step: (steps * n, 7), the rows of chaining ``step``."""
        u = np.ascontiguousarray(np.asarray(commands, dtype=float).reshape(-1, 2))
        return truth_rollout(np.asarray(state, dtype=float)[:6], u, self._lags, self._consts)


def to_action(params: VehicleParams, a_cmd: float, delta_cmd: float) -> np.ndarray:
    """Physical commands -> the environment's normalised action in [-1, 1]^2.

    Acceleration maps piecewise-linearly so that 0 stays 0: [a_min, 0] -> [-1, 0] and
    [0, a_max] -> [0, 1]; steering maps linearly [-max_steer, max_steer] -> [-1, 1].
    """
    ua = a_cmd / params.accel_max if a_cmd >= 0 else -a_cmd / params.accel_min
    return np.clip(np.array([ua, delta_cmd / params.max_steer_rad], dtype=np.float32), -1.0, 1.0)


def from_action(params: VehicleParams, action) -> tuple[float, float]:
    """Normalised action -> physical (a_cmd, delta_cmd); the inverse of ``to_action``.

    Raises ``ValueError`` for a NaN, infinite or wrongly shaped action; finite values
    outside [-1, 1] are clipped, as an actuator saturates.
    """
    raw = np.asarray(action)
    if raw.dtype.kind not in "iuf":  # booleans, complex numbers, text, objects: not a command
        kinds = {"b": "booleans", "c": "complex numbers", "U": "text", "S": "bytes"}
        got = kinds.get(raw.dtype.kind, f"{type(action).__name__} values")
        raise ValueError(f"action: expected two real numbers [accel, steer] in [-1, 1], got {got}")
    arr = raw.astype(float)
    if arr.shape != (2,):
        raise ValueError(f"action: expected shape (2,) [accel, steer] in [-1, 1], got {arr.shape}")
    ua, ud = float(arr[0]), float(arr[1])
    if not (math.isfinite(ua) and math.isfinite(ud)):
        raise ValueError(f"action: must be finite numbers in [-1, 1], got [{ua}, {ud}]")
    ua = min(max(ua, -1.0), 1.0)
    ud = min(max(ud, -1.0), 1.0)
    a_cmd = ua * params.accel_max if ua >= 0 else -ua * params.accel_min
    return a_cmd, ud * params.max_steer_rad


@cache
def _table_ii() -> VehicleParams:
    return VehicleParams.from_config(default_vehicle())


# Cars by name: each a file of ``VehicleConfig``'s fields among the shipped configs.
VEHICLES = {"paper": "vehicle.yaml", "tpcap": "vehicle_tpcap.yaml"}


def vehicle_named(spec: str) -> VehicleParams:
    """A car by name (``paper``: the paper's Table II; ``tpcap``: the TPCAP benchmark's,
    ``configs/vehicle_tpcap.yaml``) or from a YAML file of ``configs/vehicle.yaml``'s fields.
    Raises ``ValueError`` naming the names allowed or the file's problem."""
    from pathlib import Path

    from .config import load

    if spec in VEHICLES:
        return _shipped(spec)
    p = Path(spec)
    if p.suffix.lower() not in (".yaml", ".yml") or not p.is_file():
        raise ValueError(f"vehicle: one of {sorted(VEHICLES)} or a YAML file of vehicle fields, got {spec!r}")
    return VehicleParams.from_config(load(VehicleConfig, p))


@cache
def _shipped(name: str) -> VehicleParams:
    from .config import default_config_path, load

    return VehicleParams.from_config(load(VehicleConfig, default_config_path(VEHICLES[name])))


def vehicle_name(params: VehicleParams) -> str | None:
    """The name of a shipped car with exactly these parameters, or None."""
    return next((n for n in VEHICLES if vehicle_named(n) == params), None)
