"""How a filtered learner (``rl-shield:PATH``) fails: per episode, whether it parked, how
often the filter overrode it, the share of its last 30 s spent standing, and the learner's
own acceleration command while it stood (docs/rl.md).

    python scripts/experiments/rl_shield_stalls.py models/dagger-markov/model.zip [--sample smoke] [--step 3]
"""

from __future__ import annotations

import argparse
import json

import numpy as np

from evaluation.cases import from_sample
from evaluation.registry import make_policy
from evaluation.runner import worker_env
from planners.base import run_episode

STANDING = 0.05  # [m/s]
LAST = 300  # control steps: the last 30 s


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("model")
    ap.add_argument("--sample", default="smoke")
    ap.add_argument("--step", type=int, default=3, help="every STEP-th case of the sample")
    args = ap.parse_args()
    env = worker_env()
    for sc in from_sample(args.sample)[:: args.step]:
        policy = make_policy(f"rl-shield:{args.model}")
        seen: list[tuple[float, float]] = []
        learner = policy.inner.act

        def act(obs, info, _learner=learner, _seen=seen):
            action = _learner(obs, info)
            _seen.append((info["vehicle_state"].v, float(action[0])))
            return action

        policy.inner.act = act
        info, steps = run_episode(env, policy, sc)
        last = np.array(seen[-LAST:])
        standing = np.abs(last[:, 0]) < STANDING
        accel = last[standing, 1]
        row = {
            "case": sc.case_id,
            "parked": bool(info["is_success"]),
            "failed": info["failed_criterion"],
            "steps": steps,
            "overrides": policy.overrides,
            "gear_swaps": policy.gear_swaps,
            "standing_share_last_30s": round(float(standing.mean()), 3),
            "learner_accel_standing_mean": round(float(np.mean(accel)), 4) if accel.size else None,
        }
        print(json.dumps(row), flush=True)


if __name__ == "__main__":
    main()
