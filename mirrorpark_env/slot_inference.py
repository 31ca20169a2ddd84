"""The target slot of a layout that names none (TPCAP's cases give only poses and obstacles).

The ISO criteria and the mirror planner need a slot: a rectangle, its entrance and its
type. A TPCAP-style case parks the car among obstacles, so the slot is read off them:

1. The car's outline at the target pose; from each of its four sides, the free distance
   outward to the nearest obstacle within ``REACH`` (exact, with shapely).
2. The entrance is the side with the most free distance (ties: the side whose opposite
   side is nearer, a slot's back being its closest side; then the side facing the start);
   the car's left or right side makes a parallel slot, its front a reverse or angle slot
   (the car reversed in, as in the paper's cases). An entrance at the car's rear (parked
   nose-in) is not a type the criteria define: no slot is inferred. Nor is one where fewer
   than two of the three other sides meet an obstacle within ``REACH``: a target in open
   space, or beside a single wall, has no slot (its target pose is the goal).
3. The slot is centred on the car, as the grid's slots are on their target: along each
   axis it reaches as far as the nearer obstacle on the two closed sides allows, at most
   ``MAX_ALONG`` (lengthwise) and ``MAX_ACROSS`` (crosswise) beyond the car, and the
   entrance lies as far from the car as the side opposite it.
4. Reverse or angle: by the angle between the slot's axis and the start heading (the road's
   direction where the car starts): below 67.5 deg it is an angle slot, else reverse.
"""

from __future__ import annotations

import math

import numpy as np

from .config import ParkingType
from .layout import Slot
from .vehicle import VehicleParams

REACH = 3.0  # [m] how far from the car the obstacles are looked for
MAX_ALONG = 2.5  # [m] the slot ends at most this far ahead of / behind the car
MAX_ACROSS = 1.0  # [m] the slot's sides at most this far beside the car
OPEN = 1.0  # [m] an entrance needs at least this much free space
ANGLE_BELOW = math.radians(67.5)


def side_gaps(obstacles, target, vehicle: VehicleParams, reach: float = REACH) -> dict[str, float]:
    """Free distance from each side of the car's outline at ``target`` to the obstacles
    (``reach`` where none is nearer)."""
    from shapely import make_valid
    from shapely.geometry import LineString, Polygon
    from shapely.ops import unary_union

    x, y, th = target
    u = np.array([math.cos(th), math.sin(th)])
    v = np.array([-u[1], u[0]])
    p = np.array([x, y])
    f, r, hw = vehicle.front_length, vehicle.rear_overhang, 0.5 * vehicle.width
    fl, fr, rl, rr = p + f * u + hw * v, p + f * u - hw * v, p - r * u + hw * v, p - r * u - hw * v
    sides = {"front": (fl, fr, u), "rear": (rl, rr, -u), "left": (rl, fl, v), "right": (rr, fr, -v)}
    # make_valid: a self-intersecting ring is the loader's to refuse, by name; it must not
    # stop the inference first with shapely's own error.
    world = unary_union([make_valid(Polygon(q)) for q in obstacles]) if len(obstacles) else None
    gaps = {}
    for name, (a, b, d) in sides.items():
        if world is None:
            gaps[name] = reach
            continue
        strip = Polygon([a, b, b + reach * d, a + reach * d])
        hit = world.intersection(strip)
        gaps[name] = reach if hit.is_empty else float(min(reach, hit.distance(LineString([a, b]))))
    return gaps


