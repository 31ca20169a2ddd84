"""``mirrorpark robustness``: planners on perturbation ladders, with intervals (``robustness.py``)."""

from __future__ import annotations

import argparse
from pathlib import Path

from mirrorpark_env.config import PARKING_TYPES

from .call_limit import CALL_LIMIT_S
from .cases import selected
from .robustness import chosen, load_ladders, run, table, write


def add_robustness(sub, positive_int, seconds) -> None:
    p = sub.add_parser(
        "robustness", help="planners under noise, actuator error, delay, model error, a late obstacle; resumable"
    )
    p.add_argument("--planner", action="append", required=True, help="a planner (repeat for several)")
    p.add_argument(
        "--ladder",
        nargs="+",
        default=["all"],
        help="noise, actuator, delay, model, late-obstacle, presets or all (default), as in the ladders file",
    )
    p.add_argument("--ladders", default=None, help="a YAML file of ladders (default: configs/robustness.yaml)")
    p.add_argument("--sample", default="smoke", choices=["smoke", "standard", "full"], help="grid sample")
    p.add_argument("--cases", default=None, help="a JSON or CSV file of cases; overrides --sample")
    p.add_argument("--layouts", nargs="+", default=None, help="layout files or folders instead of grid cases")
    p.add_argument("--vehicle", default=None, help="with --layouts: the car of every layout")
    p.add_argument("--types", nargs="+", choices=list(PARKING_TYPES), help="only these parking types")
    p.add_argument("--chunk", default=None, help="K/N: only the K-th of N slices of the cases")
    p.add_argument("--workers", type=positive_int, default=None, help="processes (default: all cores)")
    p.add_argument(
        "--call-limit",
        type=seconds,
        default=CALL_LIMIT_S,
        metavar="SECONDS",
        help=f"wall-clock safety net per planner call (default {CALL_LIMIT_S:g}; 0: none), as for evaluate",
    )
    p.add_argument("--mixed-code", action="store_true", help="resume levels whose rows came from other code")
    p.add_argument("--quiet", action="store_true", help="no progress")
    p.add_argument("--out", default=None, help="results folder (default: results/robustness-<sample>)")
    p.set_defaults(func=cmd_robustness)


def cmd_robustness(args: argparse.Namespace) -> int:

    ladders = chosen(load_ladders(args.ladders), args.ladder)
    cases = selected(args)
    what = "layouts" if args.layouts else "cases" if args.cases else args.sample
    out = Path(args.out or f"results/robustness-{what}")
    planners = list(dict.fromkeys(args.planner))
    run(planners, cases, ladders, out, args.workers, not args.quiet, args.mixed_code, args.call_limit)
    df = table(out, planners, ladders, {c.case_id for c in cases})
    print(f"wrote {write(df, out)}")
    return 0
