"""Layouts: any parking scene as data, and the geometry the environment and planners use.

A layout is obstacle polygons (any simple polygon; non-convex ones are cut exactly into
convex parts), an optional boundary of the drivable area, the car's start and target
rear-axle poses, and optionally the target slot (a rectangle, its parking type and which
of its edges is the entrance) that the ISO criteria need. Without a slot, success is the
target pose within ``CriteriaConfig.target_position_tol`` and ``heading_tol_deg``.

A grid ``Scenario`` is one kind of layout (``Scenario.layout``): the environment builds
every scene through ``Layout.build``, so grid cases and loaded layouts share one path.
Files are read by ``layout_io``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cached_property
from typing import TYPE_CHECKING

import numpy as np

from .angles import wrap_angle
from .config import ParkingType
from .decompose import convex_parts
from .geometry import ConvexSet, inward_half_plane
from .scene import ScenarioGeometry
from .vehicle import VehicleParams, VehicleState, footprint

if TYPE_CHECKING:  # annotations only
    from .scenario import Scenario

SCENE_PAD = 5.0  # [m] a layout's scene reaches this far beyond everything in it (when not given)
BOUNDARY_DEPTH = 3.0  # [m] thickness of the wall outside a drivable-area boundary
OVERLAP_TOL = 1e-3  # [m] a start or target may touch an obstacle, not overlap it deeper
MAX_EXTENT = 10_000.0  # [m] a parking scene: everything in it lies within this of the target (after recentring)


def _pose(name: str, value) -> tuple[float, float, float]:
    try:
        x, y, th = (float(v) for v in value)
    except (TypeError, ValueError):
        raise ValueError(f"{name}: expected (x, y, theta), got {value!r}") from None
    if not all(math.isfinite(v) for v in (x, y, th)):
        raise ValueError(f"{name}: must be finite, got {value!r}")
    return (x, y, wrap_angle(th))


def _polygon(name: str, value) -> np.ndarray:
    p = np.asarray(value, dtype=float)
    if p.ndim != 2 or p.shape[1] != 2 or len(p) < 3:
        raise ValueError(f"{name}: expected at least 3 (x, y) vertices, got shape {p.shape}")
    if not np.all(np.isfinite(p)):
        raise ValueError(f"{name}: vertices must be finite")
    if len(p) > 3 and np.allclose(p[0], p[-1], rtol=0.0, atol=1e-9):
        p = p[:-1]  # a closed ring's repeated first vertex (absolute: coordinates may be ~1e9 m)
    return p


NAME_MAX = 120  # a layout name's characters: it is a case id, a table cell and a figure's file name


@dataclass(frozen=True, eq=False)
class Slot:
    """The target slot: a rectangle, its type, and its entrance edge (corner i to i + 1).

    ``road_heading`` is the direction of travel past the slot (rad); where it is None the
    planners that need it take the one closer to the start heading. Lengths along the
    slot: parallel slots are ``length`` along the entrance, reverse and angle slots
    ``width`` along it.
    """

    corners: np.ndarray
    parking_type: ParkingType
    entrance: int = 0
    road_heading: float | None = None
    length: float = field(default=math.nan)
    width: float = field(default=math.nan)

    def __post_init__(self) -> None:
        c = _polygon("slot.corners", self.corners)
        if len(c) != 4:
            raise ValueError(f"slot.corners: a slot is a rectangle of 4 corners, got {len(c)}")
        e = np.roll(c, -1, axis=0) - c
        sides = np.hypot(e[:, 0], e[:, 1])
        if sides.min() <= 1e-6:
            raise ValueError("slot.corners: two corners coincide")
        cos = np.abs((e * np.roll(e, -1, axis=0)).sum(axis=1)) / (sides * np.roll(sides, -1))
        if cos.max() > 1e-6 or abs(sides[0] - sides[2]) > 1e-6 or abs(sides[1] - sides[3]) > 1e-6:
            raise ValueError("slot.corners: not a rectangle (sides must meet at right angles)")
        object.__setattr__(self, "corners", c)
        object.__setattr__(self, "parking_type", ParkingType.parse(self.parking_type))
        if self.entrance not in (0, 1, 2, 3):
            raise ValueError(f"slot.entrance: edge index in 0..3, got {self.entrance!r}")
        if self.road_heading is not None:
            object.__setattr__(self, "road_heading", wrap_angle(float(self.road_heading)))
        along, across = float(sides[self.entrance]), float(sides[(self.entrance + 1) % 4])
        parallel = self.parking_type is ParkingType.PARALLEL
        if math.isnan(self.length):
            object.__setattr__(self, "length", along if parallel else across)
        if math.isnan(self.width):
            object.__setattr__(self, "width", across if parallel else along)

    @property
    def centre(self) -> np.ndarray:
        return self.corners.mean(axis=0)

    def outward(self) -> np.ndarray:
        """Unit normal of the entrance edge, pointing out of the slot."""
        a, b = self.corners[self.entrance], self.corners[(self.entrance + 1) % 4]
        d = b - a
        n = np.array([d[1], -d[0]]) / np.hypot(*d)
        return n if n @ (a - self.centre) > 0 else -n

    def edge_names(self, target_heading: float) -> tuple[str, ...]:
        """Names of edges 0-3 for the ISO criteria: ``entrance``, ``back`` and, for parallel,
        ``front``/``rear`` (ahead of / behind the parked car), else ``left``/``right`` (as
        seen from the parked car)."""
        names = [""] * 4
        names[self.entrance], names[(self.entrance + 2) % 4] = "entrance", "back"
        u = np.array([math.cos(target_heading), math.sin(target_heading)])
        left = np.array([-u[1], u[0]])
        for i in ((self.entrance + 1) % 4, (self.entrance + 3) % 4):
            mid = 0.5 * (self.corners[i] + self.corners[(i + 1) % 4]) - self.centre
            if self.parking_type is ParkingType.PARALLEL:
                names[i] = "front" if mid @ u > 0 else "rear"
            else:
                names[i] = "left" if mid @ left > 0 else "right"
        if len(set(names)) != 4:
            raise ValueError("slot: the target heading does not line up with the slot's sides")
        return tuple(names)


@dataclass(frozen=True, eq=False)
class Layout:
    """One parking scene as data (see the module docstring). Poses are rear-axle (x, y,
    theta) in metres and radians; headings are wrapped to [-pi, pi)."""

    obstacles: tuple[np.ndarray, ...]
    start: tuple[float, float, float]
    target: tuple[float, float, float]
    slot: Slot | None = None
    boundary: np.ndarray | None = None
    name: str = "layout"
    bounds: tuple[float, float, float, float] | None = None  # x_min, x_max, y_min, y_max: the rear axle's box
    road_width: float = 0.0  # depth of the road beside the slot where known (the grid's RW)
    origin: tuple[float, float] = (0.0, 0.0)  # where this frame's origin lies in the source file's
    scenario: Scenario | None = None  # the grid case this layout is, if any
    vehicle: VehicleParams | None = None  # the car this scene is for (None: the environment's)

    def __post_init__(self) -> None:
        obs = tuple(_polygon(f"obstacles[{i}]", p) for i, p in enumerate(self.obstacles))
        object.__setattr__(self, "obstacles", obs)
        object.__setattr__(self, "start", _pose("start", self.start))
        object.__setattr__(self, "target", _pose("target", self.target))
        if self.boundary is not None:
            object.__setattr__(self, "boundary", _polygon("boundary", self.boundary))
        if self.bounds is not None:
            b = tuple(float(v) for v in self.bounds)
            if len(b) != 4 or not all(math.isfinite(v) for v in b) or b[0] >= b[1] or b[2] >= b[3]:
                raise ValueError(f"bounds: expected finite (x_min, x_max, y_min, y_max) with min < max, got {b}")
            object.__setattr__(self, "bounds", b)
        if not self.name or not isinstance(self.name, str):
            raise ValueError(f"name: a non-empty string, got {self.name!r}")
        if len(self.name) > NAME_MAX or not self.name.isprintable():
            raise ValueError(
                f"name: at most {NAME_MAX} printable characters (it names rows and files), got "
                f"{len(self.name)} characters{'' if self.name.isprintable() else ' with control characters'}"
            )
        if self.vehicle is not None and not isinstance(self.vehicle, VehicleParams):
            raise ValueError(f"vehicle: a VehicleParams (vehicle.vehicle_named), got {type(self.vehicle).__name__}")

    @property
    def case_id(self) -> str:
        return self.scenario.case_id if self.scenario is not None else self.name

    @cached_property
    def parts(self) -> tuple[tuple[np.ndarray, ...], ...]:
        """Each obstacle's convex parts (the wall outside the boundary last)."""
        out = []
        for i, p in enumerate(self.obstacles):
            try:
                out.append(tuple(convex_parts(p)))
            except ValueError as err:
                raise ValueError(f"obstacles[{i}]: {err}") from None
        if self.boundary is not None:
            out.append(tuple(_wall_outside(self.boundary)))
        return tuple(out)

    def scene_bounds(self) -> tuple[float, float, float, float]:
        """The box the rear axle stays in: ``bounds`` if given, else everything in the layout
        padded by ``SCENE_PAD``."""
        if self.bounds is not None:
            return self.bounds
        pts = [np.asarray(self.start[:2])[None], np.asarray(self.target[:2])[None], *self.obstacles]
        if self.boundary is not None:
            pts.append(self.boundary)
        if self.slot is not None:
            pts.append(self.slot.corners)
        a = np.concatenate(pts)
        lo, hi = a.min(axis=0) - SCENE_PAD, a.max(axis=0) + SCENE_PAD
        return (float(lo[0]), float(hi[0]), float(lo[1]), float(hi[1]))

    def build(self, vehicle: VehicleParams | None = None) -> ScenarioGeometry:
        """The geometry of this layout for ``vehicle`` (default: the layout's own car, else the
        paper's); raises ``ValueError`` naming what is wrong."""
        vehicle = vehicle or self.vehicle or VehicleParams.table_ii()
        slot, edges, ptype, sl, sw = None, (), None, math.nan, math.nan
        if self.slot is not None:
            s = self.slot
            names = s.edge_names(self.target[2])
            slot, ptype, sl, sw = s.corners, s.parking_type, s.length, s.width
            edges = tuple((names[i], inward_half_plane(slot[i], slot[(i + 1) % 4], s.centre)) for i in range(4))
        g = ScenarioGeometry(
            vehicle=vehicle,
            obstacles=ConvexSet.from_polygons([q for ps in self.parts for q in ps]),
            slot=slot,
            slot_edges=edges,
            start=VehicleState(*self.start),
            target=self.target,
            bounds=self.scene_bounds(),
            road_width=self.road_width,
            parking_type=ptype,
            slot_length=sl,
            slot_width=sw,
            scenario=self.scenario,
            layout=self,
        )
        for what, pose in (("start", self.start), ("target", self.target)):
            depth = g.checker.penetration(*pose)[0] if len(g.obstacles) else np.zeros(1)
            if depth.max() > OVERLAP_TOL:
                k = int(np.argmax(depth))
                raise ValueError(f"{self.name}: {what}: the car at {pose} overlaps obstacle part {k}")
        if edges:
            body = footprint(vehicle, *self.target)
            if min(float(np.min(hp.signed_distance(body))) for _, hp in edges) < -OVERLAP_TOL:
                raise ValueError(f"{self.name}: target: the car at the target pose is not inside the slot")
        return g

    def check(self, vehicle: VehicleParams | None = None) -> ScenarioGeometry:
        """The geometry for ``vehicle`` (``build``: by default the layout's own car; it refuses
        a car overlapping an obstacle at the start or target), after ``check_placement``."""
        self.check_placement()
        return self.build(vehicle)

    def check_placement(self) -> None:
        """Refuse a scene no car can start in: coordinates farther than ``MAX_EXTENT`` from the
        target, or a start or target whose rear axle lies outside the scene's bounds or its
        drivable boundary. Raises ``ValueError`` naming the problem."""
        pts = [np.asarray([self.start[:2], self.target[:2]]), *self.obstacles]
        if self.boundary is not None:
            pts.append(self.boundary)
        far = float(np.abs(np.concatenate(pts) - np.asarray(self.target[:2])).max())
        if not far <= MAX_EXTENT:
            raise ValueError(
                f"coordinates: all must lie within {MAX_EXTENT:g} m of the target, one lies {far:.3g} m off"
            )
        x0, x1, y0, y1 = self.scene_bounds()
        for what, (x, y, _) in (("start", self.start), ("target", self.target)):
            if not (x0 <= x <= x1 and y0 <= y <= y1):
                raise ValueError(
                    f"{what}: the rear axle at ({x:g}, {y:g}) lies outside the scene's bounds {self.bounds}"
                )
            if self.boundary is not None and not _covers(self.boundary, (x, y)):
                raise ValueError(f"{what}: the rear axle at ({x:g}, {y:g}) lies outside the drivable boundary")

    def recentred(self, beyond: float = 1000.0) -> Layout:
        """This layout moved so that the target lies at the origin, if anything in it lies
        farther than ``beyond`` metres from the origin (coordinates thousands of metres away
        cost precision in every product); ``origin`` keeps where the frame was."""
        far = max(np.abs(np.concatenate([*self.obstacles, np.asarray([self.start[:2], self.target[:2]])])).max(), 0.0)
        if far <= beyond:
            return self
        o = np.array([round(self.target[0]), round(self.target[1])], dtype=float)  # whole metres: exact shifts
        sh = lambda p: np.asarray(p, float) - o  # noqa: E731
        slot = None
        if self.slot is not None:
            s = self.slot
            slot = Slot(sh(s.corners), s.parking_type, s.entrance, s.road_heading)
        return Layout(
            obstacles=tuple(sh(p) for p in self.obstacles),
            start=(self.start[0] - o[0], self.start[1] - o[1], self.start[2]),
            target=(self.target[0] - o[0], self.target[1] - o[1], self.target[2]),
            slot=slot,
            boundary=None if self.boundary is None else sh(self.boundary),
            name=self.name,
            bounds=None
            if self.bounds is None
            else (self.bounds[0] - o[0], self.bounds[1] - o[0], self.bounds[2] - o[1], self.bounds[3] - o[1]),
            road_width=self.road_width,
            origin=(float(self.origin[0] + o[0]), float(self.origin[1] + o[1])),
            vehicle=self.vehicle,
        )


def _covers(polygon: np.ndarray, point) -> bool:
    """Whether ``polygon`` holds ``point`` (its edge included)."""
    from shapely.geometry import Point, Polygon

    return bool(Polygon(polygon).covers(Point(point)))


def _wall_outside(boundary: np.ndarray) -> list[np.ndarray]:
    """Convex parts of a band ``BOUNDARY_DEPTH`` wide around the outside of ``boundary``."""
    from shapely.geometry import Polygon

    inner = Polygon(boundary)
    if not inner.is_valid or inner.area <= 0:
        raise ValueError("boundary: not a simple polygon of positive area")
    outer = inner.buffer(BOUNDARY_DEPTH, join_style="mitre").envelope
    return convex_parts(Polygon(outer.exterior.coords, holes=[inner.exterior.coords]))
