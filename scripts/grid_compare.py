"""Compare planners on the full-grid chunks they all have (results/grid/), overall and from
y0 >= 1.6 m where the slot admits an ISO pose (the mirror issue's measure), and list the
cases the first planner misses that another parks.

    python scripts/grid_compare.py mirror mirror-guided hybrid-astar [--by slot_length] [--list 20]
"""

from __future__ import annotations

import argparse
import re
from pathlib import Path

import pandas as pd

from evaluation.metrics import far_out
from evaluation.store import read_results

GRID = Path(__file__).resolve().parents[1] / "results" / "grid"


def chunks(planner: str) -> dict[int, Path]:
    """{chunk number: file} of ``planner``'s committed chunks of 64."""
    out = {}
    for f in GRID.glob(f"{planner}-chunk*-of-64.parquet"):
        m = re.fullmatch(rf"{re.escape(planner)}-chunk(\d+)-of-64\.parquet", f.name)
        if m:
            out[int(m.group(1))] = f
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("planners", nargs="+", help="the first is the one whose misses are listed")
    ap.add_argument("--by", default=None, help="a grid column to break the y0 >= 1.6 m rates down by")
    ap.add_argument("--list", type=int, default=0, help="list this many of the first planner's misses")
    args = ap.parse_args()
    have = [chunks(p) for p in args.planners]
    common = sorted(set.intersection(*(set(h) for h in have)))
    if not common:
        raise SystemExit(f"no chunk that all of {args.planners} have in {GRID}")
    tables = [read_results([h[k] for k in common]).set_index("case_id") for h in have]
    ids = tables[0].index
    tables = [t.loc[ids] for t in tables]
    first = tables[0]
    sel = far_out(first) & first.feasible
    any_ok = pd.concat([t.success for t in tables], axis=1).any(axis=1)
    n_sel = int(sel.sum())
    print(f"chunks {common[0]}-{common[-1]} ({len(common)}), {len(ids)} cases; y0 >= 1.6 m and an ISO pose: {n_sel}")
    for name, ok in [*zip(args.planners, (t.success for t in tables)), ("any of them", any_ok)]:
        print(f"  {name:>16}: {100 * ok.mean():5.1f} % of all, {100 * ok[sel].mean():5.1f} % from y0 >= 1.6 m")
    if args.by:
        rates = pd.DataFrame({p: t.success[sel] for p, t in zip(args.planners, tables)})
        print(rates.groupby(first[args.by][sel]).mean().round(3).to_string())
    miss = sel & ~first.success & any_ok
    print(f"{args.planners[0]} misses {int(miss.sum())} of them that another parks; its causes:")
    print(first.failure_cause[miss].value_counts().to_string())
    if args.list:
        cols = ["failed_criterion", "failure_cause", "switches", "planning_calls"]
        print(first.loc[miss, cols].head(args.list).to_string())


if __name__ == "__main__":
    main()
