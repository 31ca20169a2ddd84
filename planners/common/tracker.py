"""Path tracking for a planned path: a speed profile with stops at cusps and a rear-axle
lateral law, within the car's limits.

Each gear segment is driven in three phases: steer while standing to the segment's first
curvature (the real car re-steers standing, docs/design.md), drive, and stop at
its end. Steering is the path's curvature (looked ahead by the steering lag) plus
feedback on the rear axle's lateral and heading error, with gains that give the error a
critically damped response over ``preview`` metres, in either gear:

    kappa = kappa_ref - e_y / preview**2 - gear * 2 * e_theta / preview

Speed follows ``min(cruise, sqrt(2 * decel * remaining))`` with the remaining distance
shortened by what the car rolls on while it stops, and it switches to a critically damped
stop (``hold_command``) once it is within that distance of the segment's end.
"""

from __future__ import annotations

import bisect
import math

import numpy as np
from pydantic import Field

from mirrorpark_env.angles import wrap_angle
from mirrorpark_env.config import StrictModel
from mirrorpark_env.vehicle import VehicleParams, VehicleState

from .path import Path


class TrackerConfig(StrictModel):
    """Speeds, gains and tolerances of the path tracker (SI units)."""

    cruise_speed: float = Field(1.0, gt=0, le=3)  # [m/s]
    accel: float = Field(1.0, gt=0, le=3)  # [m/s^2] to reach cruise speed
    decel: float = Field(1.0, gt=0, le=5)  # [m/s^2] of the planned stop profile
    preview: float = Field(1.2, gt=0, le=20)  # [m] distance over which lateral errors decay
    speed_gain: float = Field(2.0, gt=0, le=100)  # [1/s]
    steer_tolerance: float = Field(0.03, gt=0, le=0.5)  # [rad] standing re-steer is done within this
    max_lateral_error: float = Field(0.15, gt=0, le=5)  # [m] beyond this the policy replans
    max_heading_error_deg: float = Field(5.0, gt=0, le=90)


