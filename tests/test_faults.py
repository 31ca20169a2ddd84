"""Nothing hangs, nothing stale: one test per fault found by running MirrorPark with hostile
inputs and faults (dead workers, plug-ins that exit or hang, changed layouts, foreign
folders, parser limits), each reproducing it first, then a property test that feeds
generated hostile layouts and case files through loading."""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import textwrap
import time
import warnings
from contextlib import contextmanager
from pathlib import Path

import gymnasium as gym
import pandas as pd
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import mirrorpark_env  # noqa: F401
from evaluation import cases as cases_module
from evaluation.cases import CASE_FIELDS, load_case_file
from evaluation.cli import main as cli
from evaluation.store import REQUIRED, StoreWarning, read_results
from mirrorpark_env.layout_io import load_many, write_layout
from mirrorpark_env.lots import generate_lot
from mirrorpark_env.scenario import Scenario

HEADER = ",".join(CASE_FIELDS) + "\n"
FOUR = (
    HEADER + "reverse,6,4.82,2.3,10,2.5\nreverse,6,4.82,2.3,20,2.5\nreverse,6,4.82,2.3,30,2.5\nangle,4,4.82,2.3,0,2\n"
)

PLUGIN = textwrap.dedent(
    """
    import os, sys, time
    import numpy as np
    from planners.base import Policy, PlanStats

    FOLDER = os.path.dirname(os.path.abspath(__file__))

    class Still(Policy):
        name = "still"

        def reset(self, geometry):
            self.stats = [PlanStats(0.0, "ok")]
            self.gave_up = True

        def act(self, obs, info):
            return np.zeros(2, dtype=np.float32)

    class Stuck(Still):  # while the flag file exists: notes its PID, then waits
        def reset(self, geometry):
            super().reset(geometry)
            while os.path.exists(os.path.join(FOLDER, "stuck.flag")):
                open(os.path.join(FOLDER, f"pid{os.getpid()}"), "w").close()
                time.sleep(0.1)

    class Exits(Still):
        def act(self, obs, info):
            sys.exit(0)

    class Interrupts(Still):  # raises KeyboardInterrupt itself (no Ctrl-C came)
        def act(self, obs, info):
            raise KeyboardInterrupt("planner's own")

    class NumberStatus:  # a duck-typed policy whose status is an int
        name, gave_up = "number", True

        def __init__(self):
            self.stats, self.status = [], 3

        def reset(self, geometry):
            self.stats = [PlanStats(0.0, "ok")]

        def act(self, obs, info):
            return np.zeros(2, dtype=np.float32)

    class Hangs(Still):  # and swallows every Exception on the way
        def act(self, obs, info):
            while True:
                try:
                    time.sleep(10)
                except Exception:
                    pass

    class Loud(Still):
        def act(self, obs, info):
            print("planner chatter")
            return super().act(obs, info)

    def still(): return Still()
    def stuck(): return Stuck()
    def exits(): return Exits()
    def interrupts(): return Interrupts()
    def number(): return NumberStatus()
    def hangs(): return Hangs()
    def loud(): return Loud()
    """
)


@pytest.fixture
def plug(tmp_path, monkeypatch):
    """The plug-ins above as module ``hostile`` in a folder of the test's own, for this
    process and for worker processes started afresh."""
    folder = tmp_path / "plug"
    folder.mkdir()
    (folder / "hostile.py").write_text(PLUGIN)
    monkeypatch.syspath_prepend(str(folder))
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join([str(folder), os.environ.get("PYTHONPATH", "")]))
    return folder


def _cases(tmp_path: Path, text: str = FOUR, name: str = "cases.csv") -> str:
    f = tmp_path / name
    f.write_text(text)
    return str(f)


def _one_line(err: str) -> str:
    err = err.strip()
    assert "Traceback" not in err and err.count("\n") == 0, err
    return err


@contextmanager
def _warnings_shown():
    """The store's warnings as the command line shows them (the tests' config ignores them)."""
    with warnings.catch_warnings():
        warnings.simplefilter("always", StoreWarning)
        yield


def _evaluate(planner: str, cases: str, out: Path, *extra: str) -> list[str]:
    return ["evaluate", "--planner", planner, "--cases", cases, "--out", str(out), "--quiet", *extra]


