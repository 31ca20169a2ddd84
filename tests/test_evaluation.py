"""Evaluation: summaries by hand, resumable runs, error rows, case files, Ray, report."""

from __future__ import annotations

import json
import math

import numpy as np
import pandas as pd
import pytest

from evaluation import registry
from evaluation.cases import load_case_file
from evaluation.cli import main as cli
from evaluation.metrics import comfortable, headline, odd_size, summary
from evaluation.report import write_report
from evaluation.runner import evaluate
from evaluation.store import ResultStore, read_results
from planners.base import Policy

A = "reverse_rw6.00_sl4.82_sw2.32_th+40_y3.00"
B = "angle_rw3.50_sl4.82_sw2.77_th+10_y1.30"
C = "parallel_rw4.00_sl7.32_sw2.50_th+10_y1.30"


def _row(planner, ptype, success, switches, t, times, **kw):
    base = dict(
        planner=planner,
        case_id=f"{ptype}_{kw.pop('k', 0)}",
        parking_type=ptype,
        road_width=4.0,
        slot_length=5.0,
        slot_width=2.5,
        theta0_deg=0.0,
        y0=kw.pop("y0", 2.0),
        success=success,
        switches=switches,
        parking_time_s=t,
        plan_times_ms=times,
        episode_wall_s=1.0,
        failed_criterion=None if success else "time",
        planner_status="ok",
    )
    base.update(kw)
    return base


def hand_table() -> pd.DataFrame:
    return pd.DataFrame(
        [
            _row("mirror", "parallel", True, 2, 20.0, [10, 20], k=1, y0=1.0),
            _row("mirror", "parallel", False, 9, 180.0, [30], k=2, y0=2.0),
            _row("mirror", "reverse", True, 4, 30.0, [40, 50, 60], k=3, y0=1.0),
            _row("mirror", "reverse", True, 0, 10.0, [70], k=4, y0=2.0),
            _row("base", "parallel", False, 1, 180.0, [100], k=1, y0=1.0),
            _row("base", "parallel", False, 1, 180.0, [100], k=2, y0=2.0),
            _row("base", "reverse", True, 6, 40.0, [200], k=3, y0=1.0),
            _row("base", "reverse", False, 1, 180.0, [300], k=4, y0=2.0),
        ]
    )


def test_summary_numbers_from_a_hand_made_table():
    s = summary(hand_table(), "mirror")
    assert s["cases"] == 4
    assert s["success_rate"] == {"parallel": 0.5, "reverse": 1.0, "angle": None, "all": 0.75}
    assert s["mean_switches"] == pytest.approx((2 + 4 + 0) / 3)  # successes only
    assert s["mean_parking_time_s"] == pytest.approx(20.0)
    # All seven calls pooled: 10 20 30 40 50 60 70 -> median 40, p95 by linear interpolation 67.
    assert s["plan_time_ms"]["median"] == 40.0
    assert s["plan_time_ms"]["p95"] == pytest.approx(67.0)
    assert odd_size(hand_table()) == {
        "base": {"parallel": 0, "reverse": 1, "angle": 0, "all": 1},
        "mirror": {"parallel": 1, "reverse": 2, "angle": 0, "all": 3},
    }
    h = {r["measure"]: r["ours"] for r in headline(hand_table(), "mirror", "base")}
    assert h["success rate"] == pytest.approx(100 * (0.75 - 0.25) / 0.25)  # +200 %
    assert h["ODD size"] == pytest.approx(200.0)
    assert h["direction switches"] == pytest.approx(100 * (2.0 - 6.0) / 6.0)
    # Paired: only reverse_3 parks with both (mirror 4 switches, 30 s; base 6, 40 s).
    assert h["direction switches, cases both park"] == pytest.approx(100 * (4 - 6) / 6)
    assert h["parking time, cases both park"] == pytest.approx(100 * (30 - 40) / 40)


def test_report_to_a_markdown_file_puts_figures_beside_it_and_appends_notes(tmp_path):
    from evaluation.report import write_report

    notes = tmp_path / "notes.md"
    notes.write_text("## Reading\n\nHand-written.\n")
    path = write_report(hand_table(), tmp_path / "docs" / "results.md", baseline="base", notes=notes)
    assert path == tmp_path / "docs" / "results.md"
    text = path.read_text()
    assert "![success_by_type](results/success_by_type.png)" in text
    assert (tmp_path / "docs" / "results" / "success_by_type.png").is_file()
    assert text.rstrip().endswith("Hand-written.")
    assert "| parking time, cases both park | not stated | -25.0 % |" in text


