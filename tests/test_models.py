"""The committed best learned policy: its recipe file is what trained it, and inside the
safety filter it parks a fixed case of each type (docs/rl.md, "The best learned policy")."""

from __future__ import annotations

import json
from pathlib import Path

import gymnasium as gym
import pytest

import mirrorpark_env  # noqa: F401
from planners.base import run_episode
from planners.rl.config import RLConfig, load_rl_config

ROOT = Path(__file__).resolve().parents[1]
BEST = ROOT / "models" / "dagger-gear-shield"


def test_the_best_models_recipe_file_holds_the_config_it_was_trained_with():
    meta = json.loads((BEST / "train.json").read_text())
    # Its fine-tuning section (train-rl --finetune, which DAgger never read) was retired after it was trained.
    trained = {k: v for k, v in meta["config"].items() if k != "finetune"}
    # docs/rl.md's command gives the seed and the rounds on the command line
    assert trained["seed"] == 2 and len(meta["rounds"]) == 6
    recipe = load_rl_config(ROOT / "configs" / "rl_dagger_gear_shield.yaml", {"seed": trained["seed"]})
    # Read under today's schema: fields added since (shaping, the success curriculum, her.enabled)
    # take their defaults, which are the behaviour it was trained with; a field it set, or one
    # removed since, still tells the two apart.
    assert recipe == RLConfig.model_validate(trained)
    assert _within(trained, recipe.model_dump())  # every value it was trained with, as the recipe has it


def _within(part: dict, whole: dict) -> bool:
    """Whether every key of ``part`` (nested) is in ``whole`` with the same value."""
    return all(k in whole and (_within(v, whole[k]) if isinstance(v, dict) else v == whole[k]) for k, v in part.items())


@pytest.mark.parametrize(
    "case",
    [
        "parallel_rw3.50_sl6.62_sw2.50_th+10_y1.30",
        "reverse_rw7.00_sl4.82_sw2.42_th+30_y2.80",
        "angle_rw4.00_sl4.82_sw2.47_th+10_y1.10",
    ],
)
def test_the_best_model_parks_a_fixed_case_of_each_type_inside_the_filter(require_module, case):
    require_module("stable_baselines3")
    require_module("torch")
    from evaluation.registry import make_policy

    policy = make_policy(f"rl-shield:{BEST / 'model.zip'}")
    info, _ = run_episode(gym.make("MirrorPark-v0").unwrapped, policy, case)
    assert info["is_success"] and not info["collision"], (case, info["failed_criterion"])
