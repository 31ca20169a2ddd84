"""Hybrid A* as a policy: plan once from the start, track the path, replan on drift.

A plan is searched when the episode starts and again, from where the car stands, when
tracking has drifted beyond the tracker's tolerance or the path has been driven to its
end without the ISO check passing. Before a replan the car is brought to a stand. A
failed search (no path, or the time budget spent) stops the car for good and says why
in the last ``PlanStats``; it never raises.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from mirrorpark_env.scenario import ScenarioGeometry
from mirrorpark_env.vehicle import VehicleState, to_action

from ..base import Policy
from ..common.path import Path
from ..common.tracker import PathTracker, TrackerConfig, hold_command
from .search import HybridAStar, HybridAStarConfig


class HybridAStarPolicy(Policy):
    name = "hybrid-astar"

    def __init__(
        self, config: HybridAStarConfig | None = None, tracker: TrackerConfig | None = None, max_plans: int = 6
    ) -> None:
        super().__init__()
        self.config = config or HybridAStarConfig()
        self.tracker_config = tracker or TrackerConfig()
        self.max_plans = max_plans
        self.planner: HybridAStar | None = None

    def reset(self, geometry: ScenarioGeometry) -> None:
        self.planner = HybridAStar(geometry, self.config)
        self.params = geometry.vehicle
        self.stats = []
        self.paths: list[Path] = []
        self.tracker: PathTracker | None = None
        self.gave_up = False
        self._replan_when_stopped = True

    def act(self, obs: dict[str, np.ndarray], info: dict[str, Any]) -> np.ndarray:
        if self.planner is None:
            raise RuntimeError("HybridAStarPolicy: call reset(geometry) first")
        s: VehicleState = info["vehicle_state"]
        tr = self.tracker
        if tr is not None and (tr.drifted or tr.done) and not info.get("is_success", False):
            self._replan_when_stopped = True
            self.tracker = tr = None
        if tr is None:
            if self.gave_up or not self._replan_when_stopped or abs(s.v) > 0.02:
                return self._brake(s)
            self._plan(s)
            tr = self.tracker
            if tr is None:
                return self._brake(s)
        a, d = tr.command(s)
        return to_action(self.params, a, d)

    def _plan(self, s: VehicleState) -> None:
        self._replan_when_stopped = False
        if len(self.stats) >= self.max_plans:
            self.gave_up = True
            return
        path, stats = self.planner.plan((s.x, s.y, s.theta))
        self.stats.append(stats)
        if path is None:
            self.gave_up = True
            return
        self.paths.append(path)
        self.tracker = PathTracker(path, self.params, self.tracker_config)

    def _brake(self, s: VehicleState) -> np.ndarray:
        return to_action(self.params, hold_command(self.params, s), s.delta)

    @property
    def status(self) -> str:
        if self.gave_up and self.stats and self.stats[-1].status == "ok":
            return "gave_up"
        return super().status
