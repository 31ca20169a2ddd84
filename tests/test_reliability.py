"""Nothing lost, nothing crashes: one regression test per defect found by trying MirrorPark
as a careless or hostile user would, then property tests (hypothesis) that keep it so."""

from __future__ import annotations

import json
import math
import os

import gymnasium as gym
import numpy as np
import pandas as pd
import pytest

import mirrorpark_env  # noqa: F401
from evaluation import registry
from evaluation.cases import CASE_FIELDS, load_case_file
from evaluation.cli import main as cli
from evaluation.runner import evaluate
from evaluation.store import ResultStore, StoreWarning, read_results
from mirrorpark_env import Scenario
from planners.base import Policy

HEADER = ",".join(CASE_FIELDS) + "\n"
A = "reverse_rw6.00_sl4.82_sw2.32_th+40_y3.00"
B = "angle_rw3.50_sl4.82_sw2.77_th+10_y1.30"


class _Quick(Policy):
    """Stops at once: a few steps per episode, for store and runner tests."""

    name = "quick"
    seen: list[Scenario] = []

    def reset(self, geometry):
        _Quick.seen.append(geometry.scenario)
        self.gave_up = True

    def act(self, obs, info):
        return np.zeros(2, dtype=np.float32)


@pytest.fixture
def quick(monkeypatch):
    _Quick.seen = []
    monkeypatch.setitem(registry.PLANNERS, "quick", _Quick)
    return _Quick


def _row(i: int, planner: str = "quick") -> dict:
    return {"planner": planner, "case_id": f"case{i:04d}", "success": bool(i % 2), "switches": i % 5}


# --------------------------------------------------------------- 1. another car
@pytest.mark.parametrize("width", [1.8, 1.95])
def test_random_resets_only_draw_cases_that_fit_the_configured_car(width):
    env = gym.make("MirrorPark-v0", config={"vehicle": {"width": width}})
    for seed in range(200):
        _, info = env.reset(seed=seed)
        assert info["geometry"].scenario.slot_width >= width - 1e-9


def test_a_car_too_big_for_every_case_is_named():
    env = gym.make("MirrorPark-v0", config={"vehicle": {"width": 4.0}, "parking_types": ["reverse"]})
    with pytest.raises(ValueError, match=r"vehicle: no Table III case of reverse fits a car"):
        env.reset(seed=0)


# ------------------------------------------------------- 2. cases as written
def test_case_files_run_exactly_as_written(tmp_path, quick):
    f = tmp_path / "cases.csv"
    f.write_text(
        HEADER + "reverse,6,4.82,2.3,10.4,2.5\nreverse,6,4.82,2.3,9.6,2.5\n"
        "reverse,4.504,4.82,2.3,10,2.5\nreverse,6,4.82,2.3,0,0.835\n"
    )
    cases = load_case_file(f)
    assert len({sc.case_id for sc in cases}) == 4  # four distinct cases, four names
    evaluate("quick", cases, tmp_path / "out", workers=1, progress=False)
    assert [sc for sc in _Quick.seen] == cases  # the very values, not ones parsed from an id
    df = read_results([tmp_path / "out"]).set_index("case_id")
    assert sorted(df["theta0_deg"].round(9)) == [0.0, 9.6, 10.0, 10.4]
    assert 4.504 in set(df["road_width"]) and 0.835 in set(df["y0"])


def test_repeated_cases_run_once_and_are_reported(tmp_path, quick, capsys):
    f = tmp_path / "cases.csv"
    f.write_text(HEADER + "reverse,6,4.82,2.3,10,2.5\n" * 3)
    argv = [
        "evaluate",
        "--planner",
        "quick",
        "--cases",
        str(f),
        "--out",
        str(tmp_path / "o"),
        "--quiet",
        "--workers",
        "1",
    ]
    assert cli(argv) == 0
    assert len(_Quick.seen) == 1
    assert "2 repeated case(s) run once" in capsys.readouterr().err


