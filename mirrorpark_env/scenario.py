"""Parking scenarios (Table III factors) and the geometry they build.

World frame (docs/design.md): the road runs along +X; the slot lies on the -Y side
of the slot line Y = 0; the road strip is 0 <= Y <= RW. The slot's entrance on Y = 0
runs from X = 0 to X = E (E = SL for parallel, SW for reverse, SW * sqrt(2) for the 45
deg angle slot). The car starts with its rear axle at (E + start_x_offset, y0), heading
theta0 (> 0 turns the nose away from the slot): it has just driven past the slot.
The angle slot is an SW x SL rectangle at 45 deg (its axis points down-left, so the car
reverses in and ends heading 45 deg); its side lines meet Y = 0 at X = 0 and X = E.

Infeasible regions, all convex (each is a constraint the planners see):
the two neighbours of the slot (parked cars / kerb stones) left and right of it, the
region behind the slot, and the far road boundary beyond Y = RW. They extend
``scene_margin`` metres along the road beyond the slot.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

import numpy as np

from .config import ParkingType
from .layout import Layout, Slot
from .scene import ScenarioGeometry
from .vehicle import VehicleParams, footprint

SQRT2 = math.sqrt(2.0)
DEPTH_BEYOND = 3.0  # [m] thickness of the regions behind the slot and beyond the road


def _finite(name: str, value: object) -> float:
    try:
        f = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise ValueError(f"{name}: expected a number, got {value!r}") from None
    if not math.isfinite(f):
        raise ValueError(f"{name}: must be a finite number, got {value!r}")
    return f


@dataclass(frozen=True)
class Scenario:
    """One parking case: type, road width, slot size and the car's start.

    Lengths in metres, ``theta0`` in radians (use ``Scenario.from_degrees`` at the edges).
    """

    parking_type: ParkingType
    road_width: float
    slot_length: float
    slot_width: float
    theta0: float
    y0: float
    start_x_offset: float = 0.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "parking_type", ParkingType.parse(self.parking_type))
        for name in ("road_width", "slot_length", "slot_width", "theta0", "y0", "start_x_offset"):
            object.__setattr__(self, name, _finite(name, getattr(self, name)))
        for name in ("road_width", "slot_length", "slot_width"):
            v = getattr(self, name)
            if not 0 < v <= 50:
                raise ValueError(f"{name}: must be in (0, 50] m, got {v}")
        if not -math.pi <= self.theta0 <= math.pi:
            raise ValueError(f"theta0: must be in [-pi, pi] rad ([-180, 180] deg), got {self.theta0}")
        if not 0 <= self.y0 <= self.road_width:
            raise ValueError(f"y0: must be in [0, road_width={self.road_width}] m, got {self.y0}")

    @classmethod
    def from_degrees(
        cls,
        parking_type: str | ParkingType,
        road_width: float,
        slot_length: float,
        slot_width: float,
        theta0_deg: float,
        y0: float,
        start_x_offset: float = 0.0,
    ) -> Scenario:
        theta0_deg = _finite("theta0_deg", theta0_deg)
        return cls(parking_type, road_width, slot_length, slot_width, math.radians(theta0_deg), y0, start_x_offset)

    @property
    def theta0_deg(self) -> float:
        return math.degrees(self.theta0)

    @property
    def case_id(self) -> str:
        """Stable, readable name, e.g. ``parallel_rw4.50_sl3.82_sw2.50_th-90_y0.00``.

        Grid values print at the grid's precision (cm, whole degrees); any other value
        with as many digits as it needs (up to 1e-6), so that distinct cases get distinct
        ids. A run uses the scenario's own values, never ones parsed back from its id.
        """
        cid = (
            f"{self.parking_type.value}_rw{_fmt(self.road_width, 2)}_sl{_fmt(self.slot_length, 2)}"
            f"_sw{_fmt(self.slot_width, 2)}_th{_fmt(self.theta0_deg, 0, sign=True)}_y{_fmt(self.y0, 2)}"
        )
        if self.start_x_offset != 0.0:
            cid += f"_dx{_fmt(self.start_x_offset, 2, sign=True)}"
        return cid

    @classmethod
    def from_case_id(cls, case_id: str) -> Scenario:
        m = _CASE_ID.fullmatch(case_id.strip())
        if not m:
            raise ValueError(
                f"case id: cannot parse {case_id!r}; expected e.g. 'reverse_rw6.00_sl4.82_sw2.17_th+10_y2.50'"
            )
        g = m.groupdict()
        return cls.from_degrees(
            g["type"],
            float(g["rw"]),
            float(g["sl"]),
            float(g["sw"]),
            float(g["th"]),
            float(g["y"]),
            float(g["dx"] or 0.0),
        )

    @property
    def entrance_length(self) -> float:
        """Length of the slot's opening along the slot line Y = 0."""
        if self.parking_type is ParkingType.PARALLEL:
            return self.slot_length
        if self.parking_type is ParkingType.REVERSE:
            return self.slot_width
        return self.slot_width * SQRT2

    def build(self, vehicle: VehicleParams | None = None, scene_margin: float = 25.0) -> ScenarioGeometry:
        """The scenario's geometry for ``vehicle``; raises ``ValueError`` if it cannot exist."""
        return build_geometry(self, vehicle or VehicleParams.table_ii(), scene_margin)


