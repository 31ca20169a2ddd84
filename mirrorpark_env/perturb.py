"""The world as it differs from what the planners know: the runtime of ``PerturbConfig``.

``MirrorParkEnv`` holds one ``Perturbation`` per episode. The truth model runs the truth car
(``truth_params``) and its actuators (``CommandPath``); planners see the measured state
(``MeasurementNoise``) and the geometry built for the car they are told of. Verdicts stay on
the true state. Every random draw comes from a generator seeded by the perturbation's seed
and the case's key, so an episode does not depend on which worker runs it or what ran before.
"""

from __future__ import annotations

import dataclasses
import math
import zlib
from collections import deque

import numpy as np

from .config import ActuatorConfig, LateObstacleConfig, NoiseConfig, PerturbConfig
from .vehicle import VehicleParams, VehicleState


def truth_params(told: VehicleParams, cfg: PerturbConfig) -> VehicleParams:
    """The truth car: ``told`` with the model error and the scaled lags of ``cfg``."""
    m, a = cfg.model, cfg.actuator
    return dataclasses.replace(
        told,
        wheelbase=told.wheelbase + m.wheelbase,
        rear_overhang=told.rear_overhang + m.rear_overhang,
        front_length=told.front_length + m.front_length,
        width=told.width + m.width,
        max_steer_rad=told.max_steer_rad * m.max_steer_scale,
        tau_accel_s=told.tau_accel_s * a.tau_accel_scale,
        tau_steer_s=told.tau_steer_s * a.tau_steer_scale,
    )


def episode_rng(cfg: PerturbConfig, case_key: str) -> np.random.Generator:
    """The episode's generator: a function of the perturbation's seed and the case alone."""
    return np.random.default_rng([cfg.seed, zlib.crc32(case_key.encode())])


class MeasurementNoise:
    """Noise on (x, y, theta, v): each channel a zero-mean Gaussian of its standard deviation,
    independent per step (``correlation_time_s`` 0) or a stationary first-order Gauss-Markov
    process e' = phi e + sqrt(1 - phi^2) std w, phi = exp(-dt / tau); plus constant biases.
    Position errors are drawn and biased in the car's frame (longitudinal, lateral)."""

    def __init__(self, cfg: NoiseConfig, dt: float, rng: np.random.Generator):
        self.std = np.array([cfg.position_std, cfg.position_std, math.radians(cfg.heading_std_deg), cfg.speed_std])
        self.bias = np.array(
            [cfg.longitudinal_bias, cfg.lateral_bias, math.radians(cfg.heading_bias_deg), cfg.speed_bias]
        )
        tau = cfg.correlation_time_s
        self.phi = math.exp(-dt / tau) if tau > 0 else 0.0
        self.rng = rng
        self.error: np.ndarray | None = None  # the last draw (car frame), before the bias

    def measure(self, true: np.ndarray) -> VehicleState:
        """The measured state of the true (x, y, theta, v, a, delta): pose, heading and speed
        with error; acceleration and steering angle as they are."""
        w = self.rng.standard_normal(4) * self.std
        if self.error is None or self.phi == 0.0:
            self.error = w
        else:
            self.error = self.phi * self.error + math.sqrt(1.0 - self.phi**2) * w
        e = self.error + self.bias
        x, y, th, v, a, d = (float(q) for q in true[:6])
        c, s = math.cos(th), math.sin(th)
        return VehicleState(x + c * e[0] - s * e[1], y + s * e[0] + c * e[1], th + e[2], v + e[3], a, d)


class CommandPath:
    """What happens to a command on its way to the truth's actuators: gains and a steering
    offset, a delay of ``delay_steps`` control steps (the queue starts with the standing
    car's commands, 0 and 0), then rate limits per control step (0: none)."""

    def __init__(self, cfg: ActuatorConfig, delay_steps: int, dt: float):
        self.cfg = cfg
        self.queue: deque[tuple[float, float]] = deque([(0.0, 0.0)] * delay_steps)
        self.offset = math.radians(cfg.steer_offset_deg)
        self.max_dd = math.radians(cfg.steer_rate_max_deg_s) * dt if cfg.steer_rate_max_deg_s else math.inf
        self.max_da = cfg.jerk_max * dt if cfg.jerk_max else math.inf
        self.last: tuple[float, float] = (0.0, 0.0)  # the command the actuators last took

    def apply(self, a_cmd: float, d_cmd: float) -> tuple[float, float]:
        """The (acceleration, steering) command the actuators take this step."""
        self.queue.append((self.cfg.accel_gain * a_cmd, self.cfg.steer_gain * d_cmd + self.offset))
        a, d = self.queue.popleft()
        a0, d0 = self.last
        a = min(max(a, a0 - self.max_da), a0 + self.max_da)
        d = min(max(d, d0 - self.max_dd), d0 + self.max_dd)
        self.last = (a, d)
        return a, d


def late_box(cfg: LateObstacleConfig, car: VehicleParams, x: float, y: float, th: float, direction: int) -> np.ndarray:
    """The late obstacle's corners (4, 2): a box aligned with the car, ``cfg.ahead`` beyond the
    bumper on the side the car drives toward (``direction`` +1 forward, -1 reverse)."""
    bumper = car.front_length if direction > 0 else car.rear_overhang
    along = direction * (bumper + cfg.ahead + 0.5 * cfg.length)
    c, s = math.cos(th), math.sin(th)
    cx, cy = x + c * along - s * cfg.lateral, y + s * along + c * cfg.lateral
    hl, hw = 0.5 * cfg.length, 0.5 * cfg.width
    local = np.array([[hl, hw], [-hl, hw], [-hl, -hw], [hl, -hw]])
    return np.column_stack([cx + c * local[:, 0] - s * local[:, 1], cy + s * local[:, 0] + c * local[:, 1]])


class Perturbation:
    """One episode's perturbation: the noise, the command path and the late obstacle's clock."""

    def __init__(self, cfg: PerturbConfig, told: VehicleParams, dt: float, case_key: str):
        self.cfg = cfg
        self.truth = truth_params(told, cfg)
        self.noise = MeasurementNoise(cfg.noise, dt, episode_rng(cfg, case_key))
        self.commands = CommandPath(cfg.actuator, cfg.delay_steps, dt)
        self.obstacle_due = cfg.late_obstacle is not None

    def late_obstacle(self, time: float, state: np.ndarray, last_dir: int) -> np.ndarray | None:
        """The late obstacle's corners once its time has come (once per episode), else None."""
        ob = self.cfg.late_obstacle
        if not self.obstacle_due or ob is None or time < ob.time_s - 1e-9:
            return None
        self.obstacle_due = False
        v = float(state[3])
        direction = (1 if v > 0 else -1) if abs(v) > 0.01 else (last_dir or 1)
        return late_box(ob, self.truth, float(state[0]), float(state[1]), float(state[2]), direction)
