"""``mirrorpark compare``: runs on the same cases side by side, with intervals (``compare.py``)."""

from __future__ import annotations

import argparse
from pathlib import Path

from .committed import committed_rows
from .compare import markdown, paired_table, run_table, success_figure
from .store import REQUIRED, read_results


def add_compare(sub) -> None:
    c = sub.add_parser(
        "compare", help="several runs on their common cases: rates with 95 %% intervals, paired differences"
    )
    c.add_argument("runs", nargs="+", help="results folders or exported tables (each planner in them is a run)")
    c.add_argument(
        "--against",
        default=None,
        metavar="PLANNERS",
        help="also these planners' committed full-grid rows (comma-separated, e.g. mirror,hybrid-astar) "
        "for exactly the runs' cases, without running them; refused where they came from other code",
    )
    c.add_argument("--allow-other-code", action="store_true", help="take committed rows of other code, labelled so")
    c.add_argument("--grid", default=None, help="the folder of committed rows (default: the repository's results/grid)")
    c.add_argument("--reference", default=None, help="the run the others are paired against (default: the first)")
    c.add_argument("--out", default=None, help="folder for compare.md, .csv and .png (default: print only)")
    c.set_defaults(func=cmd_compare)


def cmd_compare(args: argparse.Namespace) -> int:

    found = [
        (planner, path, rows)
        for path in args.runs
        for planner, rows in read_results([path], REQUIRED).groupby("planner", sort=False)
    ]
    if not found:
        raise ValueError("runs: no rows in the runs given")
    if args.against:
        cases = set.intersection(*(set(rows["case_id"]) for _, _, rows in found))
        for planner in filter(None, (p.strip() for p in args.against.split(","))):
            rows, same = committed_rows(planner, cases, args.grid, args.allow_other_code)
            label = f"{planner} (committed)" if same else f"{planner} (committed, other code)"
            found.append((label, "", rows))
    planners = [p for p, _, _ in found]
    # A planner in several runs is named by its run too.
    runs = {(p if planners.count(p) == 1 else f"{p} ({path})"): rows for p, path, rows in found}
    common = set.intersection(*(set(r["case_id"]) for r in runs.values()))
    if not common:
        raise ValueError("runs: no case is common to all of them")
    runs = {k: r[r["case_id"].isin(common)] for k, r in runs.items()}
    reference = args.reference or next(iter(runs))
    if reference not in runs:
        raise ValueError(f"--reference: one of {', '.join(runs)}, got {reference!r}")
    table, paired = run_table(runs), paired_table(runs, reference)
    text = f"# {len(runs)} runs on {len(common)} common cases\n\n{markdown(table)}\n"
    if len(paired):
        text += f"\nAgainst `{reference}`, paired by case:\n\n{markdown(paired)}\n"
    print(text)
    if args.out:
        out = Path(args.out)
        out.mkdir(parents=True, exist_ok=True)
        (out / "compare.md").write_text(text)
        table.merge(paired, on="run", how="left").to_csv(out / "compare.csv", index=False)
        success_figure(runs, out / "compare.png")
    return 0
