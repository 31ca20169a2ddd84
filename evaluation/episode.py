"""One episode of a planner on a grid case or a layout, as one result row (``run_case``).

The row holds the case's own values, the episode's verdict and margins, the planner's
work and time per call, and, where asked for, the driven trajectory: the states and
commands of every step (``path_*``, for ``mirrorpark export --trajectories``).
"""

from __future__ import annotations

import math
import sys
import time
import traceback
from contextlib import redirect_stdout
from typing import Any

import gymnasium as gym
import numpy as np

import mirrorpark_env  # noqa: F401
from mirrorpark_env.config import PerturbConfig
from mirrorpark_env.criteria import iso_pose_exists
from mirrorpark_env.layout import Layout
from mirrorpark_env.layout_io import content_key
from mirrorpark_env.scenario import Scenario
from mirrorpark_env.vehicle import VehicleParams, from_action, vehicle_name
from planners.base import run_episode

from . import registry
from .call_limit import CALL_LIMIT_S, CallTimeout, limited
from .causes import episode_cause
from .provenance import current_id
from .schema import MARGINS, wrong_types

_ENVS: dict[PerturbConfig | None, gym.Env] = {}  # one environment per worker process and perturbation


def worker_env(perturb: PerturbConfig | None = None):
    """This process's environment (with its TimeLimit: episodes end at 180 s), under ``perturb``."""
    if perturb not in _ENVS:
        _ENVS[perturb] = gym.make("MirrorPark-v0", config=None if perturb is None else {"perturb": perturb})
    return _ENVS[perturb]


def case_fields(sc: Scenario) -> dict[str, Any]:
    """The case's own values, as run (the id is only its name)."""
    return {
        "case_id": sc.case_id,
        "parking_type": sc.parking_type.value,
        "road_width": sc.road_width,
        "slot_length": sc.slot_length,
        "slot_width": sc.slot_width,
        "theta0_deg": round(sc.theta0_deg, 9),
        "y0": sc.y0,
        "y1": round(sc.road_width - sc.y0, 9),  # distance from the rear axle to the road boundary
        "start_x_offset": sc.start_x_offset,
    }


def layout_fields(lay: Layout) -> dict[str, Any]:
    """A layout's row fields: its name, slot and start (the grid's columns where they apply)."""
    s = lay.slot
    return {
        "case_id": lay.name,
        "layout": lay.name,
        "layout_key": content_key(lay),
        "vehicle": "paper" if lay.vehicle is None else (vehicle_name(lay.vehicle) or "custom"),
        "parking_type": s.parking_type.value if s is not None else "none",
        "road_width": lay.road_width,
        "slot_length": s.length if s is not None else math.nan,
        "slot_width": s.width if s is not None else math.nan,
        "theta0_deg": round(math.degrees(lay.start[2]), 9),
        "y0": math.nan,
        "y1": math.nan,
        "start_x_offset": math.nan,
    }


def _feasible(case: Scenario | Layout) -> bool:
    """Whether the case's slot admits an ISO pose (a layout without a slot: always)."""
    if isinstance(case, Layout):
        if case.slot is None:
            return True
        ptype, sl, sw = case.slot.parking_type, case.slot.length, case.slot.width
    else:
        ptype, sl, sw = case.parking_type, case.slot_length, case.slot_width
    car = case.vehicle if isinstance(case, Layout) and case.vehicle is not None else VehicleParams.table_ii()
    return bool(iso_pose_exists(ptype.value, sl, sw, car))


def trajectory_fields(trace: list[dict], actions: list, params: VehicleParams) -> dict[str, list[float]]:
    """The driven trajectory as row fields: the state after the reset and after every step
    (time, rear-axle pose, speed, actual acceleration and steering), and the commands of each
    step (acceleration, steering; the last state has none: NaN). States are rounded to 0.1 mm
    and 1e-6 rad; commands are kept whole, so that the truth model replays them exactly."""

    states = [i.get("true_state", i["vehicle_state"]) for i in trace]  # the truth, where it is perturbed
    commands = [from_action(params, a) for a in actions] + [(math.nan, math.nan)]
    return {
        "path_t": [round(float(i["parking_time"]), 6) for i in trace],
        "path_x": [round(s.x, 4) for s in states],
        "path_y": [round(s.y, 4) for s in states],
        "path_theta": [round(s.theta, 6) for s in states],
        "path_v": [round(s.v, 6) for s in states],
        "path_accel": [round(s.a, 6) for s in states],
        "path_steer": [round(s.delta, 6) for s in states],
        "path_accel_cmd": [float(c[0]) for c in commands],
        "path_steer_cmd": [float(c[1]) for c in commands],
    }