def test_types_filter_applies_to_case_files(tmp_path, quick):
    f = tmp_path / "cases.csv"
    f.write_text(HEADER + "reverse,6,4.82,2.3,10,2.5\nangle,4,4.82,2.3,0,2.0\n")
    out = str(tmp_path / "o")
    argv = [
        "evaluate",
        "--planner",
        "quick",
        "--cases",
        str(f),
        "--types",
        "angle",
        "--out",
        out,
        "--quiet",
        "--workers",
        "1",
    ]
    assert cli(argv) == 0
    assert [sc.parking_type.value for sc in _Quick.seen] == ["angle"]


# ------------------------------------------------- 3, 4. the store never destroys
def test_a_folder_holding_only_results_parquet_is_resumed_not_overwritten(tmp_path, quick):
    evaluate("quick", [Scenario.from_case_id(A)], tmp_path, workers=1, progress=False)
    for p in [tmp_path / "journal.jsonl", tmp_path / "environment.jsonl", *tmp_path.glob("parts/*")]:  # copied without
        p.unlink(missing_ok=True)
    assert [p.name for p in tmp_path.iterdir() if p.is_file()] == ["results.parquet"]
    before = pd.read_parquet(tmp_path / "results.parquet")
    _Quick.seen = []
    evaluate("quick", [Scenario.from_case_id(A), Scenario.from_case_id(B)], tmp_path, workers=1, progress=False)
    assert [sc.case_id for sc in _Quick.seen] == [B]  # A was not run again
    after = read_results([tmp_path]).set_index("case_id")
    assert after.loc[A, "episode_wall_s"] == before.set_index("case_id").loc[A, "episode_wall_s"]


def test_a_deleted_part_never_makes_the_next_part_overwrite_another(tmp_path):
    store = ResultStore(tmp_path, part_rows=5)
    for i in range(15):
        store.append(_row(i))
    parts = sorted((tmp_path / "parts").glob("part-*.parquet"))
    assert len(parts) == 3
    parts[0].unlink()  # the user removes one part
    for i in range(15, 20):
        store.append(_row(i))
    df = ResultStore(tmp_path).table()
    assert set(df["case_id"]) == {f"case{i:04d}" for i in range(5, 20)}  # 10 earlier rows kept, 5 new


# ----------------------------------------------------- 5, 7. the environment
def test_human_render_mode_resets(monkeypatch):
    monkeypatch.setenv("SDL_VIDEODRIVER", "dummy")
    env = gym.make("MirrorPark-v0", render_mode="human")
    env.reset(seed=0)
    obs, reward, *_ = env.step(np.zeros(2, dtype=np.float32))
    assert env.observation_space.contains(obs) and math.isfinite(reward)  # a window does not change the episode
    env.close()


def test_a_failed_first_reset_does_not_break_the_env():
    env = gym.make("MirrorPark-v0")
    with pytest.raises(ValueError, match="case id"):
        env.reset(options={"scenario": "typo"})
    env.reset(seed=0)
    obs, reward, *_ = env.step(np.zeros(2, dtype=np.float32))
    assert math.isfinite(reward)


# ---------------------------------------------------------- 6. journal damage
@pytest.mark.parametrize(
    "line",
    [
        b"42",
        b"null",
        b'{"a": 1}',
        b'{"planner": 5, "case_id": "x"}',
        b'{"planner": "quick", "case_id": "x", "success": "yes"}',
        b"\xff\xfe{}",
        b'{"planner": "quick", "case_id": "case0',
        b"[" * 100_000 + b"]" * 100_000,  # nested past the parser's depth
        b"[" + b"9" * 5_000 + b"]",  # an integer too long to convert
    ],
)
def test_journal_damage_is_reported_skipped_and_kept_aside(tmp_path, line):
    store = ResultStore(tmp_path)
    store.append(_row(1))
    with (tmp_path / "journal.jsonl").open("ab") as f:
        f.write(line + b"\n")
    store.append(_row(2))
    with pytest.warns(StoreWarning, match=r"journal.jsonl:2: skipped"):
        df = ResultStore(tmp_path).table()
    assert set(df["case_id"]) == {"case0001", "case0002"}
    ResultStore(tmp_path).compact()
    assert (tmp_path / "journal.rejected.jsonl").read_bytes().startswith(line)  # kept, not dropped
    assert set(read_results([tmp_path])["case_id"]) == {"case0001", "case0002"}


