"""Demonstrations: a planner's episodes as a Minari dataset that loads and replays exactly."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

from evaluation.collect import collect
from mirrorpark_env import Scenario
from planners.rl.demos import build_dataset, dataset_id

CASES = ["reverse_rw6.00_sl4.82_sw2.32_th+40_y3.00", "angle_rw3.50_sl4.82_sw2.77_th+10_y1.30"]


def test_collected_episodes_load_with_minari_and_replay_exactly(tmp_path, require_module, monkeypatch):
    minari = require_module("minari")
    path = collect("mirror", [Scenario.from_case_id(c) for c in CASES], tmp_path, workers=1, progress=False)
    ds = minari.MinariDataset(path / "data")  # from its path ...
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path / "minari"))
    assert minari.load_dataset(dataset_id("mirror")).total_episodes == 2  # ... and by its id
    assert ds.spec.env_spec.id == "MirrorPark-v0" and ds.storage.metadata["algorithm_name"] == "mirror"
    env = gym.make("MirrorPark-v0")
    meta = list(ds.storage.get_episode_metadata(range(ds.total_episodes)))
    for ep, m in zip(ds.iterate_episodes(), meta):
        obs, _ = env.reset(options=m["options"])  # the recorded scenario
        for key in obs:
            assert np.array_equal(obs[key], ep.observations[key][0])
        for t, action in enumerate(ep.actions):
            obs, reward, term, trunc, info = env.step(action)
            for key in obs:
                assert np.array_equal(obs[key], ep.observations[key][t + 1]), (m, t, key)
            assert reward == ep.rewards[t] and term == ep.terminations[t]
            assert info["is_success"] == ep.infos["is_success"][t + 1, 0]
        assert ep.terminations[-1] or ep.truncations[-1]  # every episode ends one way or the other
    assert ep.infos["is_success"][-1, 0]  # these easy cases park
    assert ds.storage.metadata["total_steps"] == sum(m["total_steps"] for m in meta)
    # The dataset's size is measured once, after the last episode (Minari re-measures after
    # each one, which is quadratic): it must still be the folder's size. Twenty episodes
    # make it large enough not to round to 0 MB.
    files = sorted((tmp_path / "episodes").glob("*.npz")) * 10
    big = minari.MinariDataset(build_dataset("mirror", files, tmp_path / "big") / "data")
    assert big.total_episodes == 20
    assert big.storage.metadata["dataset_size"] == big.storage.get_size() > 0


def test_collection_resumes_without_redoing_episodes(tmp_path, require_module):
    require_module("minari")
    first = [Scenario.from_case_id(CASES[0])]
    collect("guide-only", first, tmp_path, workers=1, progress=False)
    stored = tmp_path / "episodes" / f"{CASES[0]}.npz"
    stamp = stored.stat().st_mtime_ns
    path = collect("guide-only", [Scenario.from_case_id(c) for c in CASES], tmp_path, workers=1, progress=False)
    assert stored.stat().st_mtime_ns == stamp  # not recorded again
    import minari

    assert minari.MinariDataset(path / "data").total_episodes == 2


def test_a_collection_resumes_only_the_same_planners_episodes_of_the_same_code(tmp_path, require_module, monkeypatch):
    """Episodes are named by case: resuming another planner's folder, or one recorded by
    other code, would pass its episodes off as this run's."""
    require_module("minari")
    from evaluation import provenance

    first = [Scenario.from_case_id(CASES[0])]
    collect("guide-only", first, tmp_path, workers=1, progress=False)
    with pytest.raises(ValueError, match="holds episodes of guide-only, not only of 'hybrid-astar'"):
        collect("hybrid-astar", first, tmp_path, workers=1, progress=False)
    monkeypatch.setattr(provenance, "source_id", lambda planner: "changed")
    with pytest.raises(ValueError, match="its 1 result of 'guide-only' came from other code"):
        collect("guide-only", first, tmp_path, workers=1, progress=False)
    collect("guide-only", first, tmp_path, workers=1, progress=False, mixed_code=True)


def test_unknown_planner_is_rejected_before_anything_runs(tmp_path):
    with pytest.raises(ValueError, match="planner: unknown"):
        collect("nope", [Scenario.from_case_id(CASES[0])], tmp_path, progress=False)
