"""Write the 20 TPCAP-format layouts of ``configs/layouts/tpcap/`` (deterministic).

TPCAP publishes its cases as CSV rows (start pose, target pose, obstacle polygons) that
we do not have; these are written in that format to test the reader and every planner on
scenes outside the grid: parallel, perpendicular and angle slots among parked cars,
pillars, kerbs and planters, drawn for TPCAP's car (4.689 m by 1.942 m, the car a TPCAP
file runs with). Slot sizes are given as for the paper's car (3.82 m by 1.67 m) and
enlarged by the difference: parallel lengths in proportion to the car's length,
perpendicular and angle widths by the difference in width, the angle slot's length by
the difference in length. Each scene is drawn in a local frame (road along +x, slot
below it, as in the grid) and then placed in the world by a rotation, a shift and, for
some, a reflection (the car then passes with the slot on its left). Three hold a
non-convex obstacle, two lie thousands of metres from the origin, and several headings
are written beyond +-pi, as TPCAP's files have them.

    python scripts/make_tpcap_layouts.py [OUT_DIR]
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np

L_OFF = 0.5 * (3.76 - 0.929)  # [m] rear axle to the body centre of TPCAP's car (front 3.76, rear 0.929)
CAR = (4.5, 1.8)  # [m] a parked neighbour's outline
LONGER = 4.689 / 3.82  # TPCAP's car against the paper's, in length
WIDER = 1.942 - 1.67  # [m] ... and in width


def rect(cx, cy, length, width, heading=0.0):
    c, s = math.cos(heading), math.sin(heading)
    pts = [(-length / 2, -width / 2), (length / 2, -width / 2), (length / 2, width / 2), (-length / 2, width / 2)]
    return [(cx + c * x - s * y, cy + s * x + c * y) for x, y in pts]


def box(x0, x1, y0, y1):
    return [(x0, y0), (x1, y0), (x1, y1), (x0, y1)]


def axle(cx, cy, heading):
    """Rear-axle pose of the paper's car whose body centre is (cx, cy)."""
    return (cx - L_OFF * math.cos(heading), cy - L_OFF * math.sin(heading), heading)


def parallel(sl, road, start, clutter=(), kerb=None):
    """Slot between two parked cars, from x = 0 to sl (given for the paper's car), the kerb
    2.2 m below the road edge."""
    sl = round(sl * LONGER, 3)
    obs = [rect(-2.35, -1.1, *CAR), rect(sl + 2.35, -1.1, *CAR), rect(-7.2, -1.1, *CAR)]
    obs.append(kerb if kerb is not None else box(-14.0, sl + 12.0, -3.0, -2.2))
    obs.append(box(-14.0, sl + 12.0, road, road + 0.6))  # the far side of the road
    obs += list(clutter)
    return obs, axle(sl / 2, -1.1, 0.0), start


def perpendicular(sw, aisle, start, clutter=(), back=None):
    """Slot between two cars parked side by side (x = 0 to sw, given for the paper's car), a
    wall 5.4 m deep."""
    sw = round(sw + WIDER, 3)
    obs = [
        rect(-1.0, -2.45, CAR[1], CAR[0]),
        rect(sw + 1.0, -2.45, CAR[1], CAR[0]),
        rect(sw + 3.3, -2.45, CAR[1], CAR[0]),
    ]
    obs.append(back if back is not None else box(-6.0, sw + 8.0, -6.0, -5.4))
    obs.append(box(-6.0, sw + 8.0, aisle, aisle + 0.6))
    obs += list(clutter)
    return obs, axle(sw / 2, -2.7, math.pi / 2), start


def angled(sw, aisle, start, clutter=()):
    """A 45 deg slot (the grid's angle geometry): width sw and 5.0 m long for the paper's
    car, cars either side."""
    sw = round(sw + WIDER, 3)
    depth = 5.0 + 4.689 - 3.82
    ax = np.array([-1.0, -1.0]) / math.sqrt(2)  # into the slot
    across = np.array([1.0, -1.0]) / math.sqrt(2)
    mid_entrance = 0.5 * sw * across
    centre = mid_entrance + 0.5 * depth * ax
    step = (0.5 * sw + 1.0) * across  # the neighbours' centres: 0.1 m beyond the slot's sides
    h = math.pi / 4
    far = step + 2.3 * across  # a third car beyond the right neighbour
    obs = [rect(*(centre - step), 4.5, 1.8, h), rect(*(centre + step), 4.5, 1.8, h), rect(*(centre + far), 4.5, 1.8, h)]
    obs.append(box(-12.0, 12.0, -6.2, -5.6))
    obs.append(box(-12.0, 12.0, aisle, aisle + 0.6))
    obs += list(clutter)
    return obs, axle(*centre, h), start


L_KERB = [(-14.0, -3.0), (12.0, -3.0), (12.0, 0.4), (11.2, 0.4), (11.2, -2.2), (-14.0, -2.2)]  # kerb turning up
U_GARAGE = [(-0.1, -6.0), (2.8, -6.0), (2.8, -0.3), (2.7, -0.3), (2.7, -5.9), (0.0, -5.9), (0.0, -0.3), (-0.1, -0.3)]
T_PILLAR = [(6.0, 4.9), (6.7, 4.9), (6.7, 4.5), (7.3, 4.5), (7.3, 4.9), (8.0, 4.9), (8.0, 5.5), (6.0, 5.5)]
PILLAR = lambda x, y: box(x - 0.35, x + 0.35, y - 0.35, y + 0.35)  # noqa: E731