def test_an_unreadable_part_is_set_aside_and_its_cases_rerun(tmp_path):
    store = ResultStore(tmp_path, part_rows=2)
    for i in range(4):
        store.append(_row(i))
    first = sorted((tmp_path / "parts").glob("part-*.parquet"))[0]
    first.write_bytes(b"not parquet")
    with pytest.warns(StoreWarning, match="unreadable"):
        df = ResultStore(tmp_path).table()
    assert set(df["case_id"]) == {"case0002", "case0003"}
    assert first.with_name(first.name + ".unreadable").exists()


# ------------------------------------------------------- 8, 9. one line, exit 2
def _err(capsys) -> str:
    err = capsys.readouterr().err.strip()
    assert "Traceback" not in err and err.count("\n") == 0, err
    return err


def test_cli_answers_user_errors_in_one_line(tmp_path, capsys, quick):
    a_file = tmp_path / "file.txt"
    a_file.write_text("x")
    empty = tmp_path / "empty"
    empty.mkdir()
    ok_cases = tmp_path / "ok.csv"
    ok_cases.write_text(HEADER + "reverse,6,4.82,2.3,10,2.5\n")
    calls = [
        (["evaluate", "--planner", "quick", "--cases", str(ok_cases), "--out", str(a_file)], "is a file"),
        (["report", str(empty), "--out", str(tmp_path / "r")], "is empty"),
        (["report", str(tmp_path / "missing.parquet"), "--out", str(tmp_path / "r")], "no such results"),
        (["evaluate", "--planner", "rl:", "--sample", "smoke", "--out", str(tmp_path / "o")], "rl:"),
    ]
    for argv, words in calls:
        assert cli(argv) == 2
        assert words in _err(capsys)
    extra = tmp_path / "extra.csv"
    extra.write_text(HEADER + "reverse,6,4.82,2.3,10,2.5,99\n")
    assert cli(["evaluate", "--planner", "quick", "--cases", str(extra), "--out", str(tmp_path / "o2")]) == 2
    assert "case 1: more values than the header names" in _err(capsys)
    latin = tmp_path / "latin.csv"
    latin.write_bytes(HEADER.encode() + "reverse,6,4.82,2.3,10,2.5 \xe9\n".encode("latin-1"))
    assert cli(["evaluate", "--planner", "quick", "--cases", str(latin), "--out", str(tmp_path / "o3")]) == 2
    assert "latin.csv: not UTF-8" in _err(capsys)
    # A report whose --out is a file.
    cli(["evaluate", "--planner", "quick", "--cases", str(ok_cases), "--out", str(tmp_path / "o4"), "--quiet"])
    capsys.readouterr()
    assert cli(["report", str(tmp_path / "o4"), "--out", str(a_file)]) == 2
    assert str(a_file) in _err(capsys)


@pytest.mark.parametrize("workers", ["0", "-1", "two"])
def test_workers_below_one_are_rejected_before_anything_is_made(tmp_path, workers, capsys):
    out = tmp_path / "o"
    with pytest.raises(SystemExit) as exc:
        cli(["evaluate", "--planner", "mirror", "--workers", workers, "--out", str(out)])
    assert exc.value.code == 2 and not out.exists()
    assert "--workers" in capsys.readouterr().err


@pytest.mark.parametrize(
    "config, field",
    [
        ({"reward": {"success_bonus": math.inf}}, "success_bonus"),
        ({"reward": {"collision_penalty": -math.inf}}, "collision_penalty"),
        ({"dt": 1e-9}, "dt"),
        ({"substep": 1e-9}, "substep"),
    ],
)
def test_degenerate_settings_are_rejected_naming_the_field(config, field):
    with pytest.raises(ValueError, match=field):
        gym.make("MirrorPark-v0", config=config)


