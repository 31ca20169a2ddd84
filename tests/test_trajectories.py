"""Trajectories out: ``evaluate --trajectories``, ``mirrorpark export``, and a replay of the
exported commands through the truth model that lands on the stored states."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from evaluation.cli import main
from mirrorpark_env import Scenario, VehicleParams
from mirrorpark_env.vehicle import TruthModel

CASE = "reverse_rw7.00_sl4.82_sw2.32_th+40_y3.00"


def _case_file(folder):
    sc = Scenario.from_case_id(CASE)
    fields = ("parking_type", "road_width", "slot_length", "slot_width", "theta0_deg", "y0")
    row = {f: getattr(sc, f) for f in fields} | {"parking_type": sc.parking_type.value}
    path = folder / "cases.csv"
    pd.DataFrame([row]).to_csv(path, index=False)
    return path


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    base = tmp_path_factory.mktemp("traj")
    cases = _case_file(base)
    out = base / "run"
    args = ["evaluate", "--planner", "guide-only", "--cases", str(cases), "--workers", "1", "--quiet"]
    assert main([*args, "--out", str(out), "--trajectories"]) == 0
    files = base / "files"
    assert main(["export", str(out), "--trajectories", str(files)]) == 0
    return base, out, files


def test_an_exported_trajectory_replays_through_the_truth_model(run):
    _, _, files = run
    table = pd.read_csv(files / f"{CASE}-guide-only.csv")
    assert list(table.columns) == [
        "t", "x", "y", "heading", "v", "steer", "accel", "gear", "accel_cmd", "steer_cmd"
    ]  # fmt: skip
    assert np.allclose(np.diff(table["t"]), 0.1) and math.isnan(table["accel_cmd"].iloc[-1])
    assert set(table["gear"]) <= {-1, 0, 1} and (table["gear"] == -1).any()  # a reverse slot: it reverses
    model = TruthModel(VehicleParams.table_ii())
    state = table[["x", "y", "heading", "v", "accel", "steer"]].iloc[0].to_numpy()
    worst = 0.0
    for k in range(len(table) - 1):
        state = model.step(state, table["accel_cmd"].iloc[k], table["steer_cmd"].iloc[k])[-1, :6]
        stored = table[["x", "y", "heading"]].iloc[k + 1].to_numpy()
        worst = max(worst, float(np.abs(state[:3] - stored).max()))
    # Only the first state's rounding (0.1 mm, 1e-6 rad) and the file's 9 digits separate them.
    assert worst < 2e-3
    end = table.iloc[-1]
    assert math.hypot(state[0] - end["x"], state[1] - end["y"]) < 2e-3


def test_parquet_and_the_csv_hold_the_same(run):
    base, out, files = run
    assert main(["export", str(out), "--trajectories", str(base / "pq"), "--format", "parquet"]) == 0
    a = pd.read_parquet(base / "pq" / f"{CASE}-guide-only.parquet")
    b = pd.read_csv(files / f"{CASE}-guide-only.csv")
    np.testing.assert_allclose(a.to_numpy(float), b.to_numpy(float), rtol=1e-8, equal_nan=True)


def test_a_run_without_trajectories_is_refused_with_the_fix(tmp_path, capsys):
    cases = _case_file(tmp_path)
    args = ["evaluate", "--planner", "guide-only", "--cases", str(cases), "--workers", "1", "--quiet"]
    assert main([*args, "--out", str(tmp_path / "run")]) == 0
    capsys.readouterr()
    assert main(["export", str(tmp_path / "run"), "--trajectories", str(tmp_path / "files")]) == 2
    err = capsys.readouterr().err
    assert "kept a trajectory" in err and "--trajectories" in err and "Traceback" not in err