# ------------------------------------------------------------- 1. a dead worker
def _kill_a_worker(plug: Path, args: list[str], workers: int) -> tuple[int, int, str]:
    """Run ``mirrorpark ARGS`` with the stuck plug-in, SIGKILL one of its workers once each
    has noted its PID; (the worker's PID, the exit code, stderr)."""
    (plug / "stuck.flag").touch()
    cmd = [sys.executable, "-m", "evaluation.cli", *args]
    proc = subprocess.Popen(cmd, stderr=subprocess.PIPE, text=True, start_new_session=True, env=os.environ.copy())
    try:
        t0 = time.time()
        while len(list(plug.glob("pid*"))) < workers and time.time() - t0 < 120:
            time.sleep(0.1)
        victim = int(sorted(plug.glob("pid*"))[0].name[3:])
        os.kill(victim, signal.SIGKILL)
        err = proc.communicate(timeout=60)[1]  # it used to wait for ever
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    (plug / "stuck.flag").unlink()
    return victim, proc.returncode, err


def test_a_killed_worker_stops_the_run_naming_its_case_and_a_resume_runs_the_rest(tmp_path, plug):
    out = tmp_path / "o"
    victim, code, err = _kill_a_worker(plug, _evaluate("hostile:stuck", _cases(tmp_path), out, "--workers", "2"), 2)
    line = _one_line(err)
    assert code == 1, err
    assert f"(PID {victim}) died (SIGKILL) while running " in line and "rerun the same command to resume" in line
    case = line.split("while running ")[1].split(";")[0]
    assert case in {sc.case_id for sc in load_case_file(tmp_path / "cases.csv")}
    assert cli(_evaluate("hostile:stuck", _cases(tmp_path), out, "--workers", "2")) == 0
    df = read_results([out])
    assert len(df) == 4 and df["case_id"].is_unique and df["error"].isna().all()


@pytest.mark.slow
def test_a_killed_ray_worker_stops_the_run_naming_its_case(tmp_path, plug, require_module):
    require_module("ray")
    args = [*_evaluate("hostile:stuck", _cases(tmp_path), tmp_path / "o", "--workers", "2"), "--backend", "ray"]
    _, code, err = _kill_a_worker(plug, args, 2)
    line = [x for x in err.splitlines() if x.startswith("mirrorpark:")]  # Ray logs lines of its own
    assert code == 1 and len(line) == 1, err
    assert "a Ray worker died" in line[0] and "while running " in line[0], err


# ---------------------------------------------------------- 2. sys.exit in a plug-in
@pytest.mark.parametrize("workers", ["1", "2"])
def test_a_plugin_that_calls_sys_exit_gives_error_rows_never_an_empty_run_or_a_hang(tmp_path, plug, workers):
    out = tmp_path / "o"
    assert cli(_evaluate("hostile:exits", _cases(tmp_path), out, "--workers", workers)) == 0
    df = read_results([out])
    assert len(df) == 4 and (df["error"] == "SystemExit: 0").all() and (df["planner_status"] == "error").all()


def test_a_plugins_own_keyboard_interrupt_in_a_worker_stops_the_run_in_one_line(tmp_path, plug, capsys):
    """In a worker it cannot be Ctrl-C (workers leave SIGINT to the parent): the run stops,
    exit 1, naming the case; with one worker it is taken for Ctrl-C (exit 130, resumable)."""
    out = tmp_path / "o"
    assert cli(_evaluate("hostile:interrupts", _cases(tmp_path), out, "--workers", "2")) == 1
    line = _one_line(capsys.readouterr().err)
    assert "raised KeyboardInterrupt: planner's own" in line and "rerun the same command to resume" in line
    case = line.split("error: ")[1].split(" raised")[0]
    assert case in {sc.case_id for sc in load_case_file(tmp_path / "cases.csv")}


def test_check_planner_reports_a_sys_exit_as_a_problem(plug, capsys):
    assert cli(["check-planner", "hostile:exits"]) == 1
    assert "act(obs, info) at step 0 raised SystemExit: 0" in capsys.readouterr().err


