"""The geometric guide alone, as a policy: the ablation without any optimisation.

The mirror planner's guide (``guide.py``: Reeds-Shepp paths through the mirror line's
switch poses) is driven by the shared path tracker, exactly as hybrid A* drives its
paths: plan once, track, and plan again from where the car stands when tracking drifts
or the path has been driven without the ISO check passing. No QP, no mirrored target:
what this parks, the geometry parks; what ``mirror`` parks beyond it, the QP adds.
"""

from __future__ import annotations

import time

from mirrorpark_env.scenario import ScenarioGeometry

from ..base import PlanStats
from ..common.path import Path
from ..common.tracker import TrackerConfig
from ..common.tracking import TrackingPolicy
from .config import GuideConfig
from .guide import GuideSearch, prepared_search


class GuideOnlyPolicy(TrackingPolicy):
    name = "guide-only"
    prices_start_gear = True

    def __init__(self, guide: GuideConfig | None = None, tracker: TrackerConfig | None = None, max_plans: int = 6):
        super().__init__(tracker, max_plans)
        self.guide_config = guide or GuideConfig()
        self.search: GuideSearch | None = None

    def prepare(self, geometry: ScenarioGeometry) -> None:
        self.search = prepared_search(geometry, self.guide_config)  # the slot's part, as the mirror policy's

    def find_path(self, pose, gear: int = 0) -> tuple[Path | None, PlanStats]:
        t0 = time.perf_counter()
        guide = self.search.search(pose, gear)
        if guide is None:
            return None, PlanStats(time.perf_counter() - t0, "no_guide")
        return guide.path, PlanStats(time.perf_counter() - t0, "ok", cost=guide.cost)
