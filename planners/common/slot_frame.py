"""Planning in the slot's frame: a planner written for the grid's frame, in any layout.

The mirror planner (like the paper) states its geometry in one frame: the slot line along
+X, the slot below it (-Y), the car driving past in +X. A layout with a slot can be put in
that frame by a rigid motion, and a reflection where the car drives past with the slot on
its left: the kinematic bicycle is mirror-symmetric when the steering angle changes sign.
``InSlotFrame`` wraps such a policy: it hands it the scene and every measured state in the
slot's frame, and turns its steering back where the frame is reflected. A grid case is
already in that frame and passes through untouched.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from mirrorpark_env.config import ParkingType
from mirrorpark_env.geometry import ConvexSet
from mirrorpark_env.layout import Layout, Slot
from mirrorpark_env.scenario import ScenarioGeometry
from mirrorpark_env.slot_inference import planning_slot
from mirrorpark_env.vehicle import VehicleState, to_action

from ..base import PlanStats, Policy
from .tracker import hold_accel

ROAD_DEFAULT = 8.0  # [m] road depth beside a slot where no obstacle bounds it
ROAD_RANGE = (2.5, 15.0)  # [m] the road depth the slot frame reports is clipped to this


class NoSlot(ValueError):
    """The scene has no slot the frame can be built from; ``status`` says which case."""

    def __init__(self, status: str, reason: str):
        super().__init__(reason)
        self.status = status


@dataclass(frozen=True)
class SlotFrame:
    """World -> slot frame: p' = (e_x . (p - o), e_y . (p - o)); reflected if left-handed."""

    origin: np.ndarray
    e_x: np.ndarray
    e_y: np.ndarray

    @property
    def identity(self) -> bool:
        """Within 1e-12 of the world frame (a grid case read back from a file, say)."""
        eye = np.concatenate([self.origin, self.e_x - (1.0, 0.0), self.e_y - (0.0, 1.0)])
        return bool(np.abs(eye).max() < 1e-12)

    @property
    def reflected(self) -> bool:
        return float(self.e_x[0] * self.e_y[1] - self.e_x[1] * self.e_y[0]) < 0

    def points(self, p) -> np.ndarray:
        q = np.asarray(p, float) - self.origin
        return np.stack([q @ self.e_x, q @ self.e_y], axis=-1)

    def heading(self, th: float) -> float:
        d = np.array([math.cos(th), math.sin(th)])
        return math.atan2(float(d @ self.e_y), float(d @ self.e_x))

    def pose(self, pose) -> tuple[float, float, float]:
        x, y = self.points(np.asarray(pose[:2], float))
        return (float(x), float(y), self.heading(pose[2]))

    def state(self, s: VehicleState) -> VehicleState:
        x, y, th = self.pose((s.x, s.y, s.theta))
        return VehicleState(x, y, th, s.v, s.a, -s.delta if self.reflected else s.delta)


def _rot(d: np.ndarray, angle: float) -> np.ndarray:
    """``d`` turned by ``angle``; exact for quarter turns (a grid slot's frame is then exact)."""
    quarter = angle / (math.pi / 2)
    if abs(quarter - round(quarter)) < 1e-12:
        for _ in range(round(quarter) % 4):
            d = np.array([-d[1], d[0]])
        return np.asarray(d, float)
    c, s = math.cos(angle), math.sin(angle)
    return np.array([c * d[0] - s * d[1], s * d[0] + c * d[1]])


def planner_slot(g: ScenarioGeometry) -> Slot:
    """The slot a planner in the slot's frame plans in: the layout's, else one drawn around
    the car at the target (``slot_inference.planning_slot``: a target in open space);
    ``NoSlot`` where neither exists."""
    if g.layout is None:
        raise NoSlot("no_slot", "the scene is no layout: no slot to plan in")
    if g.layout.slot is not None:
        return g.layout.slot
    slot, why = planning_slot(g.obstacles.polygons, (g.start.x, g.start.y, g.start.theta), g.target, g.vehicle)
    if slot is None:
        raise NoSlot("no_slot", f"the layout has no slot and none can be drawn at the target: {why}")
    return slot


def slot_frame(g: ScenarioGeometry, s: Slot | None = None) -> SlotFrame:
    """The frame that puts slot ``s`` (default: ``planner_slot(g)``) where the grid's is;
    ``NoSlot`` where none can."""
    s = s if s is not None else planner_slot(g)
    n_out = s.outward()
    t = np.array([math.cos(g.target[2]), math.sin(g.target[2])])
    if s.parking_type is ParkingType.PARALLEL:
        if abs(float(t @ n_out)) > 0.1:
            raise NoSlot("unsupported_slot", "parallel slot: the target heading does not run along the entrance")
        e_y = n_out
        proper = _rot(e_y, -math.pi / 2)
        choices = [(proper, e_y), (-proper, e_y)]
        e_x, e_y = max(choices, key=lambda c: float(c[0] @ t))
    else:
        if float(t @ n_out) < 0.9:
            raise NoSlot("unsupported_slot", f"{s.parking_type.value} slot: the car must face out of it (reversed in)")
        tilt = math.pi / 4 if s.parking_type is ParkingType.ANGLE else math.pi / 2
        choices = [
            (_rot(n_out, -tilt), _rot(n_out, math.pi / 2 - tilt)),
            (_rot(n_out, tilt), _rot(n_out, tilt - math.pi / 2)),
        ]
        road = s.road_heading if s.road_heading is not None else g.start.theta
        r = np.array([math.cos(road), math.sin(road)])
        e_x, e_y = max(choices, key=lambda c: (round(float(c[0] @ r), 9), c is choices[0]))
    a, b = s.corners[s.entrance], s.corners[(s.entrance + 1) % 4]
    if s.parking_type is ParkingType.ANGLE:
        o = a if float(a @ e_y) >= float(b @ e_y) else b
    else:
        o = a if float(a @ e_x) <= float(b @ e_x) else b
    return SlotFrame(np.asarray(o, float), e_x, e_y)


