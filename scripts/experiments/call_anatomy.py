"""Where a `mirror` call's QP solves and time go, solve by solve (one process).

    python scripts/experiments/call_anatomy.py [--start 0] [--every 10] [--out anatomy.json]

Wraps ``_Call.solve`` to record, per candidate solve: its phase (V's ways, aimed at the
target, retry, refine), QP solves, wall time, whether it gave a plan, its J, and per call
which solve won. Prints a summary and writes the records as JSON lines.
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np

from evaluation.cases import from_sample
from evaluation.runner import run_case, slot_of
from planners.mirror.strategies import aimed

RECORDS: list[dict] = []
CALL: dict = {}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--start", type=int, default=0)
    ap.add_argument("--every", type=int, default=10)
    ap.add_argument("--out", default="anatomy.jsonl")
    a = ap.parse_args()

    orig_solve, orig_plan, orig_refine = aimed._Call.solve, aimed.AimedCandidates.plan, aimed._Call.refine

    def solve(self, cand, goal, seed, miqp):
        t0 = time.perf_counter()
        q0 = self.tally.qp_solves
        out = orig_solve(self, cand, goal, seed, miqp)
        fixed = bool(np.allclose(goal, self.target))
        pen = np.clip(self.vp.checks.penetration(seed).max(axis=1), 0, None)
        tx, ty, tth = self.target
        CALL["solves"].append(
            {
                "phase": CALL["phase"],
                "fixed": fixed,
                "cand": [cand.direction, cand.switch],
                "qp": self.tally.qp_solves - q0,
                "ms": 1e3 * (time.perf_counter() - t0),
                "plan": out[1] is not None,
                "j": out[0] if np.isfinite(out[0]) else None,
                "cut": out[2],
                "scout": miqp is not self.vp.miqp,
                "seed_pen_sum": float(pen.sum()),
                "seed_pen_max": float(pen.max()),
                "dist": float(np.hypot(self.xi0[0] - tx, self.xi0[1] - ty)),
                "dth": float(abs((self.xi0[2] - tth + np.pi) % (2 * np.pi) - np.pi)),
                "seed_end_err": float(np.hypot(seed[-1, 0] - goal[0], seed[-1, 1] - goal[1])),
            }
        )
        return out

    def refine(self, *args):
        CALL["phase"] = "refine"
        return orig_refine(self, *args)

    def plan(self, state, xi0, start, candidates=None):
        CALL.clear()
        CALL.update(solves=[], phase="scout")
        t = time.perf_counter()
        res = orig_plan(self, state, xi0, start, candidates)  # an Outcome
        RECORDS.append(
            {
                "ms": 1e3 * (time.perf_counter() - t),
                "qp": res.tally.qp_solves,
                "status": res.status,
                "value": res.cost,
                "solves": CALL["solves"],
                "case": CASE[0],
            }
        )
        return res

    aimed._Call.solve, aimed._Call.refine, aimed.AimedCandidates.plan = solve, refine, plan
    CASE = [None]
    cases = sorted(from_sample("standard"), key=slot_of)[a.start :: a.every]
    parked = 0
    for sc in cases:
        CASE[0] = sc.case_id
        parked += bool(run_case("mirror", sc)["success"])
    with open(a.out, "w") as f:
        for r in RECORDS:
            f.write(json.dumps(r) + "\n")
    print(f"{len(cases)} cases, {parked} parked, {len(RECORDS)} calls -> {a.out}")


if __name__ == "__main__":
    main()
