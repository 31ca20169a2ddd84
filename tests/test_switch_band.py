"""Where a mirror plan switches: the band rows (Eqs. 1, 2, 5, 6) by hand, and every
executed switch of the default planner inside its plan's band, on fixed cases."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

import mirrorpark_env  # noqa: F401
from mirrorpark_env import VehicleParams
from planners.base import run_episode
from planners.mirror.mirror_line import band_margin, parallel_upper_bound, reach_lower_bound, switch_band
from planners.mirror.policy import MirrorPolicy
from planners.mirror.presets import preset_config

P = VehicleParams.table_ii()
R_MIN = 2.5 / math.tan(0.6)


def _row_values(band, S, theta):
    return [a[0] * S[0] + a[1] * S[1] + t * theta - lo for a, t, lo in zip(band.a_s, band.a_theta, band.lo)]


def test_band_rows_by_hand_for_a_parallel_switch():
    # Goal at the origin heading 0; the car reversed into the slot and stands at heading
    # 0.3 rad, 0.2 m deeper (below) the goal's axis; it drives forward after the switch.
    band = switch_band(P, (0.0, 0.0, 0.0), 0.3, after=1, slot_width=2.5)
    low = R_MIN * (1 - math.cos(0.3))  # 0.1632 m
    up = 1.25 - P.rear_overhang * math.sin(0.3) - 0.5 * P.width * math.cos(0.3)
    assert low == pytest.approx(0.1632, abs=1e-4)
    # deeper = negative y; at the reference heading the linear rows are the exact bounds
    lower_row, upper_row = _row_values(band, (0.0, -0.2), 0.3)
    assert lower_row == pytest.approx(0.2 - low, abs=1e-12)
    assert upper_row == pytest.approx(up - 0.2, abs=1e-12)
    # one step off the reference: the rows are the first-order Taylor expansions
    d = 1e-3
    lower_row2, upper_row2 = _row_values(band, (0.0, -0.2), 0.3 + d)
    assert lower_row2 - lower_row == pytest.approx(-R_MIN * math.sin(0.3) * d, rel=1e-9)
    du = -P.rear_overhang * math.cos(0.3) + 0.5 * P.width * math.sin(0.3)
    assert upper_row2 - upper_row == pytest.approx(du * d, rel=1e-9)
    # the exact margin agrees with the hand-worked bounds
    assert band_margin(P, (0.0, 0.0, 0.0), (0.0, -0.2, 0.3), 1, 1.0, 2.5) == pytest.approx(
        min(0.2 - low, up - 0.2), abs=1e-12
    )
    assert up == pytest.approx(parallel_upper_bound(P, 2.5, 0.3), abs=1e-12)


def test_band_sides_follow_the_heading_and_the_gear():
    # Reverse parking: goal heading +90 deg; at heading 0, reversing after the switch, the
    # car must stand at least r_min (1 - cos 90 deg) x 1.1 to the goal axis' right (+x).
    goal = (0.0, 0.0, math.pi / 2)
    need = 1.1 * reach_lower_bound(P, math.pi / 2)
    assert band_margin(P, goal, (need + 0.05, 3.0, 0.0), -1, 1.1) == pytest.approx(0.05, abs=1e-9)
    assert band_margin(P, goal, (-need - 0.05, 3.0, 0.0), -1, 1.1) < -2 * need  # wrong side
    # the same pose driving forward after the switch needs the other side
    assert band_margin(P, goal, (-need - 0.05, 3.0, 0.0), 1, 1.1) == pytest.approx(0.05, abs=1e-9)
    band = switch_band(P, goal, 0.0, after=-1, margin=1.1)
    assert len(band.lo) == 1  # no kerb bound outside parallel parking
    assert _row_values(band, (need, 3.0), 0.0)[0] == pytest.approx(0.0, abs=1e-12)


class _Recording(MirrorPolicy):
    """Records, per control step, which plan ran which of its commands from which state."""

    def reset(self, geometry):
        super().reset(geometry)
        self.geometry = geometry
        self.steps: list[tuple[int, int, tuple[float, float, float], float]] = []

    def act(self, obs, info):
        action = super().act(obs, info)
        s = info["vehicle_state"]
        if self.plan is not None:
            self.steps.append((len(self.plans) - 1, self.k - 1, (s.x, s.y, s.theta), s.v))
        return action


# Cases in which plans hold their switch (in many episodes plans switch only at their ends),
# for the default planner (``mirror``) and for the guided one (``mirror-guided``: in its last
# two cases, and in parallel_rw3.50_sl6.82_sw2.50_th+0_y1.50, before the band rows, a switch
# lay 1.3 cm to 25 cm outside). That parallel case was the guided planner's third until
# 2026-12-02: in that day's fresh install (numpy 2.4.6, scipy 1.17.1, numba 0.68.1), the same
# code that passed before replans there before its plan's switch, leaving none to check.
# Likewise reverse_rw7.00_sl4.82_sw3.07_th+0_y5.20 was the default's second until
# 2026-12-04: seeded also by the way V prices at the car, it now switches where one plan
# ends and the next begins, and reverse_rw7.00_sl4.82_sw2.72_th+0_y5.50 its second until the
# warm starts' joins and goals were mended (the twenty-seventh session), for the same reason;
# and reverse_rw7.00_sl4.82_sw2.72_th+0_y5.40 until best first became the default.
SWITCHING = {
    "mirror": (
        "parallel_rw3.50_sl6.82_sw2.50_th+0_y1.50",
        "reverse_rw7.00_sl4.82_sw2.82_th+0_y5.40",
        "reverse_rw6.00_sl4.82_sw2.07_th-20_y4.90",
        "angle_rw4.50_sl4.82_sw1.92_th+10_y1.80",
        "angle_rw4.00_sl4.82_sw3.07_th-10_y2.40",
    ),
    "mirror-guided": (
        "parallel_rw4.50_sl5.82_sw2.50_th+30_y1.30",
        "angle_rw4.50_sl4.82_sw1.92_th+10_y1.80",
        "parallel_rw3.50_sl4.92_sw2.50_th+0_y2.60",
        "reverse_rw6.00_sl4.82_sw2.02_th-80_y4.00",
        "angle_rw4.00_sl4.82_sw3.07_th-10_y2.40",
    ),
}


@pytest.mark.parametrize(("planner", "case_id"), [(p, c) for p, cases in SWITCHING.items() for c in cases])
def test_every_executed_switch_in_the_natural_order_lies_in_its_plans_band(planner, case_id):
    """Parallel: reverse in, then forward; reverse and angle: forward, then reverse in. The
    switch lies in Theorem 1's band (parallel) or beyond Eq. (5) / (6)'s bound, to 1 cm,
    measured where the car stood at the plan's switch step, against the goal it mirrored."""
    policy = _Recording(preset_config(planner))
    info, _ = run_episode(gym.make("MirrorPark-v0"), policy, case_id)
    assert info["is_success"]
    g = policy.geometry
    parallel = g.parking_type.value == "parallel"
    target = np.array(g.target)
    checked = 0
    for j, plan in enumerate(policy.plans):
        s = plan.candidate.switch
        if s is None or plan.candidate.direction != (-1 if parallel else 1):
            continue
        at = [(pose, v) for (pj, k, pose, v) in policy.steps if pj == j and k == s]
        if not at:
            continue  # replanned before this plan's switch
        pose, v = at[0]
        goal = np.array(plan.goal)
        after = -plan.candidate.direction
        into_slot = parallel and after > 0 and np.allclose(goal[:2], target[:2], atol=2e-3)
        margin = 1.0 if parallel else policy.config.core.mirror_margin
        inside = band_margin(P, goal, pose, after, margin, g.slot_width if into_slot else None)
        assert abs(v) < 0.05, f"plan {j}: the car does not stand at its switch ({v:.3f} m/s)"
        assert inside > -0.01, f"plan {j}: switch {inside:.4f} m outside its band"
        checked += 1
    assert checked >= 1


def test_the_switch_step_is_chosen_by_optimal_cost():
    """A plan with a switch is solved at the guide's timing and at other seed speeds (other
    switch steps); the plan used is the one of lowest optimal cost."""
    compared = []
    for case_id in (SWITCHING["mirror-guided"][1], SWITCHING["mirror-guided"][3]):
        policy = _Recording(preset_config("mirror-guided"))
        run_episode(gym.make("MirrorPark-v0"), policy, case_id)
        compared += [p for p in policy.plans if len(p.stats.detail["candidates"]) > 1]
    assert len(compared) >= 2
    for plan in compared:
        tried = plan.stats.detail["candidates"]
        assert len({c.switch for c, _, _ in tried}) == len(tried)  # distinct switch steps
        costs = [cost for _, cost, _ in tried if cost is not None]
        assert plan.cost == pytest.approx(min(costs), abs=1e-3)
        assert plan.candidate in [c for c, cost, _ in tried if cost == min(costs)]
