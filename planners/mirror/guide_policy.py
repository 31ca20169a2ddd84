"""The geometric guide alone, as a policy: the ablation without any optimisation.

The mirror planner's guide (``guide.py``: Reeds-Shepp paths through the mirror line's
switch poses) is driven by the shared path tracker, exactly as hybrid A* drives its
paths: plan once, track, and plan again from where the car stands when tracking drifts
or the path has been driven without the ISO check passing. No QP, no mirrored target:
what this parks, the geometry parks; what ``mirror`` parks beyond it, the QP adds.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from mirrorpark_env.scenario import ScenarioGeometry
from mirrorpark_env.vehicle import VehicleState, to_action

from ..base import PlanStats, Policy
from ..common.tracker import PathTracker, TrackerConfig, hold_command
from .guide import GuideConfig, GuideSearch


class GuideOnlyPolicy(Policy):
    name = "guide-only"

    def __init__(self, guide: GuideConfig | None = None, tracker: TrackerConfig | None = None, max_plans: int = 6):
        super().__init__()
        self.guide_config = guide or GuideConfig()
        self.tracker_config = tracker or TrackerConfig()
        self.max_plans = max_plans
        self.search: GuideSearch | None = None

    def reset(self, geometry: ScenarioGeometry) -> None:
        t0 = time.perf_counter()
        self.search = GuideSearch(geometry, self.guide_config)
        self.search.road_tails()  # what depends on the slot alone, as the mirror policy does at reset
        self.setup_time_s = time.perf_counter() - t0
        self.params = geometry.vehicle
        self.stats = []
        self.tracker: PathTracker | None = None
        self.gave_up = False
        self._replan_when_stopped = True

    def act(self, obs: dict[str, np.ndarray], info: dict[str, Any]) -> np.ndarray:
        if self.search is None:
            raise RuntimeError("GuideOnlyPolicy: call reset(geometry) first")
        s: VehicleState = info["vehicle_state"]
        tr = self.tracker
        if tr is not None and (tr.drifted or tr.done) and not info.get("is_success", False):
            self._replan_when_stopped = True
            self.tracker = tr = None
        if tr is None:
            if self.gave_up or not self._replan_when_stopped or abs(s.v) > 0.02:
                return to_action(self.params, hold_command(self.params, s), s.delta)
            self._plan(s)
            if self.tracker is None:
                return to_action(self.params, hold_command(self.params, s), s.delta)
        a, d = self.tracker.command(s)
        return to_action(self.params, a, d)

    def _plan(self, s: VehicleState) -> None:
        self._replan_when_stopped = False
        if len(self.stats) >= self.max_plans:
            self.gave_up = True
            return
        t0 = time.perf_counter()
        guide = self.search.search((s.x, s.y, s.theta))
        status = "ok" if guide is not None else "no_guide"
        cost = guide.cost if guide is not None else float("nan")
        self.stats.append(PlanStats(time.perf_counter() - t0, status, cost=cost))
        if guide is None:
            self.gave_up = True
            return
        self.tracker = PathTracker(guide.path, self.params, self.tracker_config)