def run_case(
    planner: str,
    sc: Scenario | Layout,
    keep_stats: list | None = None,
    trajectory: bool = False,
    call_limit_s: float | None = CALL_LIMIT_S,
    perturb: PerturbConfig | None = None,
) -> dict[str, Any]:
    """One episode of ``planner`` on a grid case or a layout; never raises (errors become rows:
    an exception, a plug-in's ``sys.exit``, a call past ``call_limit_s`` seconds, the safety
    net of ``call_limit.py``; None: none). What the planner prints goes to stderr: stdout is
    the command's own (``evaluate --json``).

    With ``trajectory`` (always for a layout) the row also holds the driven trajectory
    (``trajectory_fields``, in the layout's frame) for figures and ``mirrorpark export
    --trajectories``. ``perturb``: the world differs from what the planner is told
    (``mirrorpark_env.perturb``; the row names it in ``perturb``). ``keep_stats``: a list
    that the policy's ``PlanStats`` of every call are appended to (the benchmark's breakdown)."""

    t0 = time.perf_counter()
    row: dict[str, Any] = {"planner": planner} | ({} if perturb is None else {"perturb": perturb.name})
    info = None
    try:
        is_layout = isinstance(sc, Layout)
        row.update(layout_fields(sc) if is_layout else case_fields(sc))
        policy = registry.make_policy(planner)  # looked up at call time: tests stand one in
        watched = limited(policy, call_limit_s)
        keep = trajectory or is_layout
        trace: list[dict] | None = [] if keep else None
        actions: list | None = [] if keep else None
        env = worker_env(perturb)
        with redirect_stdout(sys.stderr):
            info, steps = run_episode(env, watched, sc, trace=trace, actions=actions)
        if keep:
            row.update(trajectory_fields(trace, actions, env.unwrapped.params))
            if is_layout:
                row["path_origin"] = [float(sc.origin[0]), float(sc.origin[1])]
        if keep_stats is not None:
            keep_stats.extend(policy.stats)
        times = [1e3 * s.wall_time_s for s in policy.stats]
        row.update(
            success=bool(info["is_success"]),
            failed_criterion=info["failed_criterion"],
            collision=bool(info["collision"]),
            heading_error_deg=float(info["heading_error_deg"]),
            switches=int(info["direction_switches"]),
            parking_time_s=float(info["parking_time"]),
            path_length_m=float(info["path_length"]),
            steps=steps,
            planning_calls=len(times),
            plan_time_median_ms=float(np.median(times)) if times else math.nan,
            plan_time_max_ms=float(np.max(times)) if times else math.nan,
            plan_times_ms=[round(t, 3) for t in times],
            # Work per call, which (unlike time) any machine repeats: iterations (SCP rounds,
            # search expansions), QP solves, nodes (branch and bound, search).
            plan_iterations=[int(s.iterations) for s in policy.stats],
            plan_qp_solves=[int(s.qp_solves) for s in policy.stats],
            plan_nodes=[int(s.nodes) for s in policy.stats],
            safety_net_calls=sum(bool(s.detail.get("safety_net")) for s in policy.stats),
            setup_ms=1e3 * float(getattr(policy, "setup_time_s", 0.0)),
            planner_status=_text(policy.status),
            error=None,
            inside_slot=bool(info["inside_slot"]),
            min_clearance_m=float(info["min_clearance"]),
            speed_at_min_clearance=float(info["speed_at_min_clearance"]),
            min_clearance_away_m=float(info["min_clearance_away"]),
            speed_at_min_clearance_away=float(info["speed_at_min_clearance_away"]),
        )
        for m in MARGINS:
            row[m] = float(info["margins"].get(m, math.nan))
    except (Exception, SystemExit, CallTimeout) as err:  # noqa: BLE001  (one case's failure must not stop the run)
        row.update(
            success=False,
            failed_criterion="error",
            planner_status="error",
            error=f"{type(err).__name__}: {err}",
            traceback=traceback.format_exc(limit=5),
        )
    bad = wrong_types(row)
    if bad:  # a plug-in's value of the wrong type: the episode is kept, the value dropped and named
        named = ", ".join(f"{k} ({type(row[k]).__name__})" for k in bad)
        row.update(dict.fromkeys(bad, None), error=f"the planner gave values of the wrong type: {named}")
    feasible = _feasible(sc)
    row["feasible"] = feasible
    ended = None if row.get("planner_status") == "error" else info
    row["failure_cause"], row["failure_amount"] = episode_cause(ended, feasible)
    row["episode_wall_s"] = time.perf_counter() - t0
    row["environment"] = current_id()  # the machine and packages (``environment.jsonl``)
    return row


def _text(status: Any) -> str:
    """A policy's status as stored: a plug-in's non-string status as its text."""
    return status if isinstance(status, str) else str(status)
