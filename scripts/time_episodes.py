"""Time `mirror`'s episodes on part of the standard sample, in one process, with the code of a
given checkout: run two at once (one per core) to compare two versions paired.

    python scripts/time_episodes.py CHECKOUT [--start 1] [--every 5] [--planner mirror]

CHECKOUT is a source tree (this one, or a `git worktree add /tmp/old COMMIT`); its packages
are imported ahead of the installed ones. Cases are the standard sample sorted by slot (so a
slot's cost to go is built once, as in `evaluate`), every ``every``-th from ``start``. Prints
one JSON line: wall time, plan time median / mean / p95 / p99, calls.
"""

from __future__ import annotations

import argparse
import json
import sys
import time


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("checkout")
    ap.add_argument("--start", type=int, default=1)
    ap.add_argument("--every", type=int, default=5)
    ap.add_argument("--planner", default="mirror")
    a = ap.parse_args()
    sys.path.insert(0, a.checkout)
    import numpy as np

    from evaluation.cases import from_sample
    from evaluation.runner import run_case, slot_of

    cases = sorted(from_sample("standard"), key=slot_of)[a.start :: a.every]
    t0 = time.perf_counter()
    plan_ms: list[float] = []
    for sc in cases:
        plan_ms += list(run_case(a.planner, sc)["plan_times_ms"] or [])
    print(
        json.dumps(
            {
                "checkout": a.checkout,
                "cases": len(cases),
                "wall_s": round(time.perf_counter() - t0, 1),
                "plan_median_ms": round(float(np.median(plan_ms)), 1),
                "plan_mean_ms": round(float(np.mean(plan_ms)), 1),
                "plan_p95_ms": round(float(np.percentile(plan_ms, 95)), 1),
                "plan_p99_ms": round(float(np.percentile(plan_ms, 99)), 1),
                "calls": len(plan_ms),
            }
        )
    )


if __name__ == "__main__":
    main()