# ------------------------------------------------- 3. a status that is not a string
def test_a_status_that_is_not_a_string_keeps_every_episode(tmp_path, plug):
    out = tmp_path / "o"
    assert cli(_evaluate("hostile:number", _cases(tmp_path), out, "--workers", "1")) == 0
    df = read_results([out])
    assert len(df) == 4 and (df["planner_status"] == "3").all() and df["error"].isna().all()
    assert not (out / "journal.rejected.jsonl").exists()
    before = df.set_index("case_id")["episode_wall_s"]
    assert cli(_evaluate("hostile:number", _cases(tmp_path), out, "--workers", "1")) == 0  # nothing runs again
    assert read_results([out]).set_index("case_id")["episode_wall_s"].equals(before)


# ------------------------------------------------------- 4. layouts keyed by content
def _lot(folder: Path, seed: int, name: str | None = None, shift: float = 0.0) -> Path:
    lot = generate_lot(seed, 1)
    d = json.loads(write_layout(lot, folder / "tmp.json").read_text())
    (folder / "tmp.json").unlink()
    d["start"]["x"] += shift
    if name:
        d["name"] = name
    path = folder / f"{(name or lot.name)[:40]}-{seed}-{shift}.json"
    path.write_text(json.dumps(d))
    return path


def test_two_different_layouts_of_one_name_are_refused_in_one_line(tmp_path, capsys):
    a, b = _lot(tmp_path, 1, "same"), _lot(tmp_path, 2, "same")
    args = ["evaluate", "--planner", "guide-only", "--layouts", str(a), str(b), "--out", str(tmp_path / "o")]
    assert cli(args) == 2
    assert "two different layouts are named 'same'" in _one_line(capsys.readouterr().err)
    twin = tmp_path / "twin.json"
    twin.write_text(a.read_text())  # the same layout twice: run once
    args = ["evaluate", "--planner", "guide-only", "--layouts", str(a), str(twin), "--out", str(tmp_path / "o")]
    assert cli([*args, "--quiet"]) == 0 and len(read_results([tmp_path / "o"])) == 1


def test_an_edited_layout_runs_again_and_an_unchanged_one_does_not(tmp_path, capsys):
    folder = tmp_path / "lots"
    folder.mkdir()
    edited, kept = _lot(folder, 3, "edited"), _lot(folder, 4, "kept")
    args = ["evaluate", "--planner", "guide-only", "--layouts", str(folder), "--out", str(tmp_path / "o"), "--quiet"]
    assert cli(args) == 0
    first = read_results([tmp_path / "o"]).set_index("case_id")
    d = json.loads(edited.read_text())
    d["start"]["x"] += 0.3
    edited.write_text(json.dumps(d))
    with _warnings_shown():
        assert cli(args) == 0
    assert "1 layout(s) changed since their rows were stored: run again" in capsys.readouterr().err
    second = read_results([tmp_path / "o"]).set_index("case_id")
    assert len(second) == 2 and second.loc["kept", "episode_wall_s"] == first.loc["kept", "episode_wall_s"]
    assert second.loc["edited", "layout_key"] != first.loc["edited", "layout_key"]
    assert second.loc["edited", "path_x"][0] == pytest.approx(first.loc["edited", "path_x"][0] + 0.3, abs=1e-3)
    assert kept.exists()


# ------------------------------------------------ 5. foreign or partial result tables
@pytest.mark.parametrize("columns", [{"a": [1]}, {"planner": ["p"], "case_id": ["c"]}])
def test_a_foreign_table_is_refused_by_every_command_naming_file_and_columns(tmp_path, capsys, columns):
    table = tmp_path / "t.parquet"
    pd.DataFrame(columns).to_parquet(table)
    folder = tmp_path / "run"
    folder.mkdir()
    pd.DataFrame(columns).to_parquet(folder / "results.parquet")
    commands = [
        ["report", str(table), "--out", str(tmp_path / "r")],
        ["diff", "--before", str(table), "--after", str(table)],
        ["compare", str(table)],
        ["export", str(table), "--trajectories", str(tmp_path / "x")],
        ["evaluate", "--planner", "guide-only", "--sample", "smoke", "--types", "angle", "--out", str(folder)],
    ]
    for args in commands:
        assert cli(args) == 2, args
        line = _one_line(capsys.readouterr().err)
        named = line.split("lacks the column(s) ")[1].split(", ")
        assert named and not set(named) & set(columns) and set(named) <= set(REQUIRED), line
        assert ("t.parquet" in line) or ("results.parquet" in line), line


