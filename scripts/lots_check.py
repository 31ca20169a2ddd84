"""Every generated lot loads, resets and steps: N lots per level written as files, read back,
reset and driven a few random steps (the real-lots issue's benchmark).

    python scripts/lots_check.py [--per-level 500] [--seed 0]

Prints one JSON line: lots per level, how many loaded, reset and stepped, and every
failure with its lot and error (none expected).
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

import gymnasium as gym
import numpy as np

import mirrorpark_env  # noqa: F401
from mirrorpark_env.layout_io import load_layouts, write_layout
from mirrorpark_env.lots import LEVELS, generate_lot


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--per-level", type=int, default=500)
    ap.add_argument("--seed", type=int, default=0)
    a = ap.parse_args()
    env = gym.make("MirrorPark-v0").unwrapped
    rng = np.random.default_rng(a.seed)
    ok, failures, t0 = dict.fromkeys(LEVELS, 0), [], time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        for level in LEVELS:
            for seed in range(a.seed, a.seed + a.per_level):
                name = f"L{level}-{seed}"
                try:
                    path = write_layout(generate_lot(seed, level), Path(tmp) / f"{name}.json")
                    (lot,) = load_layouts(path)
                    env.reset(options={"layout": lot})
                    for _ in range(5):
                        env.step(rng.uniform(-1, 1, 2).astype(np.float32))
                    ok[level] += 1
                except Exception as err:  # noqa: BLE001 - every failure is counted and shown
                    failures.append(f"{name}: {type(err).__name__}: {err}")
    wall = round(time.perf_counter() - t0, 1)
    print(json.dumps({"per_level": a.per_level, "ok": ok, "failures": failures, "wall_s": wall}))


if __name__ == "__main__":
    main()
