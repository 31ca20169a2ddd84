"""Interruptions (Ctrl-C, SIGKILL) and property tests (hypothesis) that keep MirrorPark from
losing or crashing: the second half of tests/test_reliability.py."""

from __future__ import annotations

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
from evaluation.cases import CASE_FIELDS, load_case_file
from evaluation.episode import case_fields
from evaluation.store import ResultStore, StoreWarning, read_results
from mirrorpark_env import Scenario

HEADER = ",".join(CASE_FIELDS) + "\n"


def _row(i: int, planner: str = "quick") -> dict:
    return {"planner": planner, "case_id": f"case{i:04d}", "success": bool(i % 2), "switches": i % 5}


def test_ctrl_c_with_several_workers_stops_cleanly_and_says_how_to_resume(tmp_path):
    """SIGINT to the whole process group mid-run: one line, exit 130, stored rows kept."""
    out = tmp_path / "o"
    proc = _start_slow_run(
        out,
        40,
        0.2,
        stderr=subprocess.PIPE,
        text=True,
        # A shell's background job inherits SIGINT ignored (pytest run with `&`), and so would
        # the child: give it the default disposition, as a terminal's foreground job has.
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
    _wait_for_rows(out, 3)
    os.killpg(proc.pid, signal.SIGINT)
    err = proc.communicate(timeout=60)[1].strip()
    assert proc.returncode == 130, err
    assert "Traceback" not in err and err.count("\n") == 0, err
    assert "rerun the same command to resume" in err
    stored = int(err.split("interrupted: ")[1].split()[0])
    assert stored == len(read_results([out])) >= 3


def test_sigterm_to_the_run_alone_stops_its_workers_and_keeps_what_is_stored(tmp_path):
    """SIGTERM to the main process only (``kill PID``, a scheduler's stop): it stops as at
    Ctrl-C, with exit 143, and its workers do not run on orphaned (they did, each until at
    least the case in hand was done: 1.4 s after the run with cases of 1 s)."""
    out = tmp_path / "o"
    proc = _start_slow_run(out, 40, 3.0, stderr=subprocess.PIPE, text=True)
    _wait_for_rows(out, 2)
    os.kill(proc.pid, signal.SIGTERM)
    err = proc.communicate(timeout=60)[1].strip()
    assert proc.returncode == 143, err
    assert "Traceback" not in err and err.count("\n") == 0, err
    assert err.startswith("mirrorpark: terminated:") and "rerun the same command to resume" in err
    stored = int(err.split("terminated: ")[1].split()[0])
    assert stored == len(read_results([out])) >= 2
    t0 = time.time()
    while time.time() - t0 < 1.0:  # an orphaned worker would run on to the end of its 3 s case
        try:
            os.killpg(proc.pid, 0)
        except ProcessLookupError:
            return
        time.sleep(0.05)
    raise AssertionError("worker processes still ran 1 s after the run stopped")


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


def _start_slow_run(out: Path, n: int, delay: float, **popen) -> subprocess.Popen:
    """``_SLOW_RUN`` into ``out`` in a process group of its own (its workers' too)."""
    script = _SLOW_RUN.format(out=str(out), n=n, delay=delay)
    return subprocess.Popen([sys.executable, "-c", script], start_new_session=True, **popen)


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


def test_sigkill_to_the_run_alone_takes_its_workers_with_it(tmp_path):
    """SIGKILL to the main process only: no clean-up runs, and the workers went on to the
    end of the case in hand; they now die with their parent. Cases take 10 s, so a worker
    left running would still run 3 s after the kill."""
    out = tmp_path / "o"
    proc = _start_slow_run(out, 40, 10.0, stderr=subprocess.DEVNULL)
    _wait_for_rows(out, 1, timeout=120)
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait(timeout=10)
    t0 = time.time()
    while time.time() - t0 < 3.0:
        try:
            os.killpg(proc.pid, 0)
        except ProcessLookupError:
            return
        time.sleep(0.05)
    left = [p.name for p in Path("/proc").iterdir() if p.name.isdigit() and _pgid(int(p.name)) == proc.pid]
    os.killpg(proc.pid, signal.SIGKILL)
    raise AssertionError(f"processes {left} still ran 3 s after the run was killed")


def _pgid(pid: int) -> int | None:
    try:
        return os.getpgid(pid)
    except ProcessLookupError:
        return None


def test_two_runs_on_one_folder_the_second_is_refused_and_the_first_loses_nothing(tmp_path):
    """Two runs appending to one store lost rows and repeated cases; now the second refuses
    at once, naming the first, and the first ends with every case once."""
    from evaluation.cli import main as cli

    out = tmp_path / "o"
    first = _start_slow_run(out, 30, 0.2, stderr=subprocess.PIPE, text=True)
    _wait_for_rows(out, 1)
    assert cli(["evaluate", "--planner", "guide-only", "--sample", "smoke", "--out", str(out), "--quiet"]) == 2
    assert first.wait(timeout=120) == 0, first.stderr.read()
    rows = read_results([out])
    assert len(rows) == 30 and rows["case_id"].is_unique and set(rows["planner"]) == {"slow"}
