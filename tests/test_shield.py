"""The safety filter around a learned policy (``rl-shield:PATH``), with a stand-in learner."""

from __future__ import annotations

import gymnasium as gym
import numpy as np

import mirrorpark_env  # noqa: F401
from planners.base import PlanStats, Policy, run_episode
from planners.rl.shield import Shielded


class FullLeft(Policy):
    """A reckless learner: full throttle, full left lock, every step."""

    name = "rl:full-left"

    def reset(self, geometry) -> None:
        self.stats = []

    def act(self, obs, info) -> np.ndarray:
        self.stats.append(PlanStats(0.0, "ok"))
        return np.array([1.0, 1.0], dtype=np.float32)


CASE = "reverse_rw5.00_sl4.82_sw2.47_th+0_y2.00"  # the car 2 m from the slot's kerb, 3 m from the far one


def test_the_filter_stops_a_reckless_learner_short_of_the_kerb_and_says_so():
    env = gym.make("MirrorPark-v0").unwrapped
    info, _ = run_episode(env, FullLeft(), CASE, max_steps=300)
    assert info["collision"]  # unfiltered, full lock left at full throttle meets the far kerb
    shield = Shielded(FullLeft())
    info, _ = run_episode(env, shield, CASE, max_steps=300)
    assert not info["collision"]
    assert info["path_length"] > 0.5  # it let the learner drive while that was safe
    assert shield.overrides > 0
    assert shield.stats[-1].status == "shielded" and shield.stats[-1].detail["learner_status"] == "ok"
    assert shield.name == "rl-shield:full-left"


class FullLeftSecondBack(FullLeft):
    """The reckless learner, whose second choice is the same lock in reverse."""

    def second_choice(self, action: np.ndarray) -> np.ndarray:
        return np.array([-action[0], action[1]], dtype=np.float32)


def test_a_car_stopped_short_of_the_kerb_backs_off_in_the_learners_second_gear():
    """Braked to a stand before the far kerb, the learner that insists on going forward
    stays there; one with a second choice backs off in it, still without a collision."""
    env = gym.make("MirrorPark-v0").unwrapped
    for learner, backs in ((FullLeft(), False), (FullLeftSecondBack(), True)):
        shield, trace = Shielded(learner), []
        info, _ = run_episode(env, shield, CASE, max_steps=300, trace=trace)
        assert not info["collision"]
        went_back = min(i["vehicle_state"].v for i in trace) < -0.05
        assert went_back == backs == (shield.gear_swaps > 0)


def _chained(model, state, a_cmd, d_cmd, brake_steps):
    """The filter's look-ahead as it was written in Python: ``TruthModel.step``, then the brake."""
    from planners.common.tracker import hold_accel

    rows = model.step(state, a_cmd, d_cmd)
    poses, x = [r[:3] for r in rows], rows[-1][:6]
    for _ in range(brake_steps):
        if abs(x[3]) < 1e-3 and abs(x[4]) < 1e-2:
            break
        rows = model.step(x, hold_accel(model.params, x[3], x[4]), x[5])
        poses += [r[:3] for r in rows]
        x = rows[-1][:6]
    return np.array(poses)


def test_the_compiled_look_ahead_repeats_the_truth_model_bit_for_bit():
    from mirrorpark_env.vehicle import TruthModel, VehicleParams
    from planners.common.brake import BrakeRollout

    p = VehicleParams.table_ii()
    model = TruthModel(p, 0.1, 0.01)
    roll = BrakeRollout(model)
    rng = np.random.default_rng(3)
    lengths = set()
    for _ in range(300):  # moving and standing starts, in and beyond the command bounds
        state = (
            *rng.uniform(-20, 20, 2),
            rng.uniform(-np.pi, np.pi),
            rng.uniform(-2.5, 2.5) * rng.integers(0, 2),
            rng.uniform(-3, 3),
            rng.uniform(-0.7, 0.7),
        )
        a_cmd, d_cmd = rng.uniform(-5, 5), rng.uniform(-1, 1)
        for steps in (0, 3, 40):
            got, want = roll(state, a_cmd, d_cmd, steps), _chained(model, state, a_cmd, d_cmd, steps)
            assert got.shape == want.shape and np.array_equal(got, want)
            lengths.add(len(got))
    assert min(lengths) == 10 and max(lengths) >= 300  # a standing car, and a long brake