class _Instant(Policy):
    """Gives up at once: an episode of a few steps, for runner tests."""

    name = "instant"
    calls: list[str] = []

    def reset(self, geometry):
        _Instant.calls.append(geometry.scenario.case_id)
        self.gave_up = True

    def act(self, obs, info):
        return np.zeros(2, dtype=np.float32)


class _Interrupt(_Instant):
    def reset(self, geometry):
        if len(_Instant.calls) >= 2:
            raise KeyboardInterrupt  # as if the user pressed Ctrl-C during the third case
        super().reset(geometry)


@pytest.fixture
def stub_planners(monkeypatch):
    _Instant.calls = []
    monkeypatch.setitem(registry.PLANNERS, "instant", _Instant)
    monkeypatch.setitem(registry.PLANNERS, "interrupt", _Interrupt)


def _scenarios(*ids):
    from mirrorpark_env import Scenario

    return [Scenario.from_case_id(i) for i in ids]


def test_resume_after_interruption_repeats_and_loses_nothing(tmp_path, stub_planners, monkeypatch):
    cases = _scenarios(A, B, C)
    monkeypatch.setitem(registry.PLANNERS, "instant", _Interrupt)
    with pytest.raises(KeyboardInterrupt):
        evaluate("instant", cases, tmp_path, workers=1, progress=False)
    assert len(ResultStore(tmp_path).table()) == 2  # two finished cases were kept
    with (tmp_path / "journal.jsonl").open("a") as f:
        f.write('{"planner": "instant", "case_id": "' + C + '", "succ')  # a line cut short
    monkeypatch.setitem(registry.PLANNERS, "instant", _Instant)
    _Instant.calls = []
    evaluate("instant", cases, tmp_path, workers=1, progress=False)
    assert _Instant.calls == [C]  # only the unfinished case ran again
    df = read_results([tmp_path])
    assert sorted(df["case_id"]) == sorted([A, B, C]) and not df.duplicated(["planner", "case_id"]).any()
    assert (tmp_path / "results.parquet").exists()


def test_rows_name_the_machine_and_packages_they_ran_with(tmp_path, stub_planners):
    """Each run notes its environment once in the results folder; each row names it; an
    exported table carries the environments its rows name; a run with nothing to do adds
    no line."""
    from evaluation.store import environments_of, export_table

    evaluate("instant", _scenarios(A, B), tmp_path / "r", workers=1, progress=False)
    evaluate("instant", _scenarios(A, B), tmp_path / "r", workers=1, progress=False)  # nothing to do
    store = ResultStore(tmp_path / "r")
    envs = store.environments()
    assert len(envs) == 1 and envs[0]["cases"] == 2 and envs[0]["planner"] == "instant"
    assert envs[0]["packages"]["numpy"] == np.__version__ and envs[0]["python"] and envs[0]["cpu"]
    df = store.table()
    assert set(df["environment"]) == {envs[0]["id"]}
    stranger = {**envs[0], "id": "not-in-rows", "cpu": "another"}
    path = export_table(df, tmp_path / "x", "instant", environments=[*envs, stranger, envs[0]])
    assert environments_of(path) == envs
    assert set(pd.read_parquet(path)["environment"]) == {envs[0]["id"]}


def test_a_folder_resumes_only_with_the_code_its_rows_came_from(tmp_path, stub_planners, monkeypatch, capsys):
    """After a change to the code, resuming a results folder would hand back the old code's
    rows as the new code's: refused, naming the folder and the way out, unless asked. A
    folder from before sources were recorded, and another planner's rows, do not count."""
    from evaluation import provenance

    evaluate("instant", _scenarios(A), tmp_path / "r", workers=1, progress=False)
    assert ResultStore(tmp_path / "r").environments()[0]["source"] == provenance.source_id("instant")
    evaluate("instant", _scenarios(A, B), tmp_path / "r", workers=1, progress=False)  # the same code: resumes
    monkeypatch.setattr(provenance, "source_id", lambda planner: "changed")
    _Instant.calls = []
    with pytest.raises(ValueError, match=r"r: its 2 results of 'instant' came from other code.*--mixed-code"):
        evaluate("instant", _scenarios(A, B, C), tmp_path / "r", workers=1, progress=False)
    assert _Instant.calls == []  # refused before anything ran
    cases = tmp_path / "cases.csv"
    cases.write_text("parking_type,road_width,slot_length,slot_width,theta0_deg,y0\nreverse,6,4.82,2.32,40,3.0\n")
    args = ["evaluate", "--planner", "instant", "--cases", str(cases), "--out", str(tmp_path / "r"), "--quiet"]
    assert cli(args) == 2
    assert "came from other code" in capsys.readouterr().err
    evaluate("instant", _scenarios(A, B, C), tmp_path / "r", workers=1, progress=False, mixed_code=True)
    assert _Instant.calls == [C] and ResultStore(tmp_path / "r").environments()[-1]["source"] == "changed"
    evaluate("instant", _scenarios(A, B, C), tmp_path / "r", workers=1, progress=False)  # now "changed" is the code
    old = tmp_path / "old"  # a folder from before sources were recorded
    evaluate("instant", _scenarios(A), old, workers=1, progress=False)
    log = old / "environment.jsonl"
    log.write_text("".join(json.dumps({k: v for k, v in json.loads(x).items() if k != "source"}) + "\n"
                           for x in log.read_text().splitlines()))  # fmt: skip
    monkeypatch.setattr(provenance, "source_id", lambda planner: "again")
    evaluate("instant", _scenarios(A, B), old, workers=1, progress=False)
    monkeypatch.setitem(registry.PLANNERS, "other", _Instant)
    evaluate("other", _scenarios(A), tmp_path / "r", workers=1, progress=False)  # another planner's rows