def in_slot_frame(g: ScenarioGeometry) -> tuple[ScenarioGeometry, SlotFrame | None]:
    """``g`` in its slot's frame and the frame (None for a grid case: already there)."""
    if g.scenario is not None:
        return g, None
    s = planner_slot(g)
    f = slot_frame(g, s)
    if f.identity and g.road_width > 0 and g.slot is not None:
        return g, None  # already there, to the last bit
    parts = tuple(f.points(p) for p in g.obstacles.polygons)
    slot = Slot(f.points(s.corners), s.parking_type, s.entrance, 0.0, s.length, s.width)
    x0, x1, y0, y1 = g.bounds
    box = f.points(np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]]))
    bounds = (*(float(v) for v in (box[:, 0].min(), box[:, 0].max(), box[:, 1].min(), box[:, 1].max())),)
    layout = Layout(
        obstacles=parts,
        start=f.pose((g.start.x, g.start.y, g.start.theta)),
        target=f.pose(g.target),
        slot=slot,
        name=g.layout.name,
        bounds=bounds,
        road_width=_road_depth(parts, slot.corners),
    )
    return layout.build(g.vehicle), f


def _road_depth(parts, slot: np.ndarray) -> float:
    """How far the road reaches above the slot line: the lowest obstacle above it, near the slot."""
    x_lo, x_hi = float(slot[:, 0].min()) - 5.0, float(slot[:, 0].max()) + 10.0
    lows = [
        float(p[:, 1].min()) for p in parts if p[:, 1].min() > 0.5 and p[:, 0].max() >= x_lo and p[:, 0].min() <= x_hi
    ]
    return float(np.clip(min(lows, default=ROAD_DEFAULT), *ROAD_RANGE))


class InSlotFrame(Policy):
    """Runs ``inner`` (a policy written for the grid's frame) in any layout with a slot.

    Without a usable slot it plans nothing: it brakes, and its one planning record says
    why (status ``no_slot`` or ``unsupported_slot``).
    """

    def __init__(self, inner: Policy):
        self.inner = inner
        self.name = inner.name
        self.frame: SlotFrame | None = None
        self._refusal: PlanStats | None = None

    def reset(self, geometry: ScenarioGeometry) -> None:
        self.params = geometry.vehicle
        self._refusal = None
        try:
            canon, self.frame = in_slot_frame(geometry)
        except NoSlot as err:
            self._refusal = PlanStats(0.0, err.status, detail={"reason": str(err)})
            return
        self._told, self._canon = geometry, canon  # the scene as told, and as the inner policy has it
        self.inner.reset(canon)

    def act(self, obs: dict[str, np.ndarray], info: dict[str, Any]) -> np.ndarray:
        if self._refusal is not None:
            s = info["vehicle_state"]
            return to_action(self.params, hold_accel(self.params, s.v, s.a), s.delta)
        if self.frame is None:
            return self.inner.act(obs, info)
        seen = {"vehicle_state": self.frame.state(info["vehicle_state"])}
        if info.get("geometry") is not None:  # the scene: as the inner policy has it, changed or not
            seen["geometry"] = self._scene(info["geometry"])
        action = np.array(self.inner.act(obs, {**info, **seen}))
        if self.frame.reflected:
            action[1] = -action[1]
        return action

    def _scene(self, told: ScenarioGeometry) -> ScenarioGeometry:
        """``told`` in the slot's frame: the one the inner policy has, or where the scene has
        changed since (a late obstacle; the slot stays where it was), its obstacles moved in."""
        if told is not self._told:
            parts = [self.frame.points(p) for p in told.obstacles.polygons]
            self._told, self._canon = told, dataclasses.replace(self._canon, obstacles=ConvexSet.from_polygons(parts))
        return self._canon

    @property
    def stats(self) -> list[PlanStats]:
        return [self._refusal] if self._refusal is not None else self.inner.stats

    @property
    def gave_up(self) -> bool:
        return self._refusal is not None or self.inner.gave_up

    @property
    def setup_time_s(self) -> float:
        return getattr(self.inner, "setup_time_s", 0.0)

    @property
    def status(self) -> str:
        return self._refusal.status if self._refusal is not None else self.inner.status

    def __getattr__(self, name: str):  # plans, planner, ...: the inner policy's
        if name == "inner":
            raise AttributeError(name)
        return getattr(self.inner, name)