class PathTracker:
    """Turns a ``Path`` into [accel, steer] commands; ``done`` once it stands at the end."""

    def __init__(self, path: Path, params: VehicleParams, config: TrackerConfig | None = None):
        self.cfg = config or TrackerConfig()
        self.params = params
        self.path = path
        self.segments = path.segments()
        p = path.poses
        ds = np.hypot(*np.diff(p[:, :2], axis=0).T)
        self.s = np.concatenate(([0.0], np.cumsum(ds)))  # arc length along the whole path
        # Python lists for the per-step scalar look-ups (numpy scalars are slow one by one).
        self._s = self.s.tolist()
        self._kappa = path.curvature.tolist()
        self._gear = path.direction.tolist()
        self._poses = p[:, :3].tolist()
        self._x, self._y = p[:, 0].tolist(), p[:, 1].tolist()
        self._max_heading_error = math.radians(self.cfg.max_heading_error_deg)
        self.seg = 0
        self.j = self.segments[0][0] if self.segments else 0
        self.phase = "steer"
        self.done = not self.segments
        self.drifted = False
        self.e_y = 0.0
        self.e_theta = 0.0

    @property
    def first_gear(self) -> int:
        """+1 or -1: the gear of the path's first segment (0 for an empty path)."""
        return int(self._gear[self.segments[0][1]]) if self.segments else 0

    def _kappa_at(self, s: float, i0: int, i1: int) -> float:
        k = bisect.bisect_left(self._s, s, i0, i1 + 1)
        return self._kappa[min(max(k, i0 + 1), i1)]

    def command(self, st: VehicleState) -> tuple[float, float]:
        """Acceleration and steering commands [m/s^2, rad] for the measured state."""
        return self.command_at(st.x, st.y, st.theta, st.v, st.a, st.delta)

    def command_at(self, x: float, y: float, theta: float, v: float, a: float, delta: float) -> tuple[float, float]:
        """``command`` on the state's components (closed loops that keep them as floats)."""
        p, cfg = self.params, self.cfg
        if self.done:
            return self._hold(v, a, delta)
        i0, i1 = self.segments[self.seg]
        gear = float(self._gear[i1])
        if self.phase == "steer":
            delta0 = self._steer_for(self._kappa_at(self._s[i0] + 0.1, i0, i1))
            if abs(delta - delta0) < cfg.steer_tolerance and abs(v) < 0.02:
                self.phase = "drive"
            else:
                return self._hold(v, a, delta0)
        # Nearest path sample ahead of the last one, within this segment (the first of equals).
        j, hi = self.j, min(i1, self.j + 40)
        xs, ys = self._x, self._y
        best = (xs[j] - x) ** 2 + (ys[j] - y) ** 2
        for k in range(j + 1, hi + 1):
            d2 = (xs[k] - x) ** 2 + (ys[k] - y) ** 2
            if d2 < best:
                best, j = d2, k
        self.j = j
        xr, yr, thr = self._poses[j]
        c, s = math.cos(thr), math.sin(thr)
        dx, dy = x - xr, y - yr
        along = gear * (c * dx + s * dy)  # progress past sample j in the driving direction
        self.e_y = -s * dx + c * dy
        self.e_theta = wrap_angle(theta - thr)
        if abs(self.e_y) > cfg.max_lateral_error or abs(self.e_theta) > self._max_heading_error:
            self.drifted = True
        s_now = self._s[j] + along
        remaining = self._s[i1] - s_now
        speed = abs(v)
        if self.phase == "drive":
            # Distance the hold law of _hold rolls on from here: 2 tau v + tau^2 a (along the gear).
            roll = 2.0 * p.tau_accel_s * speed + p.tau_accel_s**2 * gear * a
            if remaining <= max(roll, 0.005):
                self.phase = "stop"
        if self.phase == "stop":
            if speed < 0.01 and abs(a) < 0.2:
                return self._next_segment(x, y, theta, v, a, delta)
            return self._hold(v, a, delta)
        kappa_ref = self._kappa_at(s_now + speed * p.tau_steer_s + 0.05, i0, i1)
        kappa = kappa_ref - self.e_y / cfg.preview**2 - gear * 2.0 * self.e_theta / cfg.preview
        steer = self._steer_for(kappa)
        room = max(remaining - 2.0 * p.tau_accel_s * speed, 0.0)
        v_ref = min(cfg.cruise_speed, math.sqrt(2.0 * cfg.decel * room), speed + cfg.accel * 0.5 + 0.1)
        acc = cfg.speed_gain * (gear * v_ref - v)
        return max(p.accel_min, min(p.accel_max, acc)), steer

    def _next_segment(self, x: float, y: float, theta: float, v: float, a: float, delta: float) -> tuple[float, float]:
        if self.seg + 1 >= len(self.segments):
            self.done = True
            return self._hold(v, a, delta)
        self.seg += 1
        self.j = self.segments[self.seg][0]
        self.phase = "steer"
        return self.command_at(x, y, theta, v, a, delta)

    def _clip_steer(self, delta: float) -> float:
        return max(-self.params.max_steer_rad, min(self.params.max_steer_rad, delta))

    def _steer_for(self, kappa: float) -> float:
        return self._clip_steer(math.atan(self.params.wheelbase * kappa))

    def _hold(self, v: float, a: float, delta: float) -> tuple[float, float]:
        """Brake to a stand (or stay there) while steering to ``delta``."""
        return hold_accel(self.params, v, a), self._clip_steer(delta)


def hold_command(p: VehicleParams, st: VehicleState) -> float:
    """Acceleration command that brings the car to a stand without rolling back."""
    return hold_accel(p, st.v, st.a)


def emergency_accel(p: VehicleParams, v: float, a: float) -> float:
    """The hardest stop: the full brake while the speed the car would settle at with the
    command dropped now (v + tau a, the lag's remaining effect) still has ``v``'s sign, then
    ``hold_accel``. It stops in about half the distance of ``hold_accel`` alone, whose
    critically damped approach eases off early (1.0 m against 0.5 m from 1.6 m/s reversing)."""
    rest = v + p.tau_accel_s * a
    if abs(rest) < 0.05 or rest * v <= 0:
        return hold_accel(p, v, a)
    return p.accel_min if rest > 0 else p.accel_max


def hold_accel(p: VehicleParams, v: float, a: float) -> float:
    """``hold_command`` for speed ``v`` and actual acceleration ``a``.

    With the acceleration lag tau, a_cmd = -(v / tau + a) makes the speed critically
    damped (double pole at -1/tau): from speed v0 it rolls on 2 tau v0 + tau^2 a0.
    """
    return max(p.accel_min, min(p.accel_max, -(v / p.tau_accel_s + a)))