@pytest.fixture
def strategy_copy(tmp_path, monkeypatch):
    """A copy of planners/mirror/strategies/aimed.py that ``source_id`` reads in its place: edit it freely."""
    from evaluation import provenance

    files = provenance._row_files()
    copy = tmp_path / "aimed.py"
    copy.write_bytes(dict(files)["planners/mirror/strategies/aimed.py"].read_bytes())
    swapped = tuple((n, copy if n == "planners/mirror/strategies/aimed.py" else f) for n, f in files)
    monkeypatch.setattr(provenance, "_row_files", lambda: swapped)
    return copy


def test_a_refused_resume_names_the_files_that_changed(tmp_path, stub_planners, strategy_copy):
    evaluate("instant", _scenarios(A), tmp_path / "r", workers=1, progress=False)
    strategy_copy.write_bytes(strategy_copy.read_bytes() + b"\n")
    with pytest.raises(ValueError, match=r"changed: planners/mirror/strategies/aimed.py\):"):
        evaluate("instant", _scenarios(A, B), tmp_path / "r", workers=1, progress=False)


def test_the_source_id_changes_with_a_planner_file_and_an_rl_model_file(tmp_path, strategy_copy):
    from evaluation import provenance

    names = {n for n, _ in provenance._row_files()}
    assert {"planners/mirror/strategies/aimed.py", "mirrorpark_env/env.py", "evaluation.runner"} <= names
    assert "configs/vehicle.yaml" in names
    before = provenance.source_id("mirror")
    assert before == provenance.source_id("mirror-cold")  # the code, not the name
    strategy_copy.write_bytes(strategy_copy.read_bytes() + b"\n")
    assert provenance.source_id("mirror") != before
    model = tmp_path / "model.zip"
    model.write_bytes(b"one")
    first = provenance.source_id(f"rl:{model}")
    model.write_bytes(b"two")
    assert provenance.source_id(f"rl:{model}") != first


def test_a_case_that_raises_is_an_error_row(tmp_path, stub_planners):
    from mirrorpark_env import Scenario

    bad = Scenario("reverse", 6.0, 4.82, 1.5, 0.0, 2.0)  # narrower than the car: fails at reset
    evaluate("instant", [bad, *_scenarios(A)], tmp_path, workers=1, progress=False)
    df = read_results([tmp_path]).set_index("case_id")
    assert df.loc[bad.case_id, "planner_status"] == "error"
    assert "slot too small" in df.loc[bad.case_id, "error"]
    assert not df.loc[bad.case_id, "success"]
    assert df.loc[A, "planner_status"] != "error"