# ---------------------------------------------------- 6. a damaged environment.jsonl
@pytest.mark.parametrize("damage", [b"42\n", b"\xff\xfe\n", b"[1, 2]\n"])
def test_a_damaged_environment_log_is_skipped_by_line_and_the_run_resumes(tmp_path, damage, capsys):
    cases = _cases(tmp_path, HEADER + "reverse,6,4.82,2.3,10,2.5\nreverse,6,4.82,2.3,20,2.5\n")
    out = tmp_path / "o"
    assert cli(_evaluate("guide-only", cases, out)) == 0
    with (out / "environment.jsonl").open("ab") as f:
        f.write(damage)
    more = _cases(tmp_path, HEADER + "reverse,6,4.82,2.3,10,2.5\nreverse,6,4.82,2.3,30,2.5\n", "more.csv")
    with _warnings_shown():
        assert cli(_evaluate("guide-only", more, out)) == 0
    assert "environment.jsonl:2: skipped, not a run's record (a JSON object)" in capsys.readouterr().err
    assert len(read_results([out])) == 3


# ---------------------------------------------------------------- 7. parser limits
def _deep(n: int) -> str:
    return "[" * n + "]" * n


@pytest.mark.parametrize(
    "name, text, message",
    [
        ("big.json", '[{"parking_type": "reverse", "road_width": ' + "9" * 400 + ", " + '"slot_length": 4.82, '
         '"slot_width": 2.3, "theta0_deg": 10, "y0": 2.5}]', "case 1: int too large"),
        ("huge.json", "[" + "9" * 5000 + "]", "JSON not readable"),
        ("wide.csv", HEADER + "reverse,6,4.82,2.3,10," + "2" * 140_000 + "\n", "line 2: not readable as CSV"),
        ("deep.json", _deep(100_000), "JSON nested too deeply"),
    ],
)  # fmt: skip
def test_case_files_past_the_parsers_limits_are_refused_naming_the_file(tmp_path, capsys, name, text, message):
    path = _cases(tmp_path, text, name)
    assert cli(_evaluate("guide-only", path, tmp_path / "o")) == 2
    line = _one_line(capsys.readouterr().err)
    assert line.startswith(f"mirrorpark: error: {path}: ") and message in line, line


@pytest.mark.parametrize(
    "name, content, message",
    [
        ("deep.json", _deep(100_000).encode(), "JSON nested too deeply"),
        ("deep.yaml", _deep(100_000).encode(), "YAML nested too deeply"),
        ("deep2.yaml", ("a: " + _deep(3000)).encode(), "YAML nested too deeply"),
        ("latin.yaml", b"name: caf\xe9\n", "not UTF-8 text (byte 9)"),
    ],
)
def test_layout_and_config_files_past_the_parsers_limits_are_refused_naming_the_file(
    tmp_path, capsys, name, content, message
):
    path = tmp_path / name
    path.write_bytes(content)
    assert cli(["evaluate", "--planner", "guide-only", "--layouts", str(path), "--out", str(tmp_path / "o")]) == 2
    assert message in _one_line(capsys.readouterr().err)
    if name.endswith(".yaml"):
        assert cli(["grid", "--config", str(path)]) == 2
        line = _one_line(capsys.readouterr().err)
        assert str(path) in line and message in line
    with pytest.raises(ValueError, match=re.escape(f"{path}: {message}")):  # a layout file given to the environment
        gym.make("MirrorPark-v0").reset(options={"layout": str(path)})


def test_notes_that_are_not_utf8_are_named(tmp_path, capsys):
    cases = _cases(tmp_path, HEADER + "reverse,6,4.82,2.3,10,2.5\n")
    assert cli(_evaluate("guide-only", cases, tmp_path / "o")) == 0
    notes = tmp_path / "notes.md"
    notes.write_bytes(b"# notes \xff\n")
    assert cli(["report", str(tmp_path / "o"), "--out", str(tmp_path / "r"), "--notes", str(notes)]) == 2
    assert f"{notes}: not UTF-8 text (byte 8)" in _one_line(capsys.readouterr().err)


