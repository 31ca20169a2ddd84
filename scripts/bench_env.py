"""Benchmark: MirrorPark-v0 env steps per second without rendering (run it on one core:
``taskset -c 0 python scripts/bench_env.py``). ``mirrorpark bench`` runs it too."""

from __future__ import annotations

import argparse
import json

from evaluation.bench import env_steps_per_second


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=5000)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    res = env_steps_per_second(args.steps)
    if args.json:
        print(json.dumps(res))
    else:
        print(f"MirrorPark-v0: {res['median']:.0f} env steps/s (median of {len(res['all'])} x {args.steps} steps)")


if __name__ == "__main__":
    main()
