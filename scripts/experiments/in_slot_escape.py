"""How many arcs the way out of each short parallel slot takes, from the target.

The cost to go reaches the target of a tight slot only through exact multi-point turns
out of it (``planners/common/turns.py``: full-lock arcs in alternating gears, each driven
until it would come within a clearance). This prints, per parallel slot length of the
full grid up to ``--max-length``, whether such a turn leaves the slot within ``--arcs``
arcs (its heading turns past 45 degrees), how many arcs that takes and how many of them are
shorter than 10 cm, at the cost to go's settings and at finer ones, on the widest road of
the grid (4.5 m), where the road's far side is least in the way. It says why no
planner here parks the shortest slots that admit an ISO pose.

    python scripts/experiments/in_slot_escape.py [--max-length 4.62] [--arcs 100]
    python scripts/experiments/in_slot_escape.py --layout configs/layouts/tpcap/par07.csv --arcs 200
"""

from __future__ import annotations

import argparse
import math

import numpy as np

from evaluation.cases import from_sample
from mirrorpark_env.criteria import iso_pose_exists
from mirrorpark_env.layout_io import load_layout
from planners.common.clearance import gaps
from planners.common.turns import turn_chains
from planners.mirror.config import AimedConfig

OUT = math.radians(45.0)  # turned this far, the car is out of the slot's grip


def escape(geometry, radius: float, step: float, clearance: float, arcs: int) -> tuple[int, int] | None:
    """(arcs, arcs under 10 cm) of the shortest turn out of the slot; None: none leaves it."""
    checker = geometry.checker

    def first_bad(poses: np.ndarray, n: int) -> int:
        bad = np.flatnonzero(gaps(checker, poses, all_axes=True) < clearance)
        return int(bad[0]) if len(bad) else len(poses)

    th0 = float(geometry.target[2])
    best = None
    for chain, ends in turn_chains(tuple(float(t) for t in geometry.target), radius, step, arcs, first_bad):
        out = np.flatnonzero(np.abs(chain[np.asarray(ends), 2] - th0) >= OUT)
        if len(out) == 0:
            continue
        k = int(out[0]) + 1  # arcs driven until the heading is past OUT
        lengths = np.diff(np.concatenate([[0], np.asarray(ends[:k])])) * step
        if best is None or k < best[0]:
            best = (k, int(np.sum(lengths < 0.1)))
    return best


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--max-length", type=float, default=4.62, help="longest slot to look at [m]")
    ap.add_argument("--arcs", type=int, default=100, help="most arcs per turn")
    ap.add_argument("--layout", default=None, help="a layout file's target instead of the grid's slots")
    a = ap.parse_args()
    v = AimedConfig().lattice
    settings = [  # (label, steer fraction, sample step [m], clearance [m])
        (f"V ({v.clearance * 100:g} cm, {v.tail_step * 100:g} cm steps)", v.steer_fraction, v.tail_step, v.clearance),
        ("4 cm, 1 cm steps", v.steer_fraction, 0.01, 0.04),
        ("2 cm, full lock, 5 mm steps", 1.0, 0.005, 0.02),
        ("5 mm, full lock, 5 mm steps", 1.0, 0.005, 0.005),
    ]
    if a.layout:
        g = load_layout(a.layout).build()
        for label, frac, step, clearance in settings:
            r = escape(g, g.vehicle.r_min / frac, step, clearance, a.arcs)
            print(f"{a.layout}: {label}: " + (f"{r[0]} ({r[1]})" if r else "none"))
        return
    slots = {}
    for sc in from_sample("full"):
        if sc.parking_type.value == "parallel" and sc.slot_length <= a.max_length + 1e-9:
            key = round(sc.slot_length, 2)
            if key not in slots or sc.road_width > slots[key].road_width:  # the widest road: least in the way
                slots[key] = sc
    print(f"turns out of the target of a parallel slot, at most {a.arcs} arcs: arcs to 45 deg (of them under 10 cm)")
    for sl, sc in sorted(slots.items()):
        g = sc.build()
        if not iso_pose_exists("parallel", sc.slot_length, sc.slot_width, g.vehicle):
            print(f"SL {sl:.2f} m: no ISO pose")
            continue
        cells = []
        for label, frac, step, clearance in settings:
            r = escape(g, g.vehicle.r_min / frac, step, clearance, a.arcs)
            cells.append(f"{label}: " + (f"{r[0]} ({r[1]})" if r else "none"))
        print(f"SL {sl:.2f} m ({sl / g.vehicle.length:.2f} L): " + "; ".join(cells), flush=True)


if __name__ == "__main__":
    main()
