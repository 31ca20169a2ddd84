"""The learner's help: potential-based shaping with the cost to go telescopes, is off unless
asked for, and the success-driven curriculum moves only when success crosses its threshold
and only ever opens cases of the grid."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest
from tiny_rl import tiny_config

import mirrorpark_env  # noqa: F401  (registers MirrorPark-v0)
from mirrorpark_env.grid import Grid
from planners.rl.config import RLConfig
from planners.rl.curriculum import CurriculumScenarios, SuccessLadder
from planners.rl.shaping import CostToGoShaping

CASE = "reverse_rw6.00_sl5.50_sw2.80_th+0_y2.00"


def _episode(gamma: float, actions: np.ndarray, steps: int) -> tuple[list[float], float, float, bool]:
    """(shaping terms, Phi at the start, Phi at the end, terminated) of one shaped episode."""
    env = CostToGoShaping(gym.make("MirrorPark-v0", max_episode_steps=steps), gamma)
    env.reset(options={"scenario": CASE})
    phi0, terms, terminated = env.phi, [], False
    for a in actions:
        _, _, terminated, truncated, info = env.step(a)
        terms.append(info["shaping"])
        if terminated or truncated:
            break
    return terms, phi0, env.phi, terminated


@pytest.mark.parametrize("gamma", [1.0, 0.95])
def test_the_shaping_telescopes_over_an_episode_cut_by_the_time_limit(gamma):
    """sum_t gamma^t F_t = gamma^T Phi(s_T) - Phi(s_0): exactly the difference for gamma = 1."""
    rng = np.random.default_rng(0)
    terms, phi0, phi_end, terminated = _episode(gamma, rng.uniform(-1, 1, (40, 2)), 40)
    assert not terminated and len(terms) == 40
    got = math.fsum(t * gamma**k for k, t in enumerate(terms))
    assert got == pytest.approx(gamma ** len(terms) * phi_end - phi0, abs=1e-12)
    assert phi0 < 0 and phi_end != phi0  # the potential moves as the car does


def test_the_shaping_adds_minus_the_start_potential_over_an_episode_that_ends():
    """Phi is 0 at a terminal state (here the car leaves the scene at full throttle): the
    episode's shaping is -Phi(s_0), whatever the policy did on the way."""
    terms, phi0, phi_end, terminated = _episode(0.9, np.tile([1.0, 0.0], (1000, 1)), 1000)
    assert terminated and phi_end == 0.0
    assert math.fsum(t * 0.9**k for k, t in enumerate(terms)) == pytest.approx(-phi0, abs=1e-12)


def test_shaping_is_off_unless_asked_for():
    """Off by default: the training env has no shaping wrapper, so its rewards are the
    environment's own; on, it does."""
    from planners.rl.train import make_train_env

    grid = Grid.from_config()

    def wrappers(env):
        out = []
        while isinstance(env, gym.Wrapper):
            out.append(type(env))
            env = env.env
        return out

    assert CostToGoShaping not in wrappers(make_train_env(RLConfig(), grid))
    on = RLConfig.model_validate({"shaping": {"enabled": True}})
    assert CostToGoShaping in wrappers(make_train_env(on, grid))


def test_the_success_ladder_moves_only_when_success_crosses_its_threshold():
    ladder = SuccessLadder(start=0.2, step=0.1, threshold=0.6, window=10)
    for k in range(30):  # 50 % success: never enough
        assert ladder.record(k % 2 == 0) == 0.2
    appended = 0
    while ladder.level == 0.2:  # successes from now: up one step once the last ten hold six
        ladder.record(True)
        appended += 1
    assert appended == 2 and ladder.level == pytest.approx(0.3)
    for _ in range(9):
        assert ladder.record(True) == pytest.approx(0.3)  # nine episodes at the new level: not yet
    assert ladder.record(True) == pytest.approx(0.4)
    for _ in range(200):
        ladder.record(True)
    assert ladder.level == 1.0
    with pytest.raises(ValueError, match="threshold in"):
        SuccessLadder(start=0.2, step=0.1, threshold=1.5, window=10)


def test_the_curriculum_only_opens_cases_of_the_grid():
    """Every case drawn at a level is a grid case, among the easiest fraction opened."""
    grid = Grid.from_config()
    env = CurriculumScenarios(gym.make("MirrorPark-v0"), ["parallel", "angle"], level=0.1, grid=grid)
    ids = set(grid.case_ids())
    opened = {grid.scenario(int(i)).case_id for i in env._by_difficulty[: env._open]}
    for seed in range(15):
        _, info = env.reset(seed=seed)
        case = info["scenario"].case_id
        assert case in ids and case in opened and not case.startswith("reverse")


@pytest.mark.slow
def test_a_tiny_run_with_shaping_and_the_success_curriculum_trains_end_to_end(tmp_path, require_module):
    """Both helps switched on, HER off (its relabelling would drop the shaping): the run ends
    with a model and logs its curriculum level."""
    require_module("stable_baselines3")
    require_module("torch")
    import pandas as pd

    from planners.rl.train import train

    cfg = tiny_config(
        total_steps=300,
        max_episode_steps=50,
        checkpoint_every_steps=300,
        eval={"every_steps": 300, "episodes": 1},
        shaping={"enabled": True},
        her={"enabled": False},
        curriculum={"mode": "success", "window": 1, "threshold": 0.5},
    )
    train(cfg, tmp_path, progress=False)
    assert (tmp_path / "model.zip").is_file()
    levels = pd.read_csv(tmp_path / "progress.csv")["train/curriculum_level"].dropna()
    assert len(levels) and (levels == cfg.curriculum.start_fraction).all()  # nothing parked in 300 steps
