"""Fingerprint and build time of the cost to go V on fixed slots.

Run it on two commits to check that a change to V's search leaves V the same bit for bit
(the hash) and to compare its build time (median, one process):

    python scripts/experiments/value_fingerprint.py
"""

from __future__ import annotations

import hashlib
import time

import numpy as np

from evaluation.cases import from_sample
from evaluation.runner import worker_env
from planners.common.cost_to_go import CostToGo


def main() -> None:
    cases = from_sample("standard")[::25] + from_sample("smoke")[::3]
    env = worker_env()
    h = hashlib.sha256()
    times = []
    for i, case in enumerate(cases):
        _, info = env.reset(options={"scenario": case})
        t0 = time.perf_counter()
        v = CostToGo(info["geometry"])
        if i:  # the first may compile
            times.append(time.perf_counter() - t0)
        for a in (v.V, v.P, v.next):
            h.update(np.ascontiguousarray(a).tobytes())
        for st in sorted(v.tails):
            h.update(repr(st).encode() + v.tails[st][0].tobytes() + v.tails[st][1].tobytes())
        for st in sorted(v.entry_rows):
            h.update(repr(st).encode() + v.entry_rows[st].tobytes())
    print(f"{len(cases)} slots: V {h.hexdigest()[:16]}, built in {1000 * np.median(times):.1f} ms (median)")


if __name__ == "__main__":
    main()
