"""The full grid's cases whose plans the terminal weight across the slot changes.

``mirror`` weighs the end across the target's heading more in slots whose ISO window across
is narrower than ``CoreConfig.lateral_window`` (``planners/mirror/cost.py``);
every other case plans as before, to the last bit. This writes the cases it changes as a
CSV for ``mirrorpark evaluate --cases``, so that a rerun of the grid after such a change
runs only those. Run: ``python scripts/experiments/grid_window_cases.py OUT.csv [LATERAL_WINDOW]``.
"""

from __future__ import annotations

import csv
import sys

from evaluation.cases import CASE_FIELDS, from_sample
from planners.mirror.config import CoreConfig
from planners.mirror.cost import terminal_for


def main(out: str, window: float | None = None) -> None:
    cfg = CoreConfig() if window is None else CoreConfig(lateral_window=window)
    changed: dict[tuple, bool] = {}
    rows = []
    for sc in from_sample("full"):
        key = (sc.parking_type.value, sc.road_width, sc.slot_length, sc.slot_width)
        if key not in changed:
            changed[key] = terminal_for(sc.build(), cfg) is not None
        if changed[key]:
            rows.append((sc.parking_type.value, sc.road_width, sc.slot_length, sc.slot_width, sc.theta0_deg, sc.y0))
    with open(out, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(CASE_FIELDS)
        w.writerows(rows)
    slots = sorted({(k[0], k[3]) for k, v in changed.items() if v})
    n_slots = sum(changed.values())
    print(f"{len(rows)} cases in {n_slots} of {len(changed)} slots (type, width): {slots}; written to {out}")


if __name__ == "__main__":
    main(sys.argv[1], float(sys.argv[2]) if len(sys.argv) > 2 else None)
