"""What a parking system perceives of a scene (``ScenarioGeometry``): obstacles, slot, start and target.

Grid cases (``scenario.py``) and loaded layouts (``layout.py``) alike build one; planners
read nothing else of the scene.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property
from typing import TYPE_CHECKING

import numpy as np

from .config import ParkingType
from .geometry import ConvexSet, FootprintChecker, HalfPlane
from .vehicle import VehicleParams, VehicleState

if TYPE_CHECKING:  # annotations only: the scene never needs them at run time
    from .layout import Layout
    from .scenario import Scenario


@dataclass(frozen=True, eq=False)
class ScenarioGeometry:
    """What a parking system perceives of a scene: obstacles, slot, start and target.

    Built by ``Layout.build`` for grid cases and loaded layouts alike. ``obstacles`` are
    convex parts. ``slot_edges`` are the slot's sides as inward half-planes, named
    ``entrance`` (the slot line), ``back`` and, for parallel, ``rear``/``front`` (the slot's
    ends behind and ahead of the parked car), for reverse and angle, ``left``/``right`` (as
    seen from the parked car). A layout without a slot has ``slot`` None and no edges.
    ``bounds``: the box the rear axle stays in (leaving it ends the episode, out of the
    scene); planners search inside it.
    """

    vehicle: VehicleParams
    obstacles: ConvexSet
    slot: np.ndarray | None  # (4, 2)
    slot_edges: tuple[tuple[str, HalfPlane], ...]
    start: VehicleState
    target: tuple[float, float, float]  # rear-axle (x, y, theta)
    bounds: tuple[float, float, float, float]  # x_min, x_max, y_min, y_max of the rear axle
    road_width: float = 0.0
    parking_type: ParkingType | None = None
    slot_length: float = math.nan
    slot_width: float = math.nan
    scenario: Scenario | None = None
    layout: Layout | None = None

    def edge(self, name: str) -> HalfPlane:
        for n, hp in self.slot_edges:
            if n == name:
                return hp
        raise KeyError(name)

    @cached_property
    def checker(self) -> FootprintChecker:
        """Exact footprint-vs-obstacles collision test for this car and scene."""
        v = self.vehicle
        return FootprintChecker(self.obstacles, v.front_length, v.rear_overhang, 0.5 * v.width)

    @property
    def target_heading(self) -> float:
        return self.target[2]
