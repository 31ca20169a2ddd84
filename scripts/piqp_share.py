"""How much of a planner's call time piqp's own native code takes (setup, update, solve).

    python scripts/piqp_share.py [--planner mirror] [--start 5] [--every 25]

Runs ``evaluation.runner.run_case`` on every ``every``-th standard case from ``start`` in
one process, with piqp's solver wrapped in a timer, and prints the episodes' wall time,
the planning time (the rows' ``plan_times_ms``) and the part of it inside piqp. What is
left of the planning time is the planner's own Python and numpy: the part that code
changes outside the solver can reach. The first case only warms up (imports, compiled
kernels) and is not counted.
"""

from __future__ import annotations

import argparse
import time

from evaluation.cases import from_sample
from evaluation.runner import run_case
from planners.mirror import solvers

NATIVE = ("setup", "update", "solve")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--planner", default="mirror")
    ap.add_argument("--start", type=int, default=5)
    ap.add_argument("--every", type=int, default=25)
    args = ap.parse_args()

    piqp = solvers.PIQP
    spent = dict.fromkeys(NATIVE, 0.0)

    class Timed:
        """piqp's SparseSolver with its native calls timed."""

        def __init__(self):
            self._s = piqp.SparseSolver()

        def __getattr__(self, name):
            return getattr(self._s, name)

    def timed(name):
        def call(self, *a, **kw):
            t = time.perf_counter()
            out = getattr(self._s, name)(*a, **kw)
            spent[name] += time.perf_counter() - t
            return out

        return call

    for name in NATIVE:
        setattr(Timed, name, timed(name))

    class Module:
        def __getattr__(self, name):
            return Timed if name == "SparseSolver" else getattr(piqp, name)

    solvers.PIQP = Module()
    cases = from_sample("standard")[args.start :: args.every]
    run_case(args.planner, cases[0])
    spent.update(dict.fromkeys(NATIVE, 0.0))
    wall = plan = 0.0
    for sc in cases[1:]:
        t = time.perf_counter()
        row = run_case(args.planner, sc)
        wall += time.perf_counter() - t
        plan += sum(row["plan_times_ms"]) / 1e3
    native = sum(spent.values())
    parts = ", ".join(f"{k} {v:.1f} s" for k, v in spent.items())
    print(
        f"{len(cases) - 1} cases: episodes {wall:.1f} s, planning {plan:.1f} s, "
        f"piqp {native:.1f} s ({100 * native / max(plan, 1e-9):.0f} % of the planning; {parts})"
    )


if __name__ == "__main__":
    main()
