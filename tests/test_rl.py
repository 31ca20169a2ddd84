"""The RL baseline: curriculum, HER relabelling with the env's reward, train -> save -> load -> act."""

from __future__ import annotations

import json

import gymnasium as gym
import numpy as np
import pytest
from tiny_rl import tiny_config

import mirrorpark_env  # noqa: F401
from mirrorpark_env.grid import Grid
from planners.base import run_episode
from planners.rl.config import load_rl_config
from planners.rl.curriculum import CurriculumScenarios, LeanInfo, difficulty


def test_curriculum_opens_the_easiest_cases_first():
    grid = Grid.from_config()
    env = CurriculumScenarios(gym.make("MirrorPark-v0"), ["reverse"], level=0.05, grid=grid)
    idx = grid.indices("reverse")
    d = difficulty(grid, idx)
    assert d.min() >= 0 and d.max() <= 1
    # The widest slot, nearest straight start is easier than the narrowest, farthest, most turned one.
    c = grid.columns
    easy = np.argmin(-c["slot_width"][idx] + c["y0"][idx] + np.abs(c["theta0_deg"][idx]) / 90)
    hard = np.argmax(-c["slot_width"][idx] + c["y0"][idx] + np.abs(c["theta0_deg"][idx]) / 90)
    assert d[easy] < 0.2 < 0.8 < d[hard]
    widths = []
    for seed in range(20):
        _, info = env.reset(seed=seed)
        widths.append(info["scenario"].slot_width)
    assert np.mean(widths) > np.mean(c["slot_width"][idx])  # wider slots than the grid's average
    with pytest.raises(ValueError, match=r"curriculum level: must be in \(0, 1\]"):
        env.set_level(0.0)


def test_rl_config_rejects_bad_values_naming_the_field(tmp_path):
    with pytest.raises(ValueError, match=r"rl.yaml: algo: Input should be 'sac' or 'tqc'"):
        load_rl_config(overrides={"algo": "ppo"})
    with pytest.raises(ValueError, match=r"rl.yaml: gamma: Input should be less than or equal to 1"):
        load_rl_config(overrides={"gamma": 1.5})
    with pytest.raises(ValueError, match=r"rl.yaml: ent_coef"):
        load_rl_config(overrides={"ent_coef": "automatic"})
    assert load_rl_config(overrides={"ent_coef": "auto_0.01"}).ent_coef == "auto_0.01"


def test_her_relabelled_rewards_are_the_envs_compute_reward(require_module, tmp_path):
    require_module("stable_baselines3")
    from stable_baselines3 import SAC, HerReplayBuffer
    from stable_baselines3.common.logger import configure

    env = LeanInfo(CurriculumScenarios(gym.make("MirrorPark-v0", max_episode_steps=50), ["parallel"], level=1.0))
    model = SAC(
        "MultiInputPolicy",
        env,
        replay_buffer_class=HerReplayBuffer,
        replay_buffer_kwargs=dict(n_sampled_goal=4, goal_selection_strategy="future", copy_info_dict=True),
        learning_starts=10_000,
        buffer_size=1000,
        seed=0,
        device="cpu",
    )
    model.set_logger(configure(str(tmp_path), ["csv"]))  # not SB3's default folder in /tmp
    model.learn(300)  # only collects: learning starts later
    buf = model.replay_buffer
    batch = buf.sample(256)
    next_achieved = batch.next_observations["achieved_goal"].numpy()
    desired = batch.observations["desired_goal"].numpy()
    # The reward of every sample, real or relabelled, is the env's vectorised one: the
    # goal term, plus the collision penalty on the transitions that collided.
    r0 = env.unwrapped.compute_reward(next_achieved, desired, [{}] * len(desired))
    r1 = env.unwrapped.compute_reward(next_achieved, desired, [{"collision": True}] * len(desired))
    got = batch.rewards.numpy().ravel()
    assert (np.isclose(got, r0, atol=1e-5) | np.isclose(got, r1, atol=1e-5)).all()
    assert np.isclose(got, r0, atol=1e-5).mean() > 0.8  # collisions end episodes: they are rare
    assert (r1 < r0).all()