def test_a_start_outside_the_scene_is_rejected():
    with pytest.raises(ValueError, match=r"start_x_offset: must be in"):
        Scenario.from_case_id("reverse_rw6.00_sl4.82_sw2.17_th+10_y2.50_dx+100").build()


def test_json_case_files_reject_booleans_and_nested_values(tmp_path):
    f = tmp_path / "c.json"
    row = {
        "parking_type": "reverse",
        "road_width": 6,
        "slot_length": 4.82,
        "slot_width": True,
        "theta0_deg": 0,
        "y0": 2,
    }
    f.write_text(json.dumps([row]))
    with pytest.raises(ValueError, match=r"case 1: slot_width: expected a number"):
        load_case_file(f)


# Odd inputs: the wrong kind of value is refused with one line naming what is wrong, never
# read as something else (pydantic alone reads True as 1; numpy reads a complex action's real part).


@pytest.mark.parametrize(
    ("config", "message"),
    [
        ([1, 2], "config: expected a dict of settings, got list"),
        ({"dt": True}, "config: dt: expected a number, got True"),
        ({"lidar": {"rays": True}}, "config: lidar: rays: expected a number, got True"),
    ],
)
def test_a_config_of_the_wrong_kind_is_refused_by_name(config, message):
    with pytest.raises(ValueError, match=message):
        gym.make("MirrorPark-v0", config=config)


def test_reset_options_that_are_not_a_dict_are_refused():
    env = gym.make("MirrorPark-v0")
    with pytest.raises(ValueError, match=r"reset options: expected a dict .* got str"):
        env.reset(options="reverse_rw6.00_sl4.82_sw2.47_th+0_y1.40")


@pytest.mark.parametrize(
    ("action", "got"),
    [(np.array([0.1 + 1j, 0.0]), "complex numbers"), ("ab", "text"), ([True, False], "booleans")],
)
def test_an_action_that_is_not_two_real_numbers_is_refused_naming_the_action(action, got):
    env = gym.make("MirrorPark-v0").unwrapped
    env.reset(seed=0)
    with pytest.raises(ValueError, match=f"action: expected two real numbers .* got {got}"):
        env.step(action)


def test_a_layout_coordinate_given_as_a_boolean_is_refused(tmp_path):
    import yaml

    from mirrorpark_env.layout_io import load_layouts, write_layout

    path = write_layout(load_layouts("configs/layouts/tpcap/per03.csv")[0], tmp_path / "a.yaml")
    data = yaml.safe_load(path.read_text())
    data["start"]["x"] = True
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(ValueError, match="start: x: expected a number, got True"):
        load_layouts(path)


def test_a_planner_setting_given_as_a_boolean_is_refused():
    from planners.mirror.presets import preset_config

    with pytest.raises(ValueError, match="horizon: expected a number"):
        preset_config("mirror", horizon=True)
    assert preset_config("mirror", end_settled=False).core.end_settled is False  # a boolean where one belongs


def test_a_layouts_name_never_writes_outside_the_report_folder(tmp_path):
    """Names holding ``..`` or ``/`` wrote their figure into the parent folder, or linked a
    file that was not there; each figure now lies in ``img/`` under a safe, unique name, and
    the report links exactly that file."""
    import dataclasses

    from evaluation.layout_report import write_layout_report
    from evaluation.runner import run_case
    from mirrorpark_env.layout_io import load_layouts

    base = load_layouts("configs/layouts/tpcap/per03.csv")[0]
    layouts = [dataclasses.replace(base, name=n) for n in ("../../escaped", "a/b", "a_b")]
    df = pd.DataFrame([run_case("guide-only", lay) for lay in layouts])
    out = tmp_path / "deep" / "out"
    report = write_layout_report(df, layouts, out).read_text()
    written = sorted(p.relative_to(tmp_path).as_posix() for p in tmp_path.rglob("*.png"))
    assert written == ["deep/out/img/a_b.png", "deep/out/img/a_b_2.png", "deep/out/img/escaped.png"]
    for name in ("escaped.png", "a_b.png", "a_b_2.png"):
        assert f"(img/{name})" in report