# ----------------------------------------------------------------------- 8. bench
def test_bench_refuses_unknown_planners_and_a_bad_step_count(capsys):
    assert cli(["bench", "--planners", "nonexistent"]) == 2
    assert "planner: unknown 'nonexistent'" in _one_line(capsys.readouterr().err)
    with pytest.raises(SystemExit) as e:
        cli(["bench", "--env-steps", "-5"])
    assert e.value.code == 2 and "--env-steps: must be >= 1, got -5" in capsys.readouterr().err


# -------------------------------------------------------- 9. collect without minari
def test_collect_without_the_rl_extra_refuses_before_any_case_runs(tmp_path, monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "minari", None)  # import minari now fails
    out = tmp_path / "demo"
    assert cli(["collect", "--planner", "guide-only", "--sample", "smoke", "--out", str(out), "--quiet"]) == 2
    assert "collect needs the rl extra (minari is missing)" in _one_line(capsys.readouterr().err)
    assert not out.exists()


# ----------------------------------------------------------- 10. long layout names
def test_a_layout_name_of_5000_characters_is_refused_at_load(tmp_path, capsys):
    path = _lot(tmp_path, 5, "x" * 5000)
    assert cli(["evaluate", "--planner", "guide-only", "--layouts", str(path), "--out", str(tmp_path / "o")]) == 2
    line = _one_line(capsys.readouterr().err)
    assert "name: String should have at most 120 characters" in line and len(line) < 300


# ---------------------------------------------------------- 11. a planner that hangs
@pytest.mark.parametrize("workers", ["1", "2"])
def test_a_hanging_call_becomes_its_cases_error_row_at_the_call_limit(tmp_path, plug, workers):
    out = tmp_path / "o"
    cases = _cases(tmp_path, HEADER + "reverse,6,4.82,2.3,10,2.5\nangle,4,4.82,2.3,0,2\n")
    assert cli(_evaluate("hostile:hangs", cases, out, "--workers", workers, "--call-limit", "0.5")) == 0
    df = read_results([out])
    assert len(df) == 2 and df["error"].str.startswith("CallTimeout: act ran past the 0.5 s safety net").all()


def test_the_call_limit_is_checked(capsys):
    with pytest.raises(SystemExit):
        cli(["evaluate", "--planner", "guide-only", "--call-limit", "-1"])
    assert "--call-limit: expected finite seconds >= 0, got '-1'" in capsys.readouterr().err


# ------------------------------------------------------ 12. a million repeated cases
def test_repeated_rows_of_a_case_file_are_built_once(tmp_path, monkeypatch):
    built = []
    real = Scenario.build
    monkeypatch.setattr(Scenario, "build", lambda self, *a, **k: built.append(1) or real(self, *a, **k))
    for name, text in [
        ("many.csv", HEADER + "reverse,6,4.82,2.3,10,2.5\n" * 50_000 + "angle,4,4.82,2.3,0,2\n"),
        ("many.json", json.dumps([dict(zip(CASE_FIELDS, ["reverse", 6, 4.82, 2.3, 10, 2.5]))] * 50_000)),
    ]:
        built.clear()
        cases = load_case_file(_cases(tmp_path, text, name))
        assert len(cases) == 50_000 + name.endswith(".csv") and len(built) == 1 + name.endswith(".csv")
        unique, repeats = cases_module.unique(cases)
        assert repeats == 49_999 and len(unique) == 1 + name.endswith(".csv")


# --------------------------------------------------------- 13. BOM and planner prints
def test_a_csv_with_a_byte_order_mark_is_read(tmp_path):
    f = tmp_path / "bom.csv"
    f.write_text(HEADER + "reverse,6,4.82,2.3,10,2.5\n", encoding="utf-8-sig")
    assert [sc.case_id for sc in load_case_file(f)] == ["reverse_rw6.00_sl4.82_sw2.30_th+10_y2.50"]


