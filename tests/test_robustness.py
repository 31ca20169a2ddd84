"""Perturbed runs (``evaluate --perturb``) and ``mirrorpark robustness``: rows repeat on any
number of workers, folders never mix perturbations, ladders load, tables and figures appear."""

from __future__ import annotations

import pandas as pd
import pytest

from evaluation.cli import main as cli
from evaluation.perturbations import of_folder, resolve
from evaluation.robustness import NONE, chosen, load_ladders
from evaluation.runner import evaluate
from evaluation.store import read_results
from mirrorpark_env import Scenario

CASES = [
    Scenario.from_degrees("parallel", 4.5, 6.0, 2.5, 0, 1.6),
    Scenario.from_degrees("reverse", 6.0, 5.5, 2.8, 0, 2.0),
]
DECIDED = ["case_id", "success", "collision", "failed_criterion", "switches", "parking_time_s", "path_length_m"]


def _rows(folder) -> pd.DataFrame:
    return read_results([folder]).sort_values("case_id")[DECIDED + ["perturb"]].reset_index(drop=True)


def test_perturbed_rows_repeat_on_one_or_two_workers(tmp_path):
    mild = resolve("mild")
    a = evaluate("guide-only", CASES, tmp_path / "a", workers=1, progress=False, perturb=mild)
    b = evaluate("guide-only", CASES, tmp_path / "b", workers=2, progress=False, perturb=mild)
    ra, rb = _rows(a.folder), _rows(b.folder)
    pd.testing.assert_frame_equal(ra, rb)
    assert set(ra["perturb"]) == {"mild"} and of_folder(a.folder) == mild


def test_a_folder_never_mixes_perturbations(tmp_path):
    evaluate("guide-only", CASES[:1], tmp_path, workers=1, progress=False, perturb=resolve("mild"))
    with pytest.raises(ValueError, match="resuming would mix them"):
        evaluate("guide-only", CASES, tmp_path, workers=1, progress=False, perturb=resolve("moderate"))
    with pytest.raises(ValueError, match="ran perturbation 'mild', this run is unperturbed"):
        evaluate("guide-only", CASES, tmp_path, workers=1, progress=False)


def test_bad_perturb_exits_2_with_one_line(tmp_path, capsys):
    assert cli(["evaluate", "--planner", "guide-only", "--perturb", "extreme", "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--perturb: one of ['mild', 'moderate', 'severe']" in err[0]
    bad = tmp_path / "bad.yaml"
    bad.write_text("delay_steps: 50\n")
    assert cli(["evaluate", "--planner", "guide-only", "--perturb", str(bad), "--out", str(tmp_path / "o")]) == 2
    assert "delay_steps: Input should be less than or equal to 20" in capsys.readouterr().err


def test_the_shipped_ladders_load_with_unique_names():
    ladders = load_ladders()
    assert {"noise", "actuator", "delay", "model", "late-obstacle", "presets"} <= set(ladders)
    for levels in ladders.values():
        assert levels[0].name == NONE and levels[0].perturb is None and len(levels) >= 4
    names = [lev.name for levels in ladders.values() for lev in levels[1:]]
    assert len(names) == len(set(names))
    assert [lev.name for lev in ladders["presets"]] == [NONE, "mild", "moderate", "severe"]
    with pytest.raises(ValueError, match="unknown \\['wind'\\]"):
        chosen(ladders, ["wind"])


def test_a_ladder_with_a_name_twice_is_refused(tmp_path):
    f = tmp_path / "ladders.yaml"
    f.write_text("a: [{name: x, delay_steps: 1}]\nb: [{name: x, delay_steps: 2}]\n")
    with pytest.raises(ValueError, match="level name 'x' is used twice"):
        load_ladders(f)


def test_robustness_writes_a_table_and_figure_and_resumes(tmp_path, capsys):
    ladders = tmp_path / "ladders.yaml"
    ladders.write_text("delay: [{name: delay-2, delay_steps: 2}]\n")
    args = ["robustness", "--planner", "guide-only", "--ladders", str(ladders), "--sample", "smoke", "--chunk", "1/45"]
    args += ["--workers", "1", "--quiet", "--out", str(tmp_path / "out")]
    assert cli(args) == 0
    out = tmp_path / "out"
    table = pd.read_csv(out / "robustness.csv")
    assert list(table["level"]) == [NONE, "delay-2"] and set(table["cases"]) == {2}
    assert (out / "delay.png").stat().st_size > 0 and "## delay" in (out / "robustness.md").read_text()
    first = read_results([out / "levels" / "delay-2"])
    assert cli(args) == 0  # a rerun resumes: nothing is run again
    again = read_results([out / "levels" / "delay-2"])
    assert len(again) == len(first) == 2
    assert list(again["episode_wall_s"]) == list(first["episode_wall_s"])


@pytest.mark.parametrize("planner", ["mirror", "hybrid-astar"])
def test_planners_stop_clear_of_a_late_obstacle(planner):
    """Reversing at 1.6 m/s when a box appears 2 m behind the bumper: holding the turn on the
    gentle brake swung a corner into it (mirror, -0.07 mm); the hard stop keeps clear."""
    import gymnasium as gym

    from evaluation.registry import make_policy
    from planners.base import run_episode

    env = gym.make("MirrorPark-v0", config={"perturb": {"name": "late", "late_obstacle": {"time_s": 10}}})
    trace: list[dict] = []
    info, _ = run_episode(env, make_policy(planner), "parallel_rw4.50_sl4.72_sw2.50_th-30_y2.50", trace=trace)
    changed = [i for i, t in enumerate(trace) if i > 0 and "geometry" in t]
    assert len(changed) == 1 and abs(trace[changed[0]]["parking_time"] - 10.0) < 1e-9
    assert not info["collision"] and info["min_clearance"] > 0
