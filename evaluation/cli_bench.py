"""``mirrorpark bench`` (env stepping and planning time in one run) and ``mirrorpark
check-planner`` (does a planner keep the ``Policy`` contract)."""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Callable

from .bench import run
from .cases import from_sample
from .check_policy import check_policy
from .registry import MAIN, make_policy


def add_bench(sub, positive_int: Callable[[str], int]) -> None:
    b = sub.add_parser("bench", help="benchmark env stepping and every planner's planning time in one run")
    b.add_argument("--planners", "--planner", nargs="+", default=None, help="planner names (default: the main ones)")
    b.add_argument("--sample", choices=("smoke", "standard"), default="smoke", help="the sample to take cases from")
    b.add_argument("--cases", type=positive_int, default=9, help="cases spread over the sample (default 9)")
    b.add_argument("--env-steps", type=positive_int, default=5000, help="env steps to time (default 5000)")
    b.add_argument("--json", action="store_true")
    b.set_defaults(func=cmd_bench)

    k = sub.add_parser("check-planner", help="check that a planner keeps the Policy contract on a real case")
    k.add_argument("planner", help="a planner name, package.module:factory, or rl:PATH")
    k.add_argument("--steps", type=positive_int, default=30)
    k.set_defaults(func=cmd_check_planner)


def cmd_bench(args: argparse.Namespace) -> int:

    sample = [sc.case_id for sc in from_sample(args.sample)]
    n = min(args.cases, len(sample))
    # The middle of each of n equal blocks: the samples are ordered by type and slot size,
    # so their first cases are the tightest slots (mostly hopeless).
    cases = [sample[(2 * i + 1) * len(sample) // (2 * n)] for i in range(n)]
    res = run(args.planners or list(MAIN), cases, env_steps=args.env_steps)
    if args.json:
        print(json.dumps(res))
    else:
        print(f"env: {res['env_steps_per_s']['median']:.0f} steps/s (median)")
        for p, r in res["planners"].items():
            ms = "/".join(f"{r[k]:.1f}" if r[k] is not None else "-" for k in ("plan_ms_median", "plan_ms_mean"))
            tail = "/".join(f"{r[k]:.1f}" if r[k] is not None else "-" for k in ("plan_ms_p95", "plan_ms_p99"))
            print(
                f"{p}: plan ms median/mean {ms}, p95/p99 {tail} over {r['calls']} calls; "
                f"QP solves per call median {r['qp_per_call_median']}, p95 {r['qp_per_call_p95']}; "
                f"{r['successes']}/{r['cases']} parked" + (f", {r['errors']} errors" if r["errors"] else "")
            )
            if r["stage_shares"]:
                print("  time per stage: " + ", ".join(f"{k} {v:.0%}" for k, v in r["stage_shares"].items()))
        for k, v in res["ratios"].items():
            print(f"{k}: {v:.2f}")
    return 0


def cmd_check_planner(args: argparse.Namespace) -> int:

    problems = check_policy(make_policy(args.planner), steps=args.steps)
    if problems:
        print(f"{args.planner}: {len(problems)} problem(s) with the Policy contract:", file=sys.stderr)
        for p in problems:
            print(f"  - {p}", file=sys.stderr)
        return 1
    print(f"{args.planner}: keeps the Policy contract ({args.steps} steps of a real case)")
    return 0
