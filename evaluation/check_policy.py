"""``check_policy``: does a planner keep the ``Policy`` contract? In the spirit of Gymnasium's
``check_env``: a real case, reset, a few steps, and what each call returned."""

from __future__ import annotations

import math
from typing import Any

import gymnasium as gym
import numpy as np

import mirrorpark_env  # noqa: F401
from planners.base import PlanStats, Policy

CASE = "reverse_rw7.00_sl4.82_sw2.32_th+40_y3.00"  # an easy reverse slot: every planner here parks it


def check_policy(policy: Policy, case_id: str = CASE, steps: int = 30) -> list[str]:
    """The problems found (empty: it keeps the contract) over ``steps`` steps of ``case_id``:
    ``reset(geometry)`` and ``act(obs, info)`` callable as the runner calls them; every action
    a finite float array of shape (2,) in [-1, 1]; ``stats`` a list of ``PlanStats``;
    ``status`` a string; ``gave_up`` a bool."""

    env = gym.make("MirrorPark-v0").unwrapped
    obs, info = env.reset(options={"scenario": case_id})
    problems: list[str] = []
    try:
        policy.reset(info["geometry"])
    except (Exception, SystemExit) as err:  # noqa: BLE001 - reported, not raised (sys.exit too)
        return [f"reset(geometry) raised {type(err).__name__}: {err}"]
    for k in range(steps):
        try:
            action = policy.act(obs, info)
        except (Exception, SystemExit) as err:  # noqa: BLE001
            problems.append(f"act(obs, info) at step {k} raised {type(err).__name__}: {err}")
            break
        bad = _action_problem(action)
        if bad:
            problems.append(f"act at step {k}: {bad}")
            break
        obs, _, term, trunc, info = env.step(np.asarray(action, np.float32))
        if term or trunc:
            break
    problems += _state_problems(policy)
    return problems


def _action_problem(action: Any) -> str | None:
    a = np.asarray(action)
    if a.shape != (2,):
        return f"the action has shape {a.shape}, not (2,) [accel, steer]"
    if not np.issubdtype(a.dtype, np.floating):
        return f"the action's dtype is {a.dtype}, not a float"
    if not np.all(np.isfinite(a)):
        return f"the action {a.tolist()} is not finite"
    if np.abs(a).max() > 1.0 + 1e-6:
        return f"the action {a.tolist()} leaves [-1, 1] (normalised: planners.base, mirrorpark_env.to_action)"
    return None


def _state_problems(policy: Policy) -> list[str]:
    out = []
    stats = getattr(policy, "stats", None)
    if not isinstance(stats, list) or not all(isinstance(s, PlanStats) for s in stats):
        out.append(
            f"stats is a {type(stats).__name__} of {sorted({type(s).__name__ for s in stats or []})}, "
            "not a list of PlanStats"
        )
    elif any(
        not (isinstance(s.wall_time_s, float) and math.isfinite(s.wall_time_s) and s.wall_time_s >= 0) for s in stats
    ):
        out.append("a PlanStats' wall_time_s is not a finite number of seconds >= 0")
    if not isinstance(getattr(policy, "status", None), str):
        out.append(f"status is a {type(getattr(policy, 'status', None)).__name__}, not a str")
    if not isinstance(getattr(policy, "gave_up", None), bool):
        out.append(f"gave_up is a {type(getattr(policy, 'gave_up', None)).__name__}, not a bool")
    return out