def test_case_files(tmp_path):
    good = tmp_path / "cases.csv"
    good.write_text("parking_type,road_width,slot_length,slot_width,theta0_deg,y0\nreverse,6,4.82,2.3,10,2.5\n")
    (sc,) = load_case_file(good)
    assert sc.case_id == "reverse_rw6.00_sl4.82_sw2.30_th+10_y2.50"
    js = tmp_path / "cases.json"
    js.write_text(
        json.dumps(
            [
                {
                    "parking_type": "angle",
                    "road_width": 4,
                    "slot_length": 4.82,
                    "slot_width": 2.0,
                    "theta0_deg": 0,
                    "y0": 2.0,
                }
            ]
        )
    )
    assert load_case_file(js)[0].parking_type.value == "angle"
    bad = tmp_path / "bad.csv"
    bad.write_text("parking_type,road_width,slot_length,slot_width,y0\nreverse,6,4.82,2.3,2.5\n")
    with pytest.raises(ValueError, match=r"bad.csv: CSV header lacks theta0_deg"):
        load_case_file(bad)
    bad.write_text("parking_type,road_width,slot_length,slot_width,theta0_deg,y0\ndiagonal,6,4.82,2.3,0,2.5\n")
    with pytest.raises(ValueError, match=r"case 1: parking_type: unknown 'diagonal'"):
        load_case_file(bad)
    bad.write_text("parking_type,road_width,slot_length,slot_width,theta0_deg,y0\nreverse,6,4.82,abc,0,2.5\n")
    with pytest.raises(ValueError, match=r"case 1: slot_width: expected a number"):
        load_case_file(bad)
    js.write_text("{not json")
    with pytest.raises(ValueError, match="not valid JSON"):
        load_case_file(js)
    with pytest.raises(ValueError, match="must end in .json or .csv"):
        load_case_file(tmp_path / "cases.txt")


def test_unknown_planner_is_named(tmp_path):
    with pytest.raises(
        ValueError,
        match=r"planner: unknown .astar.; available: mirror, mirror-exhaustive, mirror-cold, mirror-paper, "
        r"mirror-guided, mirror-multistart, guide-only, hybrid-astar",
    ):
        evaluate("astar", _scenarios(A), tmp_path, progress=False)
    with pytest.raises(ValueError, match=r"planner: 'mirror-value' is now mirror \(renamed on 2026-12-02"):
        evaluate("mirror-value", _scenarios(A), tmp_path, progress=False)
    assert cli(["evaluate", "--planner", "nope", "--sample", "smoke", "--out", str(tmp_path)]) == 2


def test_two_cases_on_local_ray(tmp_path, require_module):
    ray = require_module("ray")
    try:
        evaluate("mirror", _scenarios(A, B), tmp_path, workers=2, backend="ray", progress=False)
    finally:
        ray.shutdown()
    df = read_results([tmp_path])
    assert sorted(df["case_id"]) == sorted([A, B])
    assert (df["planner_status"] != "error").all() and df["success"].all()


def test_grid_count_json(capsys):
    assert cli(["grid", "--count", "--json"]) == 0
    assert json.loads(capsys.readouterr().out) == {
        "parallel": 12420,
        "reverse": 46629,
        "angle": 11385,
        "total": 70434,
        "feasible": {"parallel": 12075, "reverse": 40977, "angle": 10005, "total": 63057},
    }


def test_report_writes_markdown_and_figures(tmp_path):
    path = write_report(hand_table(), tmp_path, baseline="base")
    text = path.read_text()
    assert "+40.6 %" in text and "+200.0 %" in text  # the paper's figure beside ours
    for name in (
        "success_by_type",
        "success_vs_road_width",
        "sensitivity_slot",
        "sensitivity_y0",
        "sensitivity_y1",
        "odd_parallel",
        "odd_reverse",
        "efficiency",
        "plan_time",
    ):
        assert (tmp_path / f"{name}.png").stat().st_size > 1000
        assert f"({name}.png)" in text


def test_evaluate_cli_json_summary(tmp_path, capsys):
    cases = tmp_path / "cases.csv"
    cases.write_text("parking_type,road_width,slot_length,slot_width,theta0_deg,y0\nreverse,7,4.82,2.32,40,3.0\n")
    assert (
        cli(
            [
                "evaluate",
                "--planner",
                "mirror",
                "--cases",
                str(cases),
                "--out",
                str(tmp_path / "r"),
                "--workers",
                "1",
                "--quiet",
                "--json",
            ]
        )
        == 0
    )
    s = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert s["planner"] == "mirror" and s["cases"] == 1 and s["success_rate"]["reverse"] == 1.0
    assert s["success_rate"]["parallel"] is None and not math.isnan(s["plan_time_ms"]["median"])


def test_store_rolls_the_journal_into_parquet_parts(tmp_path):
    store = ResultStore(tmp_path, part_rows=3)
    for i in range(7):
        store.append({"planner": "p", "case_id": f"c{i}", "success": i % 2 == 0, "plan_times_ms": [1.0, 2.0]})
    assert len(list((tmp_path / "parts").glob("part-*.parquet"))) == 2  # 6 rows rolled over
    assert len((tmp_path / "journal.jsonl").read_text().splitlines()) == 1
    df = ResultStore(tmp_path).table()
    assert sorted(df["case_id"]) == [f"c{i}" for i in range(7)]
    assert ResultStore(tmp_path).done() == {("p", f"c{i}") for i in range(7)}
    store.append({"planner": "p", "case_id": "c0", "success": False})  # a later row for a case wins
    df = ResultStore(tmp_path).table().set_index("case_id")
    assert len(df) == 7 and not df.loc["c0", "success"]


