"""Benchmarks: environment steps per second and planning time per call, all in one run.

Speed targets are measured here, never in timed tests. Figures are medians over
repeats (steps/s) or over every planning call (ms); ratios compare planners on the same
cases in the same process.
"""

from __future__ import annotations

import statistics
import time

import gymnasium as gym
import numpy as np

import mirrorpark_env  # noqa: F401
from mirrorpark_env.scenario import Scenario

from .registry import make_policy
from .runner import run_case


def env_steps_per_second(steps: int = 5000, repeats: int = 5) -> dict:
    """MirrorPark-v0 stepping without rendering, seeded random actions, resets included."""

    env = gym.make("MirrorPark-v0").unwrapped  # the raw env: no checker wrappers
    rng = np.random.default_rng(0)
    actions = rng.uniform(-1, 1, size=(steps, 2)).astype(np.float32)
    actions[:, 0] *= 0.3  # moderate speeds so that episodes last
    rates = []
    for r in range(repeats):
        env.reset(seed=r)
        t0 = time.perf_counter()
        for a in actions:
            _, _, term, trunc, _ = env.step(a)
            if term or trunc:
                env.reset()
        rates.append(steps / (time.perf_counter() - t0))
    return {"median": statistics.median(rates), "all": rates, "steps": steps}


def stage_shares(stats: list) -> dict[str, float] | None:
    """Each stage's share of the calls' summed wall time (``planners/mirror/stages.py``),
    the rest as "other"; None for planners that do not time their stages."""
    staged = [s for s in stats if "stages_ms" in s.detail]
    if not staged:
        return None
    total = sum(1e3 * s.wall_time_s for s in staged)
    shares = {k: 0.0 for k in staged[0].detail["stages_ms"]}
    for s in staged:
        for k, v in s.detail["stages_ms"].items():
            shares[k] += v
    shares = {k: v / total for k, v in shares.items()}
    shares["other"] = max(0.0, 1.0 - sum(shares.values()))
    return shares


def planning_times(planners: list[str], case_ids: list[str]) -> dict:
    """Every planning call of each planner over the same closed-loop episodes."""

    out = {}
    for p in planners:
        times, qps, wall, setup, ok, errors, stats = [], [], [], [], 0, 0, []
        for cid in case_ids:
            row = run_case(p, Scenario.from_case_id(cid), keep_stats=stats)  # grid ids: exact
            errors += bool(row.get("error"))
            times += row.get("plan_times_ms") or []
            qps += list(row.get("plan_qp_solves") or [])
            wall.append(row["episode_wall_s"])
            setup.append(row.get("setup_ms", 0.0))
            ok += bool(row.get("success"))
        t = np.asarray(times, float)
        out[p] = {
            "cases": len(case_ids),
            "successes": ok,
            "errors": errors,
            "calls": int(len(t)),
            "plan_ms_median": float(np.median(t)) if len(t) else None,
            "plan_ms_p95": float(np.percentile(t, 95)) if len(t) else None,
            "plan_ms_p99": float(np.percentile(t, 99)) if len(t) else None,
            "plan_ms_mean": float(t.mean()) if len(t) else None,
            "stage_shares": stage_shares(stats),
            # The work per call, the same on any machine (QP solves; 0 for search planners).
            "qp_per_call_median": float(np.median(qps)) if qps else None,
            "qp_per_call_p95": float(np.percentile(qps, 95)) if qps else None,
            "setup_ms_median": float(np.median(setup)) if setup else None,  # per episode, at reset
            "episode_wall_s_median": float(np.median(wall)) if wall else None,
        }
    return out


def run(planners: list[str], case_ids: list[str], env_steps: int = 5000) -> dict:
    """Env stepping (``env_steps`` steps) and each planner's calls over ``case_ids``; an unknown
    planner or a bad count is refused before anything runs."""
    if env_steps < 1:
        raise ValueError(f"--env-steps: a whole number >= 1, got {env_steps}")
    for name in planners:
        make_policy(name)  # an unknown name fails now, in one line
    res = {"env_steps_per_s": env_steps_per_second(env_steps), "planners": planning_times(planners, case_ids)}
    ratios = {}
    names = [p for p in planners if res["planners"][p]["plan_ms_median"]]
    for a in names:
        for b in names:
            if a < b:
                ratios[f"{a}/{b} plan_ms_median"] = (
                    res["planners"][a]["plan_ms_median"] / res["planners"][b]["plan_ms_median"]
                )
    res["ratios"] = ratios
    res["case_ids"] = case_ids
    return res
