"""Parking lots beyond the grid: seeded, at four levels of difficulty, as layouts.

A lot is an aisle (along +x in its own frame) with a row of parked cars below it, in
which one gap is the target slot; above the aisle a wall, from level 2 behind a second row
of parked cars (the aisle is the free width between the rows). The lot is then
turned and shifted into the world (and at level 2 and up, reflected half the time), so
that planners meet it in any frame. By level:

1. comfortable gaps (parallel 1.45-1.7 car lengths, perpendicular and angle the car's
   width + 0.7-1.0 m), a wide aisle (6.5-7.5 m), the start in the aisle near the slot,
   heading along it;
2. tighter gaps (parallel 1.3-1.45, the others + 0.45-0.7 m), aisles of 5.5-6.5 m, the
   start anywhere along the aisle, heading along it either way;
3. as 2, and pillars, irregular neighbours (triangles, notched and L-shaped outlines),
   the start at any heading, one lot in five a target in open space (no slot);
4. tight gaps (parallel 1.2-1.3, the others + 0.3-0.45 m), aisles of 4.5-5.5 m, the
   clutter of 3.

Gaps are drawn for the given car (the paper's by default); neighbours are 4.2-4.9 m by
1.75-1.95 m. ``generate_lot(seed, level)`` is deterministic: the same seed and level give
the same lot on any machine. ``mirrorpark lots`` writes them as layout files.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from .angles import wrap_angle
from .config import ParkingType
from .layout import Layout, Slot
from .vehicle import VehicleParams, footprint

LEVELS = (1, 2, 3, 4)
_PARALLEL_GAP = {1: (1.45, 1.7), 2: (1.3, 1.45), 3: (1.3, 1.45), 4: (1.2, 1.3)}  # x car length
_SIDE_GAP = {1: (0.7, 1.0), 2: (0.45, 0.7), 3: (0.45, 0.7), 4: (0.3, 0.45)}  # [m] beyond the car's width
_AISLE = {1: (6.5, 7.5), 2: (5.5, 6.5), 3: (5.5, 6.5), 4: (4.5, 5.5)}  # [m]
_DEPTH = 5.5  # [m] a perpendicular or angle bay's depth
_TRIES = 50  # starts drawn before a lot is redrawn


def generate_lot(seed: int, level: int, vehicle: VehicleParams | None = None) -> Layout:
    """The lot of ``seed`` at ``level`` (1-4) for ``vehicle``; raises ``ValueError`` on a bad
    level or seed."""
    if level not in LEVELS:
        raise ValueError(f"level: one of {LEVELS}, got {level!r}")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed: a whole number >= 0, got {seed!r}")
    car = vehicle or VehicleParams.table_ii()
    rng = np.random.default_rng([int(seed), level])
    for _ in range(_TRIES):
        lot = _draw(rng, level, car, f"lot-L{level}-{seed}")
        if lot is not None:
            return lot
    raise RuntimeError(f"lot {seed} at level {level}: no clear start in {_TRIES} draws")  # pragma: no cover


def _draw(rng: np.random.Generator, level: int, car: VehicleParams, name: str) -> Layout | None:
    kind = rng.choice(["parallel", "reverse", "angle"])
    open_space = level >= 3 and rng.random() < 0.2
    aisle = rng.uniform(*_AISLE[level])
    if kind == "parallel":
        obstacles, slot, target = _parallel_row(rng, level, car)
    else:
        obstacles, slot, target = _bay_row(rng, level, car, ParkingType(kind))
    if open_space:  # the row's gap becomes open ground: no neighbours within reach, no slot
        obstacles = [p for p in obstacles if np.abs(p[:, 0] - target[0]).min() > 4.0]
        slot = None
    far = aisle  # the wall's near edge: the aisle's far side, or behind the row across it
    if level >= 2:
        obstacles += _far_row(rng, aisle)
        far = aisle + 2.2
    obstacles.append(_box(-30.0, 30.0, far, far + 0.5))
    if level >= 3:
        obstacles += _pillars(rng, aisle)
    start = _start(rng, level, car, aisle, target, obstacles)
    if start is None:
        return None
    lot = Layout(tuple(obstacles), start, target, slot=slot, name=name, vehicle=car)
    return _placed(rng, level, lot)


def _neighbour(rng: np.random.Generator, level: int, x0: float, x1: float, y0: float, y1: float) -> np.ndarray:
    """A parked car filling the box, or at level 3 and up sometimes an irregular outline in it."""
    shape = rng.choice(["box", "triangle", "notch", "ell"]) if level >= 3 and rng.random() < 0.4 else "box"
    xm, ym = 0.5 * (x0 + x1), 0.5 * (y0 + y1)
    if shape == "triangle":  # its apex at the box's middle, on one end or the other at random
        return (
            np.array([(x0, y0), (x1, ym), (x0, y1)]) if rng.random() < 0.5 else np.array([(x1, y0), (x1, y1), (x0, ym)])
        )
    if shape == "notch":
        d = 0.3 * (x1 - x0)
        return np.array(
            [
                (x0, y0),
                (x1, y0),
                (x1, y1),
                (xm + 0.3, y1),
                (xm + 0.3, y1 - d),
                (xm - 0.3, y1 - d),
                (xm - 0.3, y1),
                (x0, y1),
            ]
        )
    if shape == "ell":
        return np.array([(x0, y0), (x1, y0), (x1, ym), (xm, ym), (xm, y1), (x0, y1)])
    return _box(x0, x1, y0, y1)


def _parallel_row(rng, level, car):
    """Cars along the aisle's lower edge (y from -depth to 0), a kerb below; the gap at x = 0."""
    gap = rng.uniform(*_PARALLEL_GAP[level]) * car.length
    depth = car.width + rng.uniform(0.35, 0.6)
    obstacles = [_box(-30.0, 30.0, -depth - 0.5, -depth)]  # the kerb
    for side in (-1.0, 1.0):
        x = 0.5 * gap if side > 0 else -0.5 * gap
        for _ in range(3):
            length, width, space = rng.uniform(4.2, 4.9), rng.uniform(1.75, 1.95), rng.uniform(0.5, 1.2)
            near, far = (x, x + side * length)
            y0 = -depth + rng.uniform(0.05, 0.2)
            obstacles.append(_neighbour(rng, level, min(near, far), max(near, far), y0, y0 + width))
            x = far + side * space
    slot = Slot(
        np.array([(-0.5 * gap, 0.0), (0.5 * gap, 0.0), (0.5 * gap, -depth), (-0.5 * gap, -depth)]), "parallel", 0, 0.0
    )
    target = (-car.center_offset, -0.5 * depth, 0.0)  # the body centred in the gap, heading along the aisle
    return obstacles, slot, target


