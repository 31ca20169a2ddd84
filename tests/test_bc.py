"""Behaviour cloning from collected demonstrations (needs the rl extra)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from evaluation.collect import collect
from mirrorpark_env import Scenario

CASES = ["reverse_rw6.00_sl4.82_sw2.32_th+40_y3.00", "angle_rw3.50_sl4.82_sw2.77_th+10_y1.30"]


@pytest.mark.rl
def test_a_short_bc_run_lowers_the_action_error_on_its_dataset(tmp_path, require_module):
    require_module("stable_baselines3")
    require_module("minari")
    from evaluation.cli import main as cli
    from planners.rl.bc import action_error, load_demos
    from planners.rl.policy import load_model

    collect("guide-only", [Scenario.from_case_id(c) for c in CASES], tmp_path / "demos", workers=1, progress=False)
    out = tmp_path / "bc"
    argv = ["train-rl", "--demos", str(tmp_path / "demos"), "--epochs", "40", "--out", str(out)]
    assert cli(argv) == 0
    summary = json.loads((out / "train.json").read_text())
    assert summary["method"] == "bc" and summary["episodes"] == 2
    assert summary["action_error_after"] < 0.5 * summary["action_error_before"]
    obs, actions, _ = load_demos(tmp_path / "demos")
    model = load_model(str(out / "model.zip"))  # loads as any trained model (rl:PATH)
    assert action_error(model, obs, actions) == pytest.approx(summary["action_error_after"], rel=1e-4)
    assert np.isfinite(summary["loss_per_epoch"]).all()


@pytest.mark.rl
def test_a_dagger_round_labels_the_states_the_learner_visits(tmp_path, require_module):
    """The round's observations are the learner's own rollout, and each label is what the
    planner, asked afresh at that state, would command."""
    require_module("stable_baselines3")
    import gymnasium as gym

    from planners.rl.dagger import PlannerExpert, dagger_round

    class Learner:  # a fixed, simple learner: creep forward, wheels straight
        def predict(self, obs, deterministic=True):
            return np.array([0.3, 0.0], dtype=np.float32), None

    env = gym.make("MirrorPark-v0")
    sc = Scenario.from_case_id(CASES[0])
    obs, labels = dagger_round(Learner(), env, PlannerExpert(), [sc], max_steps=6)
    assert len(labels) == 6 and all(len(v) == 6 for v in obs.values())
    # Replay the learner: the same states, and a fresh expert gives the same labels there.
    o, info = env.reset(options={"scenario": sc})
    expert = PlannerExpert()
    expert.reset(info["geometry"])
    for t in range(6):
        assert all(np.array_equal(obs[k][t], o[k]) for k in o)
        assert np.allclose(labels[t], expert.label(info["vehicle_state"]))
        o, *_, info = env.step(np.array([0.3, 0.0], dtype=np.float32))


@pytest.mark.rl
def test_finetune_buffers_the_demos_and_keeps_the_cloned_actor_through_the_warm_up(tmp_path, require_module):
    require_module("stable_baselines3")
    require_module("minari")
    import torch

    from evaluation.cli import main as cli
    from mirrorpark_env.grid import Grid
    from planners.rl.bc import load_demos
    from planners.rl.config import load_rl_config
    from planners.rl.finetune import add_demos_to_buffer, q_filtered_bc_step, warm_up_critic
    from planners.rl.train import make_model, make_train_env

    collect("guide-only", [Scenario.from_case_id(c) for c in CASES], tmp_path / "demos", workers=1, progress=False)
    obs, actions, _ = load_demos(tmp_path / "demos")
    cfg = load_rl_config(overrides={"learning_starts": 100, "batch_size": 32})
    model = make_model(cfg, make_train_env(cfg, Grid.from_config()))
    from stable_baselines3.common.logger import Logger

    model.set_logger(Logger(None, []))
    assert add_demos_to_buffer(model, tmp_path / "demos") == len(actions)
    assert model.replay_buffer.size() == len(actions)
    actor = {k: v.clone() for k, v in model.actor.state_dict().items()}
    critic = {k: v.clone() for k, v in model.critic.state_dict().items()}
    warm_up_critic(model, 5)
    assert all(torch.equal(actor[k], v) for k, v in model.actor.state_dict().items())
    assert not all(torch.equal(critic[k], v) for k, v in model.critic.state_dict().items())
    kept = q_filtered_bc_step(model, obs, actions, 1.0, np.random.default_rng(0))
    assert 0.0 <= kept <= 1.0
    assert q_filtered_bc_step(model, obs, actions, 1.0, np.random.default_rng(0), q_filter=False) == 1.0

    # The whole recipe from the command line, on a tiny budget.
    yaml = tmp_path / "rl.yaml"
    yaml.write_text(
        "total_steps: 200\nlearning_starts: 100\nbatch_size: 32\neval: {every_steps: 100000, episodes: 1}\n"
        "finetune: {critic_warmup_steps: 10, bc_anneal_steps: 150}\n"
    )
    out = tmp_path / "ft"
    argv = ["train-rl", "--demos", str(tmp_path / "demos"), "--finetune", "--epochs", "5", "--config", str(yaml)]
    assert cli([*argv, "--out", str(out)]) == 0
    summary = json.loads((out / "train.json").read_text())
    assert summary["method"] == "bc+sac" and summary["steps_done"] == 200
    assert summary["demo_transitions_in_buffer"] == len(actions)