def test_layouts_run_on_two_workers(tmp_path):
    """Workers take a slot's cases together; a layout is a scene of its own (grouping read
    grid factors that a layout does not have, and two layouts on two workers crashed)."""
    from mirrorpark_env.layout_io import load_layouts

    layouts = [*load_layouts("configs/layouts/tpcap/per03.csv"), *load_layouts("configs/layouts/tpcap/par02.csv")]
    evaluate("guide-only", layouts, tmp_path / "r", workers=2, progress=False)
    rows = read_results([tmp_path / "r"])
    assert sorted(rows["case_id"]) == ["par02", "per03"] and rows["error"].isna().all()
    # ... and the report over them is written (it drew an ODD map without cells: no y0 in a layout)
    from evaluation.report import write_report

    report = write_report(rows, tmp_path / "report")
    assert report.exists() and not list((tmp_path / "report").glob("odd_*.png"))


def _layout_file(tmp_path, name: str, change) -> str:
    """per03 as a native YAML file, changed by ``change(data)``."""
    import yaml

    from mirrorpark_env.layout_io import load_layouts, write_layout

    path = write_layout(load_layouts("configs/layouts/tpcap/per03.csv")[0], tmp_path / f"{name}.yaml")
    data = yaml.safe_load(path.read_text())
    change(data)
    path.write_text(yaml.safe_dump(data))
    return str(path)


@pytest.mark.parametrize(
    ("name", "change", "message"),
    [
        ("far", lambda d: d["start"].update(x=1e300), "coordinates: all must lie within 10000 m of the target"),
        ("inside", lambda d: d["start"].update(x=-12.98, y=29.06), "start: the car at .* overlaps obstacle part 0"),
        (
            "bounds",
            lambda d: d.update(bounds=[-50, 50, -50, 0]),
            "start: the rear axle at .* outside the scene.s bounds",
        ),
        (
            "boundary",
            lambda d: d.update(boundary=[[-30, 0], [0, 0], [0, 40], [-30, 40]]) or d["start"].update(x=5.0),
            "start: the rear axle at .* outside the drivable boundary",
        ),
    ],
)
def test_a_layout_no_car_can_start_in_is_refused_at_load_before_any_case_runs(tmp_path, capsys, name, change, message):
    from mirrorpark_env.layout_io import load_layouts

    path = _layout_file(tmp_path, name, change)
    with pytest.raises(ValueError, match=f"{name}.yaml: .*{message}"):
        load_layouts(path)
    out = tmp_path / "out"
    assert cli(["evaluate", "--planner", "guide-only", "--layouts", path, "--out", str(out), "--quiet"]) == 2
    assert "mirrorpark: error:" in capsys.readouterr().err and not out.exists()


# One run per results folder: two runs appending to one store lost rows and repeated cases.


def test_a_second_run_on_a_folder_in_use_is_refused_and_the_first_loses_nothing(tmp_path, quick, capsys):
    import subprocess
    import sys
    import time

    from evaluation.store import locked

    out = tmp_path / "out"
    cases = [Scenario.from_case_id(c) for c in (A, B)]
    with locked(out.parent):  # this process holds a folder: a run there is refused, naming the holder
        with pytest.raises(ValueError, match=rf"is in use by PID {os.getpid()} on "):
            evaluate("quick", cases, out.parent, workers=1, progress=False)
    holder = subprocess.Popen(  # another process holds ``out`` as a run does
        [sys.executable, "-c", f"from evaluation.store import locked\nwith locked({str(out)!r}): input()"],
        stdin=subprocess.PIPE,
    )
    try:
        out.mkdir()
        for _ in range(200):
            if (out / ".lock").exists():
                break
            time.sleep(0.05)
        assert cli(["evaluate", "--planner", "quick", "--sample", "smoke", "--out", str(out), "--quiet"]) == 2
        err = capsys.readouterr().err
        assert f"is in use by PID {holder.pid}" in err and err.count("\n") == 1
        assert not (out / "journal.jsonl").exists()
        holder.kill()  # killed outright, its lock left behind: the next run takes it over
        holder.wait()
        with pytest.warns(StoreWarning, match=f"took over the lock of PID {holder.pid}"):
            evaluate("quick", cases, out, workers=1, progress=False)
    finally:
        holder.kill()
    rows = read_results([out])
    assert sorted(rows["case_id"]) == sorted([A, B]) and not (out / ".lock").exists()