_CASE_ID = re.compile(
    r"(?P<type>[a-z]+)_rw(?P<rw>[-\d.]+)_sl(?P<sl>[-\d.]+)_sw(?P<sw>[-\d.]+)"
    r"_th(?P<th>[-+\d.]+)_y(?P<y>[-\d.]+)(?:_dx(?P<dx>[-+\d.]+))?"
)


def _rect(x0: float, x1: float, y0: float, y1: float) -> np.ndarray:
    return np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]])


def start_fits_road(vehicle: VehicleParams, theta0, y0, road_width, tol: float = 1e-9) -> np.ndarray:
    """docs/design.md, "The grid": all four start corners lie in the road strip 0 <= Y <= RW."""
    ys = footprint(vehicle, np.zeros_like(np.asarray(y0, float)), y0, theta0)[..., 1]
    return (ys.min(axis=-1) >= -tol) & (ys.max(axis=-1) <= np.asarray(road_width) + tol)


ID_PRECISION = 1e-9  # values closer than this share a case id (the grid's steps carry float noise below it)


def _fmt(value: float, decimals: int, sign: bool = False) -> str:
    """``value`` with ``decimals`` decimals if that is exact to ``ID_PRECISION``, else to 1e-9
    with trailing zeros (and a trailing point) dropped."""
    plus = "+" if sign else ""
    s = f"{value:{plus}.{decimals}f}"
    if abs(float(s) - value) <= ID_PRECISION:
        return s
    return f"{value:{plus}.9f}".rstrip("0").rstrip(".")


def slot_fits_car(vehicle: VehicleParams, slot_length: float, slot_width: float) -> bool:
    """The car's outline fits the slot at all (in its length and width along the slot's)."""
    return slot_length >= vehicle.length - 1e-9 and slot_width >= vehicle.width - 1e-9


def build_geometry(sc: Scenario, vehicle: VehicleParams, scene_margin: float = 25.0) -> ScenarioGeometry:
    """The geometry of grid case ``sc``: its layout (``grid_layout``), built."""
    return grid_layout(sc, vehicle, scene_margin).build(vehicle)


