"""Benchmark: MirrorPark-v0 env steps per second without rendering, on one core.

Run: python scripts/bench_env.py [--steps N] [--json]
Drives fixed grid cases with a seeded random policy (resetting at episode ends) and
reports the median of several timed repeats.
"""

from __future__ import annotations

import argparse
import json
import statistics
import time

import numpy as np


def run(steps: int, repeats: int = 5) -> dict:
    import gymnasium as gym

    import mirrorpark_env  # noqa: F401  (registers MirrorPark-v0)

    env = gym.make("MirrorPark-v0").unwrapped  # the raw env: no checker wrappers
    rng = np.random.default_rng(0)
    actions = rng.uniform(-1, 1, size=(steps, 2)).astype(np.float32)
    actions[:, 0] *= 0.3  # keep speeds moderate so episodes last
    rates = []
    for r in range(repeats):
        env.reset(seed=r)
        t0 = time.perf_counter()
        for a in actions:
            _, _, term, trunc, _ = env.step(a)
            if term or trunc:
                env.reset()
        rates.append(steps / (time.perf_counter() - t0))
    return {"steps_per_s_median": statistics.median(rates), "steps_per_s_all": rates, "steps": steps}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=5000)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    res = run(args.steps)
    if args.json:
        print(json.dumps(res))
    else:
        print(f"MirrorPark-v0: {res['steps_per_s_median']:.0f} env steps/s (median of {len(res['steps_per_s_all'])} x {args.steps} steps)")


if __name__ == "__main__":
    main()
