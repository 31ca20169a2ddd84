"""Nothing lost, nothing crashes: one regression test per defect found by trying MirrorPark
as a careless or hostile user would, then property tests (hypothesis) that keep it so."""

from __future__ import annotations

import json
import math
import os
import signal
import subprocess
import sys
import textwrap
import time
import warnings
from pathlib import Path

import gymnasium as gym
import numpy as np
import pandas as pd
import pytest
from hypothesis import given
from hypothesis import strategies as st

import mirrorpark_env  # noqa: F401
from evaluation import registry
from evaluation.cases import CASE_FIELDS, load_case_file
from evaluation.cli import main as cli
from evaluation.runner import case_fields, evaluate
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
    for p in [tmp_path / "journal.jsonl", *tmp_path.glob("parts/*")]:  # as a folder copied without them
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
    env.step(np.zeros(2, dtype=np.float32))
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


def test_ctrl_c_with_several_workers_stops_cleanly_and_says_how_to_resume(tmp_path):
    """SIGINT to the whole process group mid-run: one line, exit 130, stored rows kept."""
    out = tmp_path / "o"
    proc = subprocess.Popen(
        [sys.executable, "-c", _SLOW_RUN.format(out=str(out), n=40, delay=0.2)],
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
    )
    _wait_for_rows(out, 3)
    os.killpg(proc.pid, signal.SIGINT)
    err = proc.communicate(timeout=60)[1].strip()
    assert proc.returncode == 130, err
    assert "Traceback" not in err and err.count("\n") == 0, err
    assert "rerun the same command to resume" in err
    stored = int(err.split("interrupted: ")[1].split()[0])
    assert stored == len(read_results([out])) >= 3


# ------------------------------------------------ SIGKILL at random moments
_SLOW_RUN = textwrap.dedent(
    """
    import sys, time
    import numpy as np
    from evaluation import registry
    from evaluation.cli import main
    from planners.base import Policy

    class Slow(Policy):
        def reset(self, geometry):
            time.sleep({delay})
            self.gave_up = True
        def act(self, obs, info):
            return np.zeros(2, dtype=np.float32)

    registry.PLANNERS["slow"] = Slow
    sys.exit(main(["evaluate", "--planner", "slow", "--sample", "smoke", "--out", "{out}", "--workers", "2",
                   "--quiet"] + (["--types", "reverse"] if {n} <= 30 else [])))
    """
)


def _wait_for_rows(out: Path, n: int, timeout: float = 60.0) -> None:
    t0 = time.time()
    while time.time() - t0 < timeout:
        j = out / "journal.jsonl"
        if (j.exists() and j.read_bytes().count(b"\n") >= n) or (out / "parts").exists():
            return
        time.sleep(0.05)
    raise AssertionError(f"no rows in {out} after {timeout} s")


def test_killed_five_times_then_resumed_every_case_once(tmp_path):
    """SIGKILL (no clean-up at all) at random moments, five times, then a run to the end."""
    out = tmp_path / "o"
    rng = np.random.default_rng(7)
    script = _SLOW_RUN.format(out=str(out), n=30, delay=0.05)
    for _ in range(5):
        proc = subprocess.Popen([sys.executable, "-c", script], start_new_session=True, stderr=subprocess.DEVNULL)
        time.sleep(float(rng.uniform(1.0, 3.0)))
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    df = read_results([out])
    assert len(df) == 30 and not df.duplicated(["planner", "case_id"]).any()
    assert df["case_id"].str.startswith("reverse").all()


# ------------------------------------------------------------------ properties
finite = st.floats(allow_nan=False, allow_infinity=False)


@pytest.mark.property
@given(
    width=st.floats(1.4, 2.0),
    front=st.floats(2.8, 3.6),
    ptype=st.sampled_from(["parallel", "reverse", "angle"]),
    seed=st.integers(0, 2**31 - 1),
)
def test_random_valid_configs_reset_and_step(width, front, ptype, seed):
    env = gym.make(
        "MirrorPark-v0", config={"vehicle": {"width": width, "front_length": front}, "parking_types": [ptype]}
    )
    try:
        env.reset(seed=seed)
    except ValueError as err:  # the one allowed refusal: no case of the type fits this car
        assert "vehicle: no Table III case" in str(err)
        return
    env.action_space.seed(seed)
    for _ in range(3):
        obs, reward, term, trunc, _ = env.step(env.action_space.sample())
        assert math.isfinite(reward) and all(np.isfinite(v).all() for v in obs.values())
        if term or trunc:  # e.g. a start next to a kerb and a first move into it
            break