def grid_layout(sc: Scenario, vehicle: VehicleParams, scene_margin: float = 25.0) -> Layout:
    """Slot, infeasible regions, start and target of ``sc`` as a layout."""
    t, rw, sl, sw = sc.parking_type, sc.road_width, sc.slot_length, sc.slot_width
    L, D = scene_margin, DEPTH_BEYOND
    car_len, car_w = vehicle.length, vehicle.width
    if not slot_fits_car(vehicle, sl, sw):
        if t is ParkingType.PARALLEL:
            need = f"slot_length >= car length {car_len:.2f} m and slot_width >= car width {car_w:.2f} m"
        else:
            need = f"slot_width >= car width {car_w:.2f} m and slot_length >= car length {car_len:.2f} m"
        raise ValueError(f"slot too small for the car: {t.value} slot {sl:.2f} x {sw:.2f} m needs {need}")
    if not bool(start_fits_road(vehicle, sc.theta0, sc.y0, rw)):
        raise ValueError(
            f"y0={sc.y0} m, theta0={sc.theta0_deg:.1f} deg: the start footprint leaves the road "
            f"strip 0 <= Y <= road_width={rw} m, so this case cannot be generated"
        )

    E = sc.entrance_length
    off = vehicle.center_offset
    if t is ParkingType.PARALLEL:
        slot = _rect(0.0, sl, -sw, 0.0)
        depth = sw
        target_c = (sl / 2, -sw / 2)
        heading = 0.0
        names = ("back", "front", "entrance", "rear")  # edges of `slot` in CCW order
    elif t is ParkingType.REVERSE:
        slot = _rect(0.0, sw, -sl, 0.0)
        depth = sl
        target_c = (sw / 2, -sl / 2)
        heading = math.pi / 2
        names = ("back", "right", "entrance", "left")
    else:
        # An SW x SL rectangle whose axis points 45 deg down-left into the slot; its
        # entrance edge (perpendicular to the axis) has its left corner on Y = 0.
        axis = np.array([-1.0, -1.0]) / SQRT2
        ent_a = np.zeros(2)
        ent_b = np.array([sw, -sw]) / SQRT2
        slot = np.array([ent_a, ent_a + sl * axis, ent_b + sl * axis, ent_b])
        depth = (sl + sw) / SQRT2
        target_c = (float(slot[:, 0].mean()), float(slot[:, 1].mean()))
        heading = math.pi / 4
        names = ("left", "back", "right", "entrance")
    x_lo, x_hi = min(-L, float(slot[:, 0].min()) - L), E + L
    b = depth + D
    if t is ParkingType.ANGLE:  # neighbours bounded by the slot's 45 deg side lines
        neighbours = [
            np.array([[0.0, 0.0], [x_lo, 0.0], [x_lo, -b], [-b, -b]]),
            np.array([[E, 0.0], [E - b, -b], [x_hi, -b], [x_hi, 0.0]]),
        ]
        k = sw + 2 * D  # deep enough to meet the bottom of the neighbours
        behind = np.array([slot[1], slot[1] + k * axis, slot[2] + k * axis, slot[2]])
    else:
        neighbours = [_rect(x_lo, 0.0, -b, 0.0), _rect(E, x_hi, -b, 0.0)]
        behind = _rect(x_lo, x_hi, -depth - D, -depth)
    regions = neighbours + [
        behind,
        _rect(x_lo, x_hi, rw, rw + D),  # beyond the far road boundary
    ]
    tx = target_c[0] - off * math.cos(heading)
    ty = target_c[1] - off * math.sin(heading)
    lo, hi = x_lo + car_len - E, x_hi - car_len - E  # the env's scene: rear axle a car length inside its ends
    if not lo < sc.start_x_offset < hi:
        raise ValueError(
            f"start_x_offset: must be in ({lo:.2f}, {hi:.2f}) m for this scene "
            f"(scene_margin={scene_margin} m), got {sc.start_x_offset}"
        )
    entrance = names.index("entrance")
    return Layout(
        obstacles=tuple(regions),
        start=(E + sc.start_x_offset, sc.y0, sc.theta0),
        target=(tx, ty, heading),
        slot=Slot(slot, t, entrance, road_heading=0.0, length=sl, width=sw),
        name=sc.case_id,
        bounds=(x_lo + car_len, x_hi - car_len, -b, rw + D),  # the rear axle a car length inside the ends
        road_width=rw,
        scenario=sc,
    )
