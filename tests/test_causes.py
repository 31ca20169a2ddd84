"""The failure cause of a row, on one fixed case for each cause (tests/test_reliability.py
holds the store; here episodes run end to end through ``run_case``)."""

from __future__ import annotations

import numpy as np
import pytest

from evaluation import registry
from evaluation.causes import failure_cause
from evaluation.runner import run_case
from mirrorpark_env import Scenario, VehicleParams, to_action
from planners.base import Policy

P = VehicleParams.table_ii()
REV = dict(parking_type="reverse", road_width=5.0, slot_length=4.82, slot_width=2.3, y0=1.0, start_x_offset=-1.15)


def rev(theta0_deg: float = 90.0, **kw) -> Scenario:
    return Scenario.from_degrees(**{**REV, "theta0_deg": theta0_deg, **kw})


class _Script(Policy):
    """Commands from ``law(state, target)`` until ``stop(state, target)``, then gives up."""

    law = staticmethod(lambda s, t: (0.0, 0.0))
    done = staticmethod(lambda s, t: False)

    def reset(self, geometry):
        self.target = geometry.target
        self.gave_up = False

    def act(self, obs, info):
        s = info["vehicle_state"]
        if self.done(s, self.target):
            self.gave_up = True
        a, d = self.law(s, self.target) if not self.gave_up else (-(s.v / P.tau_accel_s + s.a), 0.0)
        return to_action(P, max(P.accel_min, min(P.accel_max, a)), d)


def _back_to(s, t):
    """Reverse straight toward the target's depth (the car heads +Y: back is -Y)."""
    v_ref = max(-1.0, min(1.0, 0.8 * (t[1] - s.y)))
    return 2.0 * (v_ref - s.v) - 1.0 * s.a, 0.0


def _policy(law, done=lambda s, t: False):
    return type("Scripted", (_Script,), {"law": staticmethod(law), "done": staticmethod(done)})


class _Raises(Policy):
    def reset(self, geometry):
        raise RuntimeError("a planner bug")

    def act(self, obs, info):
        raise AssertionError


CASES = {
    # cause: (policy, scenario)
    "collision": (_policy(lambda s, t: (-3.0, 0.0)), rev(90.0, start_x_offset=-0.2)),  # back into the neighbour
    "out_of_scene": (_policy(lambda s, t: (3.0, 0.0)), rev(0.0, y0=2.5)),  # full throttle down the road
    "no_iso_pose": (_policy(lambda s, t: (0.0, 0.0), lambda s, t: True), rev(90.0, slot_width=1.8)),  # < W + 0.2
    "gave_up": (_policy(lambda s, t: (0.0, 0.0), lambda s, t: True), rev()),
    "timeout": (_policy(lambda s, t: (0.0, 0.0)), rev()),  # stands still, never gives up
    "parked_outside_margin:heading": (_policy(_back_to), rev(93.5, start_x_offset=-1.4)),  # 3.5 deg askew
    "error": (_Raises, rev()),
}


@pytest.mark.parametrize("cause", list(CASES))
def test_each_failure_cause_on_a_fixed_case(cause, monkeypatch):
    policy, sc = CASES[cause]
    monkeypatch.setitem(registry.PLANNERS, "scripted", policy)
    row = run_case("scripted", sc)
    assert not row["success"]
    assert row["failure_cause"] == cause, (row["failed_criterion"], row.get("error"))
    assert row["feasible"] is (cause != "no_iso_pose")
    if cause == "parked_outside_margin:heading":
        assert row["failure_amount"] == pytest.approx(0.5, abs=0.05)  # degrees past the 3 deg tolerance


def test_a_success_has_no_cause_and_the_clearance_is_recorded(monkeypatch):
    monkeypatch.setitem(registry.PLANNERS, "scripted", _policy(_back_to))
    row = run_case("scripted", rev())
    assert row["success"] and row["failure_cause"] is None
    # Straight down a 2.3 m slot: (2.3 - 1.67) / 2 = 0.315 m to each side, less at the
    # slot's mouth corners, never below it and never negative.
    assert 0.0 < row["min_clearance_m"] <= 0.315 + 1e-6
    assert row["speed_at_min_clearance"] >= 0.0


def _cause(**over):
    """``failure_cause`` of an episode that ended standing in the slot, feasible, after 40 s."""
    ended = dict(
        success=False,
        error=False,
        collision=False,
        out_of_scene=False,
        feasible=True,
        inside_slot=True,
        stopped=True,
        heading_error_deg=0.0,
        margins={},
        parking_time_s=40.0,
    )
    return failure_cause(**{**ended, **over})


def test_parked_outside_a_margin_names_the_smallest_margin_and_the_shortfall():
    margins = {"M_fl": 0.3, "M_fr": 0.06, "M_rl": 0.3, "M_rr": 0.08, "M_e": 0.5}
    cause, amount = _cause(heading_error_deg=1.0, margins=margins)
    assert cause == "parked_outside_margin:M_fr" and amount == pytest.approx(0.04)
    cause, amount = _cause(margins={"M_f": 0.2, "M_r": -0.0, "M_e": 0.4})  # parallel: > 0 needed
    assert cause == "parked_outside_margin:M_r" and amount == pytest.approx(0.0)
    assert _cause(success=True)[0] is None
    assert _cause(inside_slot=False)[0] == "gave_up"
    assert _cause(inside_slot=False, parking_time_s=180.0)[0] == "timeout"


def test_causes_cover_every_name():
    from evaluation.causes import CAUSES

    assert {c.split(":")[0] for c in CASES} == set(CAUSES)
    assert np.isfinite(P.length)


def test_clearance_away_from_the_start_leaves_the_start_kerb_out(monkeypatch):
    """A start 1 cm from the far kerb, driven straight on along it: the whole episode's
    closest approach is that 1 cm; more than 1 m from the start it is the same kerb's gap
    (the car keeps its line), and it is never below the whole episode's."""
    monkeypatch.setitem(registry.PLANNERS, "scripted", _policy(lambda s, t: (1.0, 0.0), lambda s, t: s.x > t[0] + 9))
    sc = Scenario.from_degrees("parallel", 4.5, 6.0, 2.5, 0, 4.5 - 0.835 - 0.01)  # 1 cm below the far kerb
    row = run_case("scripted", sc)
    assert row["min_clearance_m"] == pytest.approx(0.01, abs=1e-6)
    assert row["min_clearance_away_m"] >= row["min_clearance_m"]
    assert row["min_clearance_away_m"] == pytest.approx(0.01, abs=1e-6)  # along the kerb: still 1 cm
    row = run_case("scripted", Scenario.from_degrees("parallel", 4.5, 6.0, 2.5, 0, 2.25))  # mid-road
    assert row["min_clearance_away_m"] == pytest.approx(2.25 - 0.835, abs=1e-6)  # to the slot line