def test_mirror_demo_writes_its_figure_and_animation(tmp_path):
    from PIL import Image

    from evaluation.mirror_demo import DEMO_CASES, mirror_demo

    (e,) = mirror_demo(tmp_path, ("angle",), every=20)
    assert e.case_id == DEMO_CASES["angle"].case_id and e.success and e.plans >= 1
    assert e.figure == tmp_path / "mirror_angle.png" and e.figure.stat().st_size > 10_000
    with Image.open(e.animation) as gif:
        assert gif.n_frames >= 5  # ~16 s driven, a frame every 2 s
    with pytest.raises(ValueError, match="types"):
        mirror_demo(tmp_path, ("diagonal",))


def test_odd_cells_pool_road_widths_and_nothing_else():
    """The paper's ODD: a cell is (type, SL, SW, theta0, y0); its runs are the road widths
    that hold it, and it is in the ODD at >= 95 % success: 3 of 3 is in, 2 of 3 is out."""
    from evaluation.metrics import odd_cells

    rows = []
    for rw, ok_a, ok_b in ((4.5, True, True), (4.0, True, False), (3.5, True, True)):
        rows.append(_row("m", "parallel", ok_a, 1, 10.0, [1], k=rw, y0=1.0, road_width=rw))  # cell A: 3 of 3
        rows.append(_row("m", "parallel", ok_b, 1, 10.0, [1], k=rw, y0=2.0, road_width=rw))  # cell B: 2 of 3
    # Another theta0, another slot length: cells of their own, never pooled with A or B.
    rows.append(_row("m", "parallel", True, 1, 10.0, [1], k=9, y0=1.0, theta0_deg=10.0))
    rows.append(_row("m", "parallel", False, 1, 10.0, [1], k=8, y0=1.0, slot_length=5.1))
    cells = odd_cells(pd.DataFrame(rows)).set_index(["theta0_deg", "slot_length", "y0"])
    assert cells.loc[(0.0, 5.0, 1.0), "runs"] == 3 and cells.loc[(0.0, 5.0, 1.0), "in_odd"]
    assert cells.loc[(0.0, 5.0, 2.0), "runs"] == 3 and not cells.loc[(0.0, 5.0, 2.0), "in_odd"]
    assert cells.loc[(10.0, 5.0, 1.0), "runs"] == 1 and cells.loc[(10.0, 5.0, 1.0), "in_odd"]
    assert cells.loc[(0.0, 5.1, 1.0), "runs"] == 1 and not cells.loc[(0.0, 5.1, 1.0), "in_odd"]
    assert odd_size(pd.DataFrame(rows))["m"] == {"parallel": 2, "reverse": 0, "angle": 0, "all": 2}


def test_success_over_feasible_cases():
    df = hand_table().assign(feasible=[True, False, True, True, True, False, True, True])
    s = summary(df, "mirror")
    assert s["success_rate"]["parallel"] == 0.5 and s["success_rate_feasible"]["parallel"] == 1.0
    assert s["success_rate_feasible"]["all"] == 1.0


def test_comfortable_slots_and_the_y0_target_by_hand():
    # Table II's car: 3.82 m long (1.25 x = 4.775 m), 1.67 m wide (+ 0.4 = 2.07 m).
    df = pd.DataFrame(
        [
            _row("m", "parallel", True, 1, 10.0, [1], k=1, slot_length=4.78, y0=1.6),  # comfortable
            _row("m", "parallel", False, 1, 10.0, [1], k=2, slot_length=4.77, y0=1.6),  # just too short
            _row("m", "reverse", False, 1, 10.0, [1], k=3, slot_width=2.07, y0=1.5),  # comfortable, y0 < 1.6
            _row("m", "angle", True, 1, 10.0, [1], k=4, slot_width=2.06, y0=2.0),  # just too narrow
        ]
    )
    assert list(comfortable(df)) == [True, False, True, False]
    s = summary(df.assign(feasible=[True, True, True, False]), "m")
    assert s["success_rate_comfortable"] == 0.5  # 1 of the 2 comfortable rows parked
    assert s["success_rate_y0_1.6_feasible"] == 0.5  # rows 1-2: feasible with y0 >= 1.6
