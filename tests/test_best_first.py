"""Best-first candidates (``AimedConfig.margin``): the candidates solved cheapest warm start
first, the scouting ended once the rest cost more than the best plan found by the margin."""

from __future__ import annotations

import numpy as np
import pytest

import mirrorpark_env  # noqa: F401
from mirrorpark_env.scenario import Scenario
from planners.mirror.planner import MirrorPlanner
from planners.mirror.presets import preset_config

# Starts where a call weighs several candidates: across the road, beside and past the slot.
CASES = (
    "reverse_rw6.00_sl4.82_sw2.32_th+40_y3.00",
    "parallel_rw4.50_sl6.72_sw2.50_th+10_y1.10",
    "angle_rw4.50_sl4.82_sw2.37_th-30_y2.70",
)
NO_LIMIT = {"call_qp_budget": None, "time_limit_s": 600.0}  # no cut that depends on the order


def _call(case_id: str, **changes):
    g = Scenario.from_case_id(case_id).build()
    planner = MirrorPlanner(g, preset_config("mirror", **NO_LIMIT, **changes))
    planner.prepare()
    plan = planner.plan(g.start)
    return plan, planner.last_stats


@pytest.mark.parametrize("case_id", CASES)
def test_a_margin_no_price_reaches_gives_the_exhaustive_plan(case_id):
    """Every candidate is solved either way, only in another order: the same plan wins."""
    every, st_every = _call(case_id, margin=None)
    first, st_first = _call(case_id, margin=1e9)
    assert every is not None and first is not None
    assert len(st_first.detail["candidates"]) == len(st_every.detail["candidates"])
    assert first.candidate == every.candidate and st_first.cost == st_every.cost
    np.testing.assert_array_equal(first.commands, every.commands)


@pytest.mark.parametrize("case_id", CASES)
def test_margin_zero_solves_no_more_and_starts_with_the_cheapest_warm_start(case_id):
    every, st_every = _call(case_id, margin=None)
    first, st_first = _call(case_id, margin=0.0)
    assert first is not None
    tried, prices = st_first.detail["candidates"], st_first.detail["prices"]
    assert len(tried) <= len(st_every.detail["candidates"])
    assert tried[0][0] == st_first.detail["scouted"][0] and prices[0] == min(prices)
    assert st_first.qp_solves <= st_every.qp_solves


def test_the_exhaustive_preset_is_mirror_solving_every_candidate():
    assert preset_config("mirror").strategy.margin == 10.0
    assert preset_config("mirror-exhaustive").strategy.margin is None
    assert preset_config("mirror-exhaustive").model_dump() == preset_config("mirror", margin=None).model_dump()
