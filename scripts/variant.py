"""Run a planner preset with some settings changed over a sample, one process, and export its rows.

    python scripts/variant.py --set retry_nodes=30 [--set KEY=JSON ...] [--preset mirror] \
        [--name mirror-variant] [--sample smoke] [--every 1] [--start 0] [--out results/variants]
    mirrorpark diff --before BASELINE.parquet --after results/variants/mirror-variant.parquet

Each ``--set`` overrides one field of the preset's config (the mirror presets: their core or
strategy config, ``planners/mirror/config.py``; ``hybrid-astar``: ``HybridAStarConfig``; the
value read as JSON: numbers, true/false, lists),
checked by the config's own validation. The rows go to ``OUT/<name>.parquet`` as ``mirrorpark evaluate --export``
writes them, so that ``mirrorpark diff`` compares them with a run of the default (run the
default the same way, ``--name mirror`` and no ``--set``, at the same time for paired
times). For ablations that need no new planner name in the registry.
"""

from __future__ import annotations

import argparse
import json

import numpy as np
import pandas as pd
from pydantic import ValidationError

from evaluation import registry
from evaluation.cases import from_sample
from evaluation.runner import run_case, slot_of
from evaluation.store import export_table
from planners.mirror.presets import PRESETS, preset_config


def _policy_factory(preset: str, over: dict):
    """A factory of ``preset``'s policy with ``over`` set (validated here, by field name)."""
    if preset == "hybrid-astar":
        from planners.hybrid_astar.policy import HybridAStarPolicy
        from planners.hybrid_astar.search import HybridAStarConfig

        cfg = HybridAStarConfig(**over)
        return lambda: HybridAStarPolicy(cfg)
    cfg = preset_config(preset, **over)
    return lambda: registry.mirror_policy(cfg)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--set", action="append", default=[], metavar="KEY=JSON", help="a config field to override")
    ap.add_argument("--preset", default="mirror", choices=sorted([*PRESETS, "hybrid-astar"]))
    ap.add_argument("--name", default="mirror-variant")
    ap.add_argument("--sample", default="smoke", choices=("smoke", "standard"))
    ap.add_argument("--layouts", nargs="+", default=None, help="layout files or folders instead of the sample")
    ap.add_argument("--every", type=int, default=1, help="every n-th case of the sample (sorted by slot)")
    ap.add_argument("--start", type=int, default=0, help="... from this one")
    ap.add_argument("--out", default="results/variants")
    a = ap.parse_args()
    over = {}
    for item in a.set:
        key, sep, value = item.partition("=")
        if not sep:
            raise SystemExit(f"--set: expected KEY=JSON, got {item!r}")
        over[key] = json.loads(value)
    try:
        factory = _policy_factory(a.preset, over)  # unknown fields and bad values fail here, by name
    except ValidationError as err:
        raise SystemExit(f"--set: {err.errors()[0]['loc'][-1]}: {err.errors()[0]['msg']}") from None
    except ValueError as err:
        raise SystemExit(f"--set: {err}") from None

    registry.PLANNERS[a.name] = factory
    if a.layouts:
        from mirrorpark_env.layout_io import load_many

        cases = load_many(a.layouts)
    else:
        cases = from_sample(a.sample)
    if a.every > 1 or a.start:
        cases = sorted(cases, key=slot_of)[a.start :: a.every]
    df = pd.DataFrame([run_case(a.name, sc) for sc in cases])
    path = export_table(df, a.out, a.name)
    work = "plan_iterations" if a.preset == "hybrid-astar" else "plan_qp_solves"
    spent = int(sum(sum(q) for q in df[work] if q is not None))
    calls = int(df["planning_calls"].sum())
    times = np.concatenate([np.asarray(t, float) for t in df["plan_times_ms"] if t is not None and len(t)])
    print(
        f"{a.name} {over}: {df['success'].mean():.1%} parked, {calls} calls, {spent} {work[5:]}, "
        f"call ms median {np.median(times):.1f} mean {times.mean():.1f} p95 {np.percentile(times, 95):.1f}"
    )
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
