"""A policy that plans a path and tracks it: the shape shared by the search-based
baseline and the guide-only ablation.

A path is planned when the episode starts and again, from where the car stands, when
tracking has drifted beyond the tracker's tolerance or the path has been driven to its
end without the ISO check passing, or when the next command would leave the car unable to
stop clear of an obstacle (``safety.StoppingCheck``). Before a replan the car is brought to
a stand. A failed plan stops the car for good and says why in the last ``PlanStats``; it
never raises.

With ``markov`` set (a DAgger expert, ``planners/rl/dagger.py``), it instead plans afresh
from every state it is asked about and answers with the tracker's first command on that
path: its action is a function of the state alone, with no memory of an earlier plan's
cusps, which a learner that sees only the state can imitate.
"""

from __future__ import annotations

import time
from abc import abstractmethod
from typing import Any

import numpy as np

from mirrorpark_env.scenario import ScenarioGeometry
from mirrorpark_env.vehicle import VehicleState, to_action

from ..base import PlanStats, Policy
from .brake import clearest_stop
from .path import Path
from .safety import StoppingCheck
from .tracker import PathTracker, TrackerConfig, emergency_accel, hold_command


class TrackingPolicy(Policy):
    """Subclasses say how to ``prepare`` for a scene and how to ``find_path`` from a pose."""

    prices_start_gear = False  # find_path(pose, gear) charges a switch for starting in the other gear

    def __init__(self, tracker: TrackerConfig | None = None, max_plans: int = 6, stopping_check: bool = True) -> None:
        super().__init__()
        self.stopping_check = stopping_check  # brake while the car can still stop clear (common.safety)
        self._stopping: StoppingCheck | None = None
        self.safety_stops = 0  # brakes the stopping check ordered this episode
        self.tracker_config = tracker or TrackerConfig()
        self.max_plans = max_plans
        # After a drift, plan again at once from where the car is, moving or not (a DAgger
        # expert's labels: a drifted learner is told how to go on, not to stop; dagger.py).
        # Off: brake to a stand first, as a car executing its own plans does.
        self.replan_moving = False
        self.markov = False  # plan afresh from every state (module docstring)
        self.params = None
        self.geometry: ScenarioGeometry | None = None

    @abstractmethod
    def prepare(self, geometry: ScenarioGeometry) -> None:
        """Build what the scene needs (called by ``reset``)."""

    @abstractmethod
    def find_path(self, pose: tuple[float, float, float], gear: int = 0) -> tuple[Path | None, PlanStats]:
        """A path from ``pose`` (None on failure) and the call's statistics; ``gear`` (+1, -1,
        0 standing) the way the car moves there, used where ``prices_start_gear``."""

    def reset(self, geometry: ScenarioGeometry) -> None:
        self._take_scene(geometry)
        self.params = geometry.vehicle
        self.safety_stops = 0
        self.stats = []
        self.paths: list[Path] = []
        self.tracker: PathTracker | None = None
        self.gave_up = False
        self._replan_when_stopped = True
        self._stand_first = False
        self._stop_steer: float | None = None  # the steering of a stop ordered by a changed scene

    def act(self, obs: dict[str, np.ndarray], info: dict[str, Any]) -> np.ndarray:
        if self.params is None:
            raise RuntimeError(f"{type(self).__name__}: call reset(geometry) first")
        s: VehicleState = info["vehicle_state"]
        changed = self.changed_scene(info, self.geometry)
        if changed is not None:
            self._new_scene(changed, s)
        if self.markov:
            return self._act_afresh(s)
        tr = self.tracker
        if tr is not None and (tr.drifted or tr.done) and not info.get("is_success", False):
            self._replan_when_stopped = True
            self.tracker = tr = None
        if tr is None:
            moving_ok = self.replan_moving and not self._stand_first
            if self.gave_up or not self._replan_when_stopped or (abs(s.v) > 0.02 and not moving_ok):
                return self._brake(s)
            self._plan(s)
            tr = self.tracker
            if tr is None:
                return self._brake(s)
        action = self._command(s, tr)
        if action is None:
            # Tracking has drifted toward an obstacle: stop while the car can, then replan
            # from a stand (also with ``replan_moving``: the car is about to hit something).
            self.tracker = None
            self._replan_when_stopped = True
            self._stand_first = True
            return self._brake(s)
        return action

    def _take_scene(self, geometry: ScenarioGeometry) -> None:
        """What depends on the scene: the planner's preparation (timed: ``setup_time_s``) and
        the stopping check."""
        t0 = time.perf_counter()
        self.prepare(geometry)
        self.setup_time_s = time.perf_counter() - t0
        self.geometry = geometry
        self._stopping = StoppingCheck(geometry) if self.stopping_check else None

    def _new_scene(self, geometry: ScenarioGeometry, s: VehicleState) -> None:
        """The scene changed (a late obstacle): prepare for it, brake to a stand on the
        steering that keeps clearest of it and plan again there; the path being tracked was
        planned without the new obstacle."""
        self._take_scene(geometry)
        self._stop_steer = clearest_stop(geometry, s.as_array())
        self.tracker = None
        self._replan_when_stopped = True
        self._stand_first = True

    def _command(self, s: VehicleState, tr: PathTracker) -> np.ndarray | None:
        """The tracker's command as an action, or None where the stopping check forbids it
        (counted in ``safety_stops``)."""
        a, d = tr.command(s)
        if self._stopping is not None and not self._stopping.safe(s, tr):
            self.safety_stops += 1
            return None
        return to_action(self.params, a, d)

    def _act_afresh(self, s: VehicleState) -> np.ndarray:
        """The tracker's command on a path planned from this very state. Where the car already
        moves in the path's first gear it drives on; else the tracker stops (and re-steers
        standing) first, as it does at a cusp. Standing with no path, it gives up."""
        gear = 0 if abs(s.v) <= 0.02 else (1 if s.v > 0 else -1)
        path, stats = self.find_path((s.x, s.y, s.theta), gear)
        self.stats.append(stats)
        if path is None:
            self.tracker = None
            self.gave_up = gear == 0
            return self._brake(s)
        self.paths = [path]
        tr = self.tracker = PathTracker(path, self.params, self.tracker_config)
        if gear and tr.segments and tr.first_gear == gear:
            tr.phase = "drive"
        action = self._command(s, tr)
        return self._brake(s) if action is None else action

    def _plan(self, s: VehicleState) -> None:
        self._replan_when_stopped = False
        self._stand_first = False
        if len(self.stats) >= self.max_plans:
            self.gave_up = True
            return
        path, stats = self.find_path((s.x, s.y, s.theta))
        self.stats.append(stats)
        if path is None:
            self.gave_up = True
            return
        self.paths.append(path)
        self.tracker = PathTracker(path, self.params, self.tracker_config)

    def _brake(self, s: VehicleState) -> np.ndarray:
        if self._stop_steer is None:
            return to_action(self.params, hold_command(self.params, s), s.delta)
        steer = self._stop_steer  # a changed scene's stop: the hardest brake, the clearest steering
        if abs(s.v) < 0.02:
            self._stop_steer = None  # standing: that stop is over
        return to_action(self.params, emergency_accel(self.params, s.v, s.a), steer)