@pytest.mark.property
@given(
    ptype=st.sampled_from(["parallel", "reverse", "angle"]),
    rw=st.floats(3.0, 8.0),
    sl=st.floats(3.0, 8.0),
    sw=st.floats(1.5, 3.0),
    th=st.floats(-180, 180),
    y0=st.floats(0, 8.0),
    actions=st.lists(
        st.tuples(st.one_of(finite, st.just(math.inf), st.just(math.nan)), st.one_of(finite, st.just(-math.inf))),
        min_size=1,
        max_size=5,
    ),
)
def test_random_scenarios_and_actions_never_give_a_non_finite_state(ptype, rw, sl, sw, th, y0, actions):
    env = gym.make("MirrorPark-v0")
    try:
        sc = Scenario.from_degrees(ptype, rw, sl, sw, th, y0)
        sc.build()
    except ValueError as err:  # rejected naming what is wrong
        assert any(f in str(err) for f in ("y0", "slot", "theta0", "start", "road_width")), err
        return
    env.reset(options={"scenario": sc})
    for a in actions:
        a = np.array(a, dtype=np.float32)
        if not np.isfinite(a).all():
            with pytest.raises(ValueError, match="action"):
                env.step(a)
            continue
        obs, reward, term, trunc, info = env.step(a)
        s = info["vehicle_state"]
        assert all(math.isfinite(v) for v in (s.x, s.y, s.theta, s.v, s.a, s.delta, reward))
        assert all(np.isfinite(v).all() for v in obs.values())
        if term:
            break


cell = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.sampled_from(["parallel", "reverse", "angle", "diagonal", "", "abc", "1e3", "-0"]),
    st.integers(-100, 100).map(str),
)


@pytest.mark.property
@given(rows=st.lists(st.lists(cell, min_size=6, max_size=6), min_size=1, max_size=4))
def test_random_case_files_run_as_written_or_are_rejected_naming_the_field(tmp_path_factory, rows):
    f = tmp_path_factory.mktemp("cases") / "cases.csv"
    f.write_text(HEADER + "".join(",".join(r) + "\n" for r in rows))
    try:
        cases = load_case_file(f)
    except ValueError as err:
        msg = str(err)
        assert msg.startswith(str(f)) and "case " in msg
        assert any(name in msg for name in (*CASE_FIELDS, "theta0", "slot", "start", "y0")), msg
        return
    for sc, r in zip(cases, rows):  # accepted: run with exactly these values
        fields = case_fields(sc)
        assert fields["parking_type"] == r[0].strip().lower()
        for name, text in zip(CASE_FIELDS[1:], r[1:]):
            assert fields[name] == pytest.approx(float(text), rel=0, abs=1e-9)


@pytest.mark.property
@given(n=st.integers(1, 40), part_rows=st.integers(1, 10), cut=st.floats(0, 1))
def test_a_store_cut_at_any_byte_loses_no_finished_row(tmp_path_factory, n, part_rows, cut):
    folder = tmp_path_factory.mktemp("store")
    store = ResultStore(folder, part_rows=part_rows)
    for i in range(n):
        store.append(_row(i))
    journal = folder / "journal.jsonl"
    finished = {f"case{i:04d}" for i in range(n)}
    if journal.exists():  # the write in flight is cut at a random byte: only that line's case reruns
        data = journal.read_bytes()
        k = int(cut * len(data))
        journal.write_bytes(data[:k])
        rolled = n - data.count(b"\n")  # rows already in parts
        finished = {f"case{i:04d}" for i in range(rolled + data[:k].count(b"\n"))}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StoreWarning)  # the cut line is reported
        got = set(ResultStore(folder).table().get("case_id", pd.Series(dtype=str)))
    assert finished <= got
    (folder / "parts").mkdir(exist_ok=True)
    (folder / "parts" / ".part-000099-x.parquet.tmp").write_bytes(b"half a part")  # a part cut short
    again = ResultStore(folder)
    for i in range(n):
        if f"case{i:04d}" not in got:
            again.append(_row(i))
    again.compact()
    df = read_results([folder])
    assert sorted(df["case_id"]) == sorted(f"case{i:04d}" for i in range(n))


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
