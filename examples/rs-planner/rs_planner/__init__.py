"""An example planner outside MirrorPark: the shortest Reeds-Shepp path from where the car
stands to the target, at 1.1 times the car's minimum turning radius, driven by MirrorPark's
shared path tracker. A path whose swept footprint meets an obstacle is refused (the car
then stops and the episode says so): no search, no optimisation, a baseline to beat.

It reads what a planner may read: the scene's geometry at reset (obstacles, slot, target,
the car) and the measured state each step, through ``TrackingPolicy``.
"""

from __future__ import annotations

import time

import numpy as np

from planners.base import PlanStats
from planners.common.path import Path
from planners.common.reeds_shepp import ReedsShepp
from planners.common.tracking import TrackingPolicy

STEP = 0.05  # [m] spacing of the path's poses, for the footprint check and the tracker


class ReedsSheppPolicy(TrackingPolicy):
    name = "rs-example"

    def prepare(self, geometry) -> None:
        self.geometry = geometry
        self.rs = ReedsShepp(1.1 * geometry.vehicle.r_min)

    def find_path(self, pose, gear: int = 0):
        t0 = time.perf_counter()
        poses = self.rs.sample(pose, self.geometry.target, STEP)
        if np.any(self.geometry.checker.collides(poses[:, 0], poses[:, 1], poses[:, 2])):
            return None, PlanStats(time.perf_counter() - t0, "collision")
        return Path.from_poses(poses), PlanStats(time.perf_counter() - t0, "ok")


def make() -> ReedsSheppPolicy:
    """The entry point ``rs-example`` (``pyproject.toml``)."""
    return ReedsSheppPolicy()