def _bay_row(rng, level, car, kind: ParkingType):
    """Bays below the aisle, perpendicular (reverse) or at 45-60 deg (angle); the gap at x = 0."""
    width = car.width + rng.uniform(*_SIDE_GAP[level])
    tilt = math.pi / 2 if kind is ParkingType.REVERSE else math.radians(rng.uniform(45.0, 60.0))
    axis = np.array([math.cos(tilt), -math.sin(tilt)])  # into the bay, from its entrance
    across = np.array([math.sin(tilt), math.cos(tilt)])
    mouth = np.zeros(2)  # the entrance's middle, on the aisle's edge
    back = mouth + _DEPTH * axis
    h = 0.5 * width
    corners = np.array([mouth - h * across, mouth + h * across, back + h * across, back - h * across])
    obstacles = []
    for side in (-1.0, 1.0):
        for k in range(2):
            w, length = rng.uniform(1.75, 1.95), rng.uniform(4.2, 4.9)
            c = (
                mouth
                + side * (h + 0.1 + 0.5 * w + k * (w + rng.uniform(0.5, 0.9))) * across
                + (0.5 * length + 0.3) * axis
            )
            box = np.array(
                [
                    c + sa * 0.5 * w * across + sl * 0.5 * length * axis
                    for sa, sl in ((-1, -1), (1, -1), (1, 1), (-1, 1))
                ]
            )
            obstacles.append(box if level < 3 or rng.random() > 0.3 else _neighbour_in(rng, box))
    wall = back + 0.4 * axis
    obstacles.append(
        np.array(
            [wall - 12 * across, wall + 12 * across, wall + 12 * across + 0.5 * axis, wall - 12 * across + 0.5 * axis]
        )
    )
    slot = Slot(corners, kind, 0)
    heading = math.atan2(-axis[1], -axis[0])  # reversed in: nose out of the bay
    centre = mouth + 0.5 * _DEPTH * axis
    target = (
        centre[0] - car.center_offset * math.cos(heading),
        centre[1] - car.center_offset * math.sin(heading),
        heading,
    )
    return obstacles, slot, target