def test_case_ids_keep_1e9_and_cases_closer_than_that_are_refused_both_named():
    from evaluation.runner import unique

    near = Scenario.from_degrees("reverse", 6.0, 4.82, 2.32, -30.0000004, 2.4)
    assert near.case_id == "reverse_rw6.00_sl4.82_sw2.32_th-30.0000004_y2.40"  # no trailing point
    same = Scenario.from_degrees("reverse", 6.0, 4.82, 2.32, -30.0, 2.4)
    closer = Scenario.from_degrees("reverse", 6.0, 4.82, 2.32, -30.0000000001, 2.4)
    assert closer.case_id == same.case_id
    assert unique([same, Scenario.from_case_id(same.case_id), near]) == ([same, near], 1)  # a true repeat
    with pytest.raises(ValueError, match=r"share the id reverse_rw6\.00_sl4\.82_sw2\.32_th-30_y2\.40 .*theta0"):
        unique([same, closer])


def test_an_export_folder_that_cannot_be_made_is_refused_before_any_case_runs(tmp_path, quick, capsys):
    blocker = tmp_path / "a_file"
    blocker.write_text("")
    out = tmp_path / "out"
    argv = ["evaluate", "--planner", "quick", "--sample", "smoke", "--out", str(out), "--export", str(blocker / "x")]
    assert cli([*argv, "--quiet"]) == 2
    assert "--export: cannot create" in capsys.readouterr().err and not _Quick.seen and not out.exists()


def test_damaged_files_set_aside_never_replace_each_other(tmp_path):
    store = ResultStore(tmp_path / "s")
    store.parquet.write_bytes(b"not parquet, once")
    with pytest.warns(StoreWarning, match="moved to results.parquet.unreadable"):
        store.table()
    store.parquet.write_bytes(b"not parquet, twice")
    with pytest.warns(StoreWarning, match="moved to results.parquet.2.unreadable"):
        store.table()
    assert (tmp_path / "s" / "results.parquet.unreadable").read_bytes() == b"not parquet, once"


class _Broken(Policy):
    """Raises at reset: every case of a run becomes an error row."""

    name = "broken"

    def reset(self, geometry):
        raise RuntimeError("broken on purpose")

    def act(self, obs, info):
        return np.zeros(2, dtype=np.float32)


def test_a_layout_run_where_every_case_errors_ends_with_its_report(tmp_path, monkeypatch, capsys):
    """Its rows lack every outcome column; the summary and the layouts report read them all
    the same (it ended in a traceback after the rows were saved)."""
    monkeypatch.setitem(registry.PLANNERS, "broken", _Broken)
    out = tmp_path / "out"
    argv = ["evaluate", "--planner", "broken", "--workers", "1", "--layouts", "configs/layouts/tpcap/per03.csv"]
    assert cli([*argv, "--out", str(out), "--quiet"]) == 0
    assert "broken: 1 layouts; report in" in capsys.readouterr().out
    assert "| per03 | broken |" in (out / "layouts.md").read_text()
    assert read_results([out])["error"].str.contains("broken on purpose").all()


def test_the_main_job_runs_and_writes_its_report(tmp_path, quick, capsys):
    """The README's first command, on a stub planner (a check written into it once read an
    option the main job does not have)."""
    out = tmp_path / "main"
    assert cli(["main", "--planners", "quick", "--types", "reverse", "--out", str(out), "--quiet"]) == 0
    assert (out / "report" / "report.md").exists() and len(read_results([out / "quick"])) == 30