def infer_slot(obstacles, start, target, vehicle: VehicleParams | None = None) -> tuple[Slot | None, str]:
    """The slot read off the obstacles around ``target`` (see the module docstring), and
    a one-line account of it (or of why there is none)."""
    vehicle = vehicle or VehicleParams.table_ii()
    gaps = side_gaps(obstacles, target, vehicle)
    x, y, th = target
    u = np.array([math.cos(th), math.sin(th)])
    v = np.array([-u[1], u[0]])
    toward_start = np.array(start[:2]) - np.array([x, y])
    out_dir = {"front": u, "rear": -u, "left": v, "right": -v}
    opposite = {"front": "rear", "rear": "front", "left": "right", "right": "left"}
    # Ties: the side whose opposite is nearer (a slot's back is its closest side), then the
    # side facing the start.
    entrance = max(
        gaps, key=lambda s: (round(gaps[s], 6), -round(gaps[opposite[s]], 6), float(out_dir[s] @ toward_start))
    )
    if gaps[entrance] < OPEN:
        return None, f"no side of the car at the target has {OPEN} m free: no entrance"
    closed = [s for s in gaps if s != entrance and gaps[s] < REACH]
    if len(closed) < 2:
        return None, f"{len(closed)} side(s) of the car at the target meet an obstacle within {REACH} m: open space"
    if entrance == "rear":
        return None, "the free side is behind the car at the target (nose-in): no slot type fits"
    return _slot(gaps, entrance, start, target, vehicle)


def planning_slot(obstacles, start, target, vehicle: VehicleParams) -> tuple[Slot | None, str]:
    """A slot for a planner that needs one where the scene has none (a target in open space):
    the rectangle around the car at ``target`` that ``infer_slot`` would draw, with its
    entrance on the side the car comes from (left, right or front, of those with ``OPEN``
    m free, the one facing the start most: the parking type follows from the target's
    heading against the way in). It is the planner's frame only: the scene's verdicts stay
    those of a target without a slot. None where no such side is free."""
    gaps = side_gaps(obstacles, target, vehicle)
    x, y, th = target
    u = np.array([math.cos(th), math.sin(th)])
    v = np.array([-u[1], u[0]])
    toward = np.array(start[:2]) - np.array([x, y])
    out_dir = {"front": u, "left": v, "right": -v}
    free = [s for s in out_dir if gaps[s] >= OPEN]
    if not free:
        return None, f"no side of the car at the target but its rear has {OPEN} m free"
    entrance = max(free, key=lambda s: (round(float(out_dir[s] @ toward), 6), gaps[s]))
    return _slot(gaps, entrance, start, target, vehicle)


def _slot(gaps: dict[str, float], entrance: str, start, target, vehicle: VehicleParams) -> tuple[Slot, str]:
    """The slot centred on the car at ``target`` with ``entrance`` (rules 3 and 4 above)."""
    x, y, th = target
    u = np.array([math.cos(th), math.sin(th)])
    v = np.array([-u[1], u[0]])
    L, W = vehicle.length, vehicle.width
    c = np.array([x, y]) + vehicle.center_offset * u
    if entrance in ("left", "right"):
        ptype = ParkingType.PARALLEL
        half_l = 0.5 * L + min(gaps["front"], gaps["rear"], MAX_ALONG)
        closed = "right" if entrance == "left" else "left"
        half_w = 0.5 * W + min(gaps[closed], MAX_ACROSS)
    else:
        axis_angle = abs(math.atan2(math.sin(th - start[2]), math.cos(th - start[2])))
        acute = min(axis_angle, math.pi - axis_angle)
        ptype = ParkingType.ANGLE if acute < ANGLE_BELOW else ParkingType.REVERSE
        half_l = 0.5 * L + min(gaps["rear"], MAX_ALONG)
        half_w = 0.5 * W + min(gaps["left"], gaps["right"], MAX_ACROSS)
    corners = {
        "front": (c + half_l * u + half_w * v, c + half_l * u - half_w * v),
        "left": (c - half_l * u + half_w * v, c + half_l * u + half_w * v),
        "right": (c + half_l * u - half_w * v, c - half_l * u - half_w * v),
    }[entrance]
    a, b = corners
    d = c - 0.5 * (a + b)  # from the entrance's middle to the centre: the other two corners
    rect = np.array([a, b, b + 2 * d, a + 2 * d])
    road = th if ptype is ParkingType.PARALLEL else None
    slot = Slot(rect, ptype, entrance=0, road_heading=road)
    how = (
        f"{ptype.value} slot {slot.length:.2f} x {slot.width:.2f} m, entrance at the car's {entrance} "
        f"(free {gaps[entrance]:.2f} m)"
    )
    return slot, how
