"""`mirror` with another scouting budget (branch-and-bound nodes per MIQP while the
candidates are compared), on every other standard case, one process; one JSON line per case.

    python scripts/scout_nodes.py NODES START OUT.jsonl    # START 0 or 1: which half

docs/benchmarks.md (2026-12-03, seventeenth session) compares 1, 3 and the default 5.
"""

import json
import sys
import time

from evaluation.cases import from_sample
from evaluation.runner import worker_env
from planners.base import run_episode
from planners.common.slot_frame import InSlotFrame
from planners.mirror.config import MirrorPlannerConfig
from planners.mirror.policy import MirrorPolicy


def main(nodes: int, start: int, out: str) -> None:
    with open(out, "w") as f:
        for sc in from_sample("standard")[start::2]:
            policy = MirrorPolicy(MirrorPlannerConfig(value_scout_node_limit=nodes))
            t0 = time.perf_counter()
            info, steps = run_episode(worker_env(), InSlotFrame(policy), sc)
            row = {
                "case": sc.case_id,
                "success": bool(info["is_success"]),
                "collision": bool(info["collision"]),
                "switches": int(info["direction_switches"]),
                "steps": int(steps),
                "status": policy.status,
                "qp": int(sum(s.qp_solves for s in policy.stats)),
                "plan_s": float(sum(s.wall_time_s for s in policy.stats)),
                "wall": time.perf_counter() - t0,
            }
            f.write(json.dumps(row) + "\n")
            f.flush()


if __name__ == "__main__":
    main(int(sys.argv[1]), int(sys.argv[2]), sys.argv[3])
