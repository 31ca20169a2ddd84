"""``mirrorpark export``: what a run holds, written where other tools can take it (``trajectories.py``)."""

from __future__ import annotations

import argparse
import sys

from .store import REQUIRED, read_results
from .trajectories import write_trajectories


def add_export(sub) -> None:
    x = sub.add_parser("export", help="write a run's driven trajectories, one file per episode")
    x.add_argument("runs", nargs="+", help="results folders or their .jsonl/.parquet files")
    x.add_argument("--trajectories", required=True, metavar="DIR", help="folder for the trajectory files")
    x.add_argument("--format", default="csv", choices=("csv", "parquet"), help="file format (default: csv)")
    x.add_argument("--planner", default=None, help="only this planner's rows")
    x.set_defaults(func=cmd_export)


def cmd_export(args: argparse.Namespace) -> int:

    df = read_results(args.runs, REQUIRED)
    if args.planner is not None:
        if args.planner not in set(df["planner"]):
            raise ValueError(f"--planner: one of {', '.join(sorted(set(df['planner'])))}, got {args.planner!r}")
        df = df[df["planner"] == args.planner]
    written, missing = write_trajectories(df, args.trajectories, args.format)
    if not written:
        raise ValueError(
            f"runs: none of their {len(df)} rows kept a trajectory; run `mirrorpark evaluate ... --trajectories` "
            "into a fresh --out folder (layout runs always keep them)"
        )
    note = f"; {missing} row(s) without one (run before --trajectories, or errors)" if missing else ""
    print(f"wrote {len(written)} file(s) to {args.trajectories}{note}", file=sys.stderr)
    return 0