@pytest.mark.parametrize("workers", ["1", "2"])
def test_a_planners_print_never_reaches_the_json_line(tmp_path, plug, capsys, workers):
    cases = _cases(tmp_path, HEADER + "reverse,6,4.82,2.3,10,2.5\nangle,4,4.82,2.3,0,2\n")
    assert cli([*_evaluate("hostile:loud", cases, tmp_path / "o", "--workers", workers), "--json"]) == 0
    out = capsys.readouterr().out
    assert out.count("\n") == 1 and json.loads(out)["cases"] == 2


# ------------------------------------------------- property: hostile files load or name themselves
_json = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=8),
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=8), inner, max_size=4),
    max_leaves=20,
)
_field = st.sampled_from(["reverse", "angle", "parallel", "", "nan", "inf", "-1", "1e400", "6", "4.82", "2.3", "x"])
_layout_keys = st.sampled_from(["name", "start", "target", "obstacles", "slot", "bounds", "road_width", "vehicle"])


@st.composite
def _hostile_file(draw) -> tuple[str, bytes]:
    kind = draw(st.sampled_from(["cases.json", "cases.csv", "layout.json", "layout.yaml", "layout.csv", "bytes"]))
    if kind == "bytes":
        return draw(st.sampled_from(["a.json", "a.yaml", "a.csv"])), draw(st.binary(max_size=200))
    if kind == "cases.csv":
        header = draw(st.sampled_from([list(CASE_FIELDS), [*CASE_FIELDS, "extra"], list(CASE_FIELDS[:4])]))
        rows = draw(st.lists(st.lists(_field, min_size=3, max_size=8), max_size=4))
        text = "\n".join(",".join(r) for r in [header, *rows])
        return kind, (("\ufeff" if draw(st.booleans()) else "") + text).encode()
    if kind == "layout.csv":
        return kind, ",".join(draw(st.lists(_field, max_size=20))).encode()
    if kind == "cases.json":
        value = draw(
            st.lists(st.dictionaries(st.sampled_from(list(CASE_FIELDS)), _json, max_size=6), max_size=3) | _json
        )
        return kind, json.dumps(value).encode()
    value = draw(st.dictionaries(_layout_keys, _json, max_size=8) | _json)
    text = json.dumps(value)  # YAML reads JSON too
    if draw(st.booleans()):
        depth = draw(st.integers(0, 3000))
        text = "[" * depth + text + "]" * depth
    return kind, text.encode()


@pytest.mark.property
@settings(deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(_hostile_file())
def test_hostile_files_load_or_are_refused_in_one_line_naming_the_file(tmp_path_factory, item):
    name, content = item
    folder = tmp_path_factory.mktemp("hostile")
    path = folder / f"f.{name.rsplit('.', 1)[1]}"
    path.write_bytes(content)
    loader = load_case_file if name.startswith("cases") else (lambda p: load_many([p]))
    try:
        loaded = loader(path)
    except ValueError as err:
        msg = str(err)
        assert msg.startswith(f"{path}") and "\n" not in msg and len(msg) < 2000, msg
    else:
        assert loaded


def test_the_command_line_run_in_process_hands_back_the_callers_hooks(tmp_path, capsys):
    """``cli.main`` called from a program (a notebook, a test) leaves its warning printer and
    SIGTERM handler in place only while the command runs."""
    mine = lambda *a, **k: None  # noqa: E731
    before_show, warnings.showwarning = warnings.showwarning, mine
    before_term = signal.signal(signal.SIGTERM, signal.SIG_DFL)
    try:
        assert cli(["grid", "--json"]) == 0
        assert warnings.showwarning is mine and signal.getsignal(signal.SIGTERM) is signal.SIG_DFL
    finally:
        warnings.showwarning = before_show
        signal.signal(signal.SIGTERM, before_term)


def test_a_repeated_row_is_the_same_only_with_the_same_types(tmp_path):
    """Rows are built once per distinct row, and ``true`` is not the row of an equal ``1``."""
    row = dict(zip(CASE_FIELDS, ["reverse", 6, 4.82, 2.3, 1, 2.5]))
    path = _cases(tmp_path, json.dumps([row, {**row, "theta0_deg": True}]), "typed.json")
    with pytest.raises(ValueError, match=r"case 2: theta0_deg: expected a number or a name, got True"):
        load_case_file(path)
