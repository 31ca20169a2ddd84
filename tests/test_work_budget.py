"""The mirror planner's work budget per call and its time per stage (issue: a real-time planner)."""

from __future__ import annotations

import time

import gymnasium as gym
import numpy as np
import pytest
from fixed_cases import EASY_CASES
from test_mirror_planner import NO_NET, _boxes_problem

import mirrorpark_env  # noqa: F401
from planners.mirror.planner import MirrorPlanner
from planners.mirror.presets import preset_config
from planners.mirror.solvers import BranchAndBound, PiqpQP
from planners.mirror.stages import STAGES, StageClock


def _first_call(case_id: str, **changes):
    env = gym.make("MirrorPark-v0").unwrapped
    _, info = env.reset(options={"scenario": case_id})
    # The exhaustive search: its first calls solve enough QPs to cut at several budgets
    # (best first solves 3 or 4 in some of these); the budget works alike in both.
    planner = MirrorPlanner(info["geometry"], preset_config("mirror-exhaustive", time_limit_s=NO_NET, **changes))
    planner.prepare()
    plan = planner.plan(info["vehicle_state"])
    return plan, planner.last_stats


@pytest.mark.parametrize("case_id", EASY_CASES)
def test_a_call_never_solves_more_qps_than_its_budget_and_says_so(case_id):
    """Each type's first call, unbounded, then on budgets below what it spent: the call stops
    at its budget (to the solve), reports it, and still returns the best plan it had."""
    _, free = _first_call(case_id, call_qp_budget=None)
    assert free.detail["budget_spent"] is False
    assert free.qp_solves > 4
    for budget in (1, 3, free.qp_solves // 2):
        plan, st = _first_call(case_id, call_qp_budget=budget)
        assert st.qp_solves == budget  # spent to the last solve, never past it
        assert st.detail["budget_spent"] is True
        if plan is not None:
            assert plan.stats is st
    _, same = _first_call(case_id, call_qp_budget=free.qp_solves)
    assert same.qp_solves == free.qp_solves and same.cost == free.cost  # a budget it fits changes nothing


def test_branch_and_bound_stops_at_its_solve_budget():
    qp, disj, bounds = _boxes_problem()
    free = BranchAndBound(PiqpQP(), node_limit=10_000, time_limit_s=NO_NET).solve(qp, disj, bounds)
    assert free.status == "solved" and free.qp_solves > 3
    for cap in (1, 2, 3):
        res = BranchAndBound(PiqpQP(), node_limit=10_000, time_limit_s=NO_NET).solve(qp, disj, bounds, max_solves=cap)
        assert res.qp_solves == cap and res.status == "budget"
    fits = BranchAndBound(PiqpQP(), node_limit=10_000).solve(qp, disj, bounds, max_solves=free.qp_solves)
    assert fits.status == "solved" and fits.obj == free.obj


def test_the_stages_add_up_to_at_most_the_call_and_nest():
    clock = StageClock()
    t0 = time.perf_counter()
    with clock("seeds"):
        time.sleep(0.02)
        with clock("checks"):
            time.sleep(0.03)
    total = time.perf_counter() - t0
    s = clock.seconds
    assert s["checks"] >= 0.03 and s["seeds"] >= 0.02
    assert s["seeds"] + s["checks"] <= total  # the nested check's time is not counted twice
    with pytest.raises(ValueError, match="stage: must be one of"):
        clock("thinking")
    clock.reset()
    assert set(clock.seconds) == set(STAGES) and not any(clock.seconds.values())


def test_a_calls_stage_times_are_within_its_wall_time():
    _, st = _first_call(EASY_CASES[0])
    stages = st.detail["stages_ms"]
    assert set(stages) == set(STAGES)
    assert stages["solve"] > 0 and stages["build"] > 0 and stages["checks"] > 0
    assert sum(stages.values()) <= 1e3 * st.wall_time_s + 1e-6
    assert np.isfinite(list(stages.values())).all()
