"""Profile whole episodes of a planner on part of the standard sample (pyinstrument).

    pip install -e ".[profile]"
    python scripts/profile_mirror.py [--planner mirror] [--start 5] [--every 75] [--out profile.txt]

Runs ``evaluation.runner.run_case`` on every ``every``-th standard case from ``start`` in
one process and writes pyinstrument's call tree (wall time) to ``out``.
"""

from __future__ import annotations

import argparse
import time

from pyinstrument import Profiler

from evaluation.cases import from_sample
from evaluation.runner import run_case


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--planner", default="mirror")
    ap.add_argument("--start", type=int, default=5)
    ap.add_argument("--every", type=int, default=75)
    ap.add_argument("--out", default="profile.txt")
    a = ap.parse_args()
    cases = from_sample("standard")[a.start :: a.every]
    prof = Profiler(interval=0.002)
    t0 = time.perf_counter()
    prof.start()
    for sc in cases:
        run_case(a.planner, sc)
    prof.stop()
    print(f"{len(cases)} cases, {time.perf_counter() - t0:.1f} s; call tree in {a.out}")
    with open(a.out, "w") as f:
        f.write(prof.output_text(unicode=False, color=False))


if __name__ == "__main__":
    main()
