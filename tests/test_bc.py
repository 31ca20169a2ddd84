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
