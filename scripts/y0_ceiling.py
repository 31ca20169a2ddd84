"""How much of the "y0 >= 1.6 m over slots that admit an ISO pose" set any planner here parks.

Two kinds of slot in that set are parked by none of the planners whose full-grid rows are
committed (results/grid/): reverse and angle slots of car width + 0.2 m, whose one ISO
pose is centred and aligned exactly, and parallel slots of at most 4.12 m, out of which
``scripts/in_slot_escape.py`` finds no way (so none in). This prints, per planner, its
rate over the whole set, the share of the set outside those two kinds (the ceiling they
leave) and its rate over the rest, over the full grid and over the standard sample.

    python scripts/y0_ceiling.py [--grid results/grid]
"""

from __future__ import annotations

import argparse
import glob
from pathlib import Path

import pandas as pd

from evaluation.cases import from_sample
from evaluation.metrics import far_out
from mirrorpark_env import VehicleParams
from mirrorpark_env.criteria import iso_pose_slack

PLANNERS = {"mirror": "mirror-chunk", "mirror-guided": "mirror-guided-", "hybrid-astar": "hybrid-astar-"}


def unreachable(rows: pd.DataFrame) -> pd.Series:
    """The zero-tolerance reverse and angle slots (no room to spare) and the parallel slots of <= 4.12 m."""
    slack = iso_pose_slack(rows.parking_type, rows.slot_length, rows.slot_width, VehicleParams.table_ii())
    parallel = rows.parking_type == "parallel"
    return (parallel & (rows.slot_length <= 4.125)) | (~parallel & (slack < 1e-9))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--grid", type=Path, default=Path("results/grid"))
    args = ap.parse_args()
    standard = {c.case_id for c in from_sample("standard")}
    for name, prefix in PLANNERS.items():
        files = sorted(glob.glob(str(args.grid / f"{prefix}*.parquet")))
        if not files:
            print(f"{name}: no rows under {args.grid}")
            continue
        rows = pd.concat(pd.read_parquet(f) for f in files).drop_duplicates("case_id")
        sets = {"full grid": rows, "standard": rows[rows.case_id.isin(standard)]}
        for label, r in sets.items():
            s = r[far_out(r) & r.feasible]
            bad = unreachable(s)
            rest = s[~bad]
            print(
                f"{name:13s} {label:9s} set {len(s):6d}, parked {100 * s.success.mean():5.1f} %; "
                f"none parks {int(bad.sum()):5d} (parked {int(s[bad].success.sum())}), ceiling "
                f"{100 * len(rest) / len(s):5.1f} %; the rest {len(rest):6d}, parked {100 * rest.success.mean():5.1f} %"
            )


if __name__ == "__main__":
    main()
