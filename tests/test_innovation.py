"""The innovation (``planners.common.innovation``): exactly zero where the world is the model,
so that nothing a policy does changes without a perturbation; visible under noise."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import mirrorpark_env  # noqa: F401  (registers MirrorPark-v0)
from evaluation.registry import make_policy
from mirrorpark_env import VehicleParams, to_action
from planners.base import run_episode
from planners.common.innovation import NOISE_FLOOR, Innovation

P = VehicleParams.table_ii()
CASE = "reverse_rw6.00_sl5.50_sw2.80_th+0_y2.00"


def _drive(config, commands):
    env = gym.make("MirrorPark-v0", config=config)
    _, info = env.reset(options={"scenario": CASE})
    inn = Innovation(P)
    for a, d in commands:
        s = info["vehicle_state"]
        assert inn.observe(s) is s or inn.noisy  # below the floor: the measurement itself
        action = to_action(P, a, d)
        inn.sent(action)
        _, _, term, _, info = env.step(action)
        if term:
            break
    inn.observe(info["vehicle_state"])
    return inn


def test_the_innovation_is_exactly_zero_without_a_perturbation():
    rng = np.random.default_rng(0)
    inn = _drive(None, rng.uniform([-3, -0.6], [3, 0.6], size=(60, 2)))
    assert inn.position_rms == 0.0 and not inn.noisy


def test_noise_shows_in_the_innovation():
    noise = {"perturb": {"name": "n", "noise": {"position_std": 0.05}}}  # white: innovation about sqrt(2) x 5 cm
    inn = _drive(noise, [(0.5, 0.1)] * 60)
    assert inn.noisy and NOISE_FLOOR < inn.position_rms < 0.12


def test_the_estimated_speed_leans_on_the_model_under_noise():
    """Under white speed noise the estimate's speed error is a fraction of the reading's
    (``speed_gain`` 0.1 averages over about ten steps), and the pose's error is below the
    reading's too; both measured against the true state the environment keeps."""
    noise = {"perturb": {"name": "n", "noise": {"position_std": 0.03, "speed_std": 0.05}}}
    env = gym.make("MirrorPark-v0", config=noise)
    _, info = env.reset(options={"scenario": CASE})
    inn = Innovation(P)
    err_read, err_est = [], []
    for _ in range(80):
        est = inn.observe(info["vehicle_state"])
        if inn.noisy:
            true = info["true_state"]
            err_read.append(info["vehicle_state"].v - true.v)
            err_est.append(est.v - true.v)
        action = to_action(P, 0.3, 0.1)
        inn.sent(action)
        _, _, term, _, info = env.step(action)
        assert not term
    rms = lambda e: float(np.sqrt(np.mean(np.square(e))))  # noqa: E731
    assert len(err_est) > 50 and rms(err_est) < 0.5 * rms(err_read)


@pytest.mark.parametrize(("config", "widened"), [(None, False), ({"perturb": "mild"}, True)])
def test_mirror_widens_its_clearances_only_under_noise(config, widened):
    env = gym.make("MirrorPark-v0", config=config)
    policy = make_policy("mirror")
    run_episode(env, policy, CASE, max_steps=40)
    inner = policy.inner
    assert (inner._margin_level > 0) == widened
    grown = inner.planner_config.core.obstacle_margin - inner.config.core.obstacle_margin
    assert grown == pytest.approx(inner._margin_level * inner.policy_config.margin_step)