@pytest.mark.slow
@pytest.mark.parametrize("algo", ["sac", "tqc"])
def test_a_short_training_run_saves_a_model_that_acts_as_a_policy(tmp_path, require_module, algo):
    require_module("stable_baselines3")
    require_module("torch")
    if algo == "tqc":
        require_module("sb3_contrib")
    from evaluation.registry import make_policy
    from planners.rl.train import train

    cfg = tiny_config(
        algo=algo,
        total_steps=300,
        max_episode_steps=100,
        checkpoint_every_steps=150,
        eval={"every_steps": 300, "episodes": 1},
    )
    summary = train(cfg, tmp_path, progress=False)
    for name in ("model.zip", "train.json", "progress.csv", "evaluations.npz", "learning_curve.png"):
        assert (tmp_path / name).is_file(), name
    assert list((tmp_path / "checkpoints").glob(f"{algo}_*_steps.zip"))
    assert json.loads((tmp_path / "train.json").read_text())["total_steps"] == 300 == summary["total_steps"]
    policy = make_policy(f"rl:{tmp_path / 'model.zip'}")
    assert type(policy.model).__name__ == algo.upper()
    env = gym.make("MirrorPark-v0").unwrapped
    info, steps = run_episode(env, policy, "parallel_rw4.00_sl7.32_sw2.50_th+10_y1.30", max_steps=30)
    assert steps == 30 or info["collision"] or info["is_success"]
    assert len(policy.stats) == steps and all(s.status == "ok" for s in policy.stats)
    with pytest.raises(ValueError, match=r"rl model: no such file"):
        make_policy(f"rl:{tmp_path / 'missing.zip'}")


@pytest.mark.rl
def test_resume_continues_from_the_checkpoints_step_count(tmp_path, require_module):
    """A run stopped after its 200-step checkpoint, resumed to 400 steps: the model goes on
    from 200 (its weights, buffer and step count), it does not start from zero."""
    require_module("stable_baselines3")
    from evaluation.cli import main as cli
    from planners.rl.train import latest_checkpoint, train

    cfg = tiny_config(
        total_steps=200, max_episode_steps=40, checkpoint_every_steps=100, eval={"every_steps": 1000, "episodes": 1}
    )
    train(cfg, tmp_path, progress=False)  # as if interrupted right after its last checkpoint
    ckpt, steps = latest_checkpoint(tmp_path, "sac")
    assert steps == 200
    assert cli(["train-rl", "--resume", str(tmp_path), "--steps", "400"]) == 0
    summary = json.loads((tmp_path / "train.json").read_text())
    assert summary["resumed_from_step"] == 200 and summary["steps_done"] == 400
    assert latest_checkpoint(tmp_path, "sac")[1] == 400
    with pytest.raises(ValueError, match="--resume"):
        from planners.rl.train import resume_config

        resume_config(tmp_path / "nothing")


@pytest.mark.parametrize("algo", ["sac", "tqc"])
def test_the_direct_actor_pass_gives_predicts_actions_bit_for_bit(require_module, algo):
    """``rl:``'s hot path (planners/rl/inference.py) skips predict's overhead, not its
    arithmetic: one observation or a batch, the same float32 actions; a geared model's
    direct path answers as its path through predict does."""
    require_module("stable_baselines3")
    if algo == "tqc":
        require_module("sb3_contrib")
    from planners.rl.gear import GearedModel, make_head
    from planners.rl.inference import deterministic_action, direct
    from planners.rl.train import make_model, make_train_env

    cfg = load_rl_config("configs/rl_dagger.yaml", {"algo": algo, "net_arch": [64, 64]})
    model = make_model(cfg, make_train_env(cfg, Grid.from_config()))
    assert direct(model)
    model.observation_space.seed(3)
    samples = [model.observation_space.sample() for _ in range(64)]
    for i, s in enumerate(samples):
        s["observation"][4] = 0.0 if i % 2 else s["observation"][4]  # half of them standing
    for s in samples:
        np.testing.assert_array_equal(deterministic_action(model, s), model.predict(s, deterministic=True)[0])
    batch = {k: np.stack([s[k] for s in samples]) for k in samples[0]}
    np.testing.assert_array_equal(deterministic_action(model, batch), model.predict(batch, deterministic=True)[0])
    geared = GearedModel(model, make_head(model.actor.features_dim), (0.4, -0.5))
    through_predict = GearedModel(model, geared.head, geared.go)
    through_predict._direct = False  # the head's features from a second pass, as before
    np.testing.assert_array_equal(geared.predict(batch)[0], through_predict.predict(batch)[0])
    for s in samples[:8]:
        np.testing.assert_array_equal(geared.predict(s)[0], through_predict.predict(s)[0])
