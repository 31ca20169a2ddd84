"""Hybrid A* as a policy: plan once from the start, track the path, replan on drift
(``common.tracking.TrackingPolicy``)."""

from __future__ import annotations

from mirrorpark_env.scenario import ScenarioGeometry

from ..base import PlanStats
from ..common.path import Path
from ..common.tracker import TrackerConfig
from ..common.tracking import TrackingPolicy
from .search import HybridAStar, HybridAStarConfig


class HybridAStarPolicy(TrackingPolicy):
    name = "hybrid-astar"

    def __init__(
        self,
        config: HybridAStarConfig | None = None,
        tracker: TrackerConfig | None = None,
        max_plans: int = 6,
        stopping_check: bool = True,
    ) -> None:
        super().__init__(tracker, max_plans, stopping_check)
        self.config = config or HybridAStarConfig()
        self.planner: HybridAStar | None = None

    def prepare(self, geometry: ScenarioGeometry) -> None:
        self.planner = HybridAStar(geometry, self.config)

    def find_path(self, pose, gear: int = 0) -> tuple[Path | None, PlanStats]:
        return self.planner.plan(pose)  # the search starts standing (prices_start_gear is off)

    @property
    def status(self) -> str:
        if self.gave_up and self.stats and self.stats[-1].status == "ok":
            return "gave_up"
        return super().status