def _neighbour_in(rng: np.random.Generator, box: np.ndarray) -> np.ndarray:
    """An irregular outline inside a tilted car box: a triangle or a trimmed corner."""
    a, b, c, d = box
    if rng.random() < 0.5:
        return np.array([a, b, 0.5 * (c + d)])
    return np.array([a, b, c, d + 0.4 * (c - d), d + 0.4 * (a - d)])


def _far_row(rng, aisle: float) -> list[np.ndarray]:
    """Cars parked along the aisle's far side, beyond it (the aisle keeps its width), some
    gaps between them."""
    out, x = [], rng.uniform(-28.0, -22.0)
    while x < 24.0:
        length = rng.uniform(4.2, 4.9)
        if rng.random() < 0.8:
            out.append(_box(x, x + length, aisle + 0.1, aisle + rng.uniform(1.9, 2.1)))
        x += length + rng.uniform(0.6, 2.5)
    return out


def _pillars(rng, aisle: float) -> list[np.ndarray]:
    """Up to two pillars at the aisle's far edge, clear of the slot's approach (|x| > 6 m)."""
    out = []
    for _ in range(int(rng.integers(0, 3))):
        x = rng.choice([-1.0, 1.0]) * rng.uniform(6.0, 20.0)
        y = aisle - rng.uniform(0.4, 0.8)
        out.append(_box(x - 0.3, x + 0.3, y - 0.3, y + 0.3))
    return out


def _start(rng, level, car, aisle, target, obstacles) -> tuple[float, float, float] | None:
    """A start in the aisle, clear of every obstacle by 0.2 m; None if none is found."""
    from shapely.geometry import Polygon
    from shapely.ops import unary_union

    world = unary_union([Polygon(p) for p in obstacles])
    for _ in range(_TRIES):
        if level == 1:
            x, th = target[0] + rng.uniform(3.0, 9.0), rng.uniform(-0.15, 0.15)
        elif level == 2:
            x, th = target[0] + rng.uniform(-12.0, 12.0), rng.choice([0.0, math.pi]) + rng.uniform(-0.2, 0.2)
        else:
            x, th = target[0] + rng.uniform(-15.0, 15.0), rng.uniform(-math.pi, math.pi)
        y = rng.uniform(0.2 * aisle, 0.6 * aisle)
        body = footprint(car, x, y, th)
        if body[:, 1].min() < 0.1 or body[:, 1].max() > aisle - 0.1:
            continue
        if world.distance(Polygon(body)) > 0.2:
            return (float(x), float(y), float(wrap_angle(th)))
    return None


def _placed(rng: np.random.Generator, level: int, lot: Layout) -> Layout:
    """The lot turned by a random angle and shifted; at level 2 and up reflected half the time."""
    rot, shift = rng.uniform(-math.pi, math.pi), rng.uniform(-50.0, 50.0, size=2)
    reflect = level >= 2 and rng.random() < 0.5
    c, s = math.cos(rot), math.sin(rot)

    def pts(p):
        q = np.asarray(p, float) * (np.array([1.0, -1.0]) if reflect else 1.0)
        return np.stack([c * q[:, 0] - s * q[:, 1], s * q[:, 0] + c * q[:, 1]], axis=1) + shift

    def pose(p):
        th = -p[2] if reflect else p[2]
        x, y = pts([p[:2]])[0]
        return (float(x), float(y), float(wrap_angle(th + rot)))

    slot = None
    if lot.slot is not None:
        road = None if lot.slot.road_heading is None else pose((0.0, 0.0, lot.slot.road_heading))[2]
        slot = Slot(pts(lot.slot.corners), lot.slot.parking_type, lot.slot.entrance, road)
    return replace(
        lot, obstacles=tuple(pts(p) for p in lot.obstacles), start=pose(lot.start), target=pose(lot.target), slot=slot
    )


def _box(x0: float, x1: float, y0: float, y1: float) -> np.ndarray:
    return np.array([(x0, y0), (x1, y0), (x1, y1), (x0, y1)], float)
