"""What a planner builds once per slot, shared by the episodes of one process in that slot.

A guide's tails or a cost to go depend on the slot, its obstacles, the target and the car
alone, never on the start, and nothing changes them once built: sharing them gives every
episode the same plans as building its own (a car that has measured a slot once).
"""

from __future__ import annotations

import hashlib
from collections import OrderedDict
from collections.abc import Callable
from typing import Generic, TypeVar

import numpy as np

from mirrorpark_env.scenario import ScenarioGeometry

T = TypeVar("T")


def geometry_key(geometry: ScenarioGeometry, *extra: object) -> str:
    """A digest of what a slot's plans depend on (obstacles, slot, target, road, car,
    bounds) and of ``extra`` (a planner's settings)."""
    g = geometry
    h = hashlib.sha256()
    for a in (g.obstacles.vertices, np.asarray(g.slot, float), np.asarray(g.target, float)):
        h.update(np.ascontiguousarray(a).tobytes())
    h.update(repr((g.road_width, g.slot_width, g.parking_type, g.vehicle, g.bounds, *extra)).encode())
    return h.hexdigest()


class SlotCache(Generic[T]):
    """The last ``size`` slots' objects, least recently used dropped first."""

    def __init__(self, size: int) -> None:
        self.size = size
        self._items: OrderedDict[str, T] = OrderedDict()
        self.builds = 0  # items built so far (tests count them)

    def get(
        self,
        geometry: ScenarioGeometry,
        settings: object,
        build: Callable[[], T],
        serves: Callable[[T], bool] | None = None,
    ) -> T:
        """The slot's item, built if missing or if ``serves`` says the one held does not serve."""
        key = geometry_key(geometry, settings)
        item = self._items.get(key)
        if item is None or (serves is not None and not serves(item)):
            item = self._items[key] = build()
            self.builds += 1
            if len(self._items) > self.size:
                self._items.popitem(last=False)
        else:
            self._items.move_to_end(key)
        return item