# (name, builder, world rotation [rad], shift [m], reflect, heading offset written [rad])
CASES = [
    ("par01", lambda: parallel(6.0, 6.0, (8.0, 1.6, 0.0)), 0.0, (0.0, 0.0), False, 0.0),
    ("par02", lambda: parallel(5.5, 5.5, (7.5, 1.4, 0.05), [PILLAR(2.0, 4.9)]), 0.6, (12.0, -4.0), False, 0.0),
    ("par03", lambda: parallel(6.5, 6.5, (9.0, 2.0, -0.1), kerb=L_KERB), 1.9, (-30.0, 8.0), False, 2 * math.pi),
    ("par04", lambda: parallel(5.2, 5.0, (7.0, 1.3, 0.0)), -2.4, (3512.3, -1820.7), False, 0.0),
    ("par05", lambda: parallel(5.8, 6.0, (8.5, 1.8, 0.1), [PILLAR(9.5, 5.3)]), 3.0, (40.0, 40.0), True, -2 * math.pi),
    ("par06", lambda: parallel(7.0, 5.5, (9.5, 1.5, 0.0)), -0.8, (-5.0, -60.0), True, 0.0),
    ("par07", lambda: parallel(4.4, 6.0, (6.8, 1.4, 0.0)), 0.3, (0.0, 20.0), False, 0.0),  # tight: 1.2 car lengths
    ("per01", lambda: perpendicular(2.5, 6.0, (5.0, 3.0, 0.0)), 0.0, (0.0, 0.0), False, 0.0),
    ("per02", lambda: perpendicular(2.3, 6.5, (5.5, 3.2, 0.1), [PILLAR(-2.0, 6.0)]), 1.2, (20.0, 5.0), False, 0.0),
    (  # the U garage is 2.7 m wide inside: a slot of 2.428 m for the paper's car is 2.7 m for TPCAP's
        "per03",
        lambda: perpendicular(2.428, 6.0, (6.0, 3.0, 0.0), back=U_GARAGE),
        -1.0,
        (-8.0, 30.0),
        False,
        2 * math.pi,
    ),
    ("per04", lambda: perpendicular(2.6, 7.0, (5.0, 3.5, -0.15)), 2.2, (-2743.9, 4170.2), True, 0.0),
    ("per05", lambda: perpendicular(2.4, 5.5, (4.5, 2.8, 0.0), [T_PILLAR]), 0.5, (60.0, -15.0), False, 0.0),
    ("per06", lambda: perpendicular(2.2, 6.0, (5.0, 3.0, 0.2)), -2.9, (-40.0, -40.0), True, 4 * math.pi),
    (
        "per07",
        lambda: perpendicular(2.0, 6.0, (5.0, 3.0, 0.0)),
        0.9,
        (10.0, 90.0),
        False,
        0.0,
    ),  # narrow: 2.2 m between the cars
    ("ang01", lambda: angled(2.5, 6.0, (5.0, 3.0, 0.0)), 0.0, (0.0, 0.0), False, 0.0),
    ("ang02", lambda: angled(2.3, 5.5, (4.5, 2.8, 0.05), [PILLAR(-3.0, 5.0)]), 1.6, (-25.0, 12.0), False, 0.0),
    ("ang03", lambda: angled(2.7, 6.5, (5.5, 3.2, -0.1)), -1.3, (70.0, 70.0), True, -2 * math.pi),
    ("ang04", lambda: angled(2.4, 6.0, (6.0, 3.0, 0.0), [PILLAR(8.0, 5.5)]), 2.7, (-90.0, 25.0), False, 0.0),
    ("ang05", lambda: angled(2.6, 5.0, (4.5, 2.6, 0.1)), -0.4, (33.0, -77.0), True, 2 * math.pi),
    ("ang06", lambda: angled(2.5, 6.0, (5.0, 3.0, 0.0)), 0.75, (15.0, 15.0), False, 0.0),
]


def place(pts, rot, shift, reflect):
    p = np.asarray(pts, float)
    if reflect:
        p = p * np.array([-1.0, 1.0])
    c, s = math.cos(rot), math.sin(rot)
    return np.stack([c * p[:, 0] - s * p[:, 1] + shift[0], s * p[:, 0] + c * p[:, 1] + shift[1]], axis=1)


def place_pose(pose, rot, shift, reflect, offset):
    xy = place([pose[:2]], rot, shift, reflect)[0]
    th = (math.pi - pose[2] if reflect else pose[2]) + rot + offset
    return (float(xy[0]), float(xy[1]), th)


def row(obstacles, start, target) -> str:
    vals = [*start, *target, len(obstacles), *(len(p) for p in obstacles)]
    vals += [float(v) for p in obstacles for xy in p for v in xy]
    return ",".join(f"{v:.6f}" if isinstance(v, float) else str(v) for v in vals)


def main(out: Path) -> None:
    out.mkdir(parents=True, exist_ok=True)
    for name, build, rot, shift, reflect, offset in CASES:
        obs, target, start = build()
        world = [place(p, rot, shift, reflect) for p in obs]
        s = place_pose(start, rot, shift, reflect, offset)
        t = place_pose(target, rot, shift, reflect, -offset)
        (out / f"{name}.csv").write_text(row(world, s, t) + "\n")
    print(f"wrote {len(CASES)} layouts to {out}")


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else Path("configs/layouts/tpcap"))
