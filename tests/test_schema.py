"""The result schema (``evaluation/schema.py``): every column a row carries is declared, its
values have their declared types, and every exported column survives export and ``diff``."""

from __future__ import annotations

import json
import math

import numpy as np
import pandas as pd
import pytest

from evaluation import registry
from evaluation.diff import compare
from evaluation.runner import run_case
from evaluation.schema import BY_NAME, EXPORT_COLUMNS, MACHINE_COLUMNS, column_label, type_error, unknown_columns
from evaluation.store import check_row, export_table, read_results
from mirrorpark_env import Scenario
from mirrorpark_env.layout_io import load_layouts

CASES = ("reverse_rw6.00_sl4.82_sw2.47_th+0_y1.40", "parallel_rw4.50_sl6.72_sw2.50_th+10_y1.10")


@pytest.fixture(scope="module")
def rows() -> list[dict]:
    """Real rows: two grid cases, a layout, and a case whose planner failed to build."""
    out = [run_case("guide-only", Scenario.from_case_id(c)) for c in CASES]
    out.append(run_case("guide-only", load_layouts("configs/layouts/tpcap/per03.csv")[0]))
    broken = pytest.MonkeyPatch()
    broken.setattr(registry, "make_policy", lambda name: 1 / 0)
    try:
        out.append(run_case("guide-only", Scenario.from_case_id(CASES[0])))
    finally:
        broken.undo()
    return out


def test_every_column_of_a_row_is_declared_and_typed(rows):
    assert rows[0]["success"] and rows[-1]["error"].startswith("ZeroDivisionError")
    assert "path_x" in rows[2] and "traceback" in rows[-1]  # the layout's and the error's own columns
    for row in rows:
        assert unknown_columns(row) == []
        decoded = json.loads(json.dumps(row, default=float))  # as the journal stores it
        assert type_error(decoded) is None and check_row(decoded) is None


def test_an_undeclared_column_or_a_wrong_type_is_caught(rows):
    row = dict(rows[0])
    row["new_measure"] = 1.0
    assert unknown_columns(row) == ["new_measure"]
    for col, bad in (("switches", "3"), ("success", 1), ("switches", True), ("parking_time_s", "12 s")):
        assert col in type_error({**rows[0], col: bad})
    assert "switches" in check_row({**rows[0], "switches": 2.5})


def _changed(v, kind: str):
    """A value of ``kind`` that differs from ``v`` at every export precision."""
    if kind.startswith("list"):
        return [*(v if v is not None else []), 7]
    if kind == "bool":
        return not bool(v)
    if kind == "int":
        return int(v or 0) + 1
    if kind == "float":
        return 1.0 if v is None or math.isnan(v) else v + 1.0
    return f"{v}!"


def test_every_exported_column_round_trips_through_export_and_diff(rows, tmp_path):
    """Exported and read back, the rows are the same to ``diff``; a change in any exported
    column is a changed row of that column, unless a machine measures it."""
    df = pd.DataFrame(rows[:2])
    back = read_results([export_table(df, tmp_path, "guide-only")])
    assert list(back.columns) == [c for c in EXPORT_COLUMNS if c in df.columns]
    assert set(EXPORT_COLUMNS) - set(back.columns) <= {"error"} and not df["error"].notna().any()
    d = compare(df, back)
    assert d.same_rows == 2 and d.changed_columns == {}
    for name in EXPORT_COLUMNS:
        if name in ("planner", "case_id") or name not in df:
            continue
        after = df.copy()
        if BY_NAME[name].kind.startswith("list"):
            after[name] = after[name].astype(object)
        after.at[0, name] = _changed(df.at[0, name], BY_NAME[name].kind)
        d = compare(df, after)
        if name in MACHINE_COLUMNS:
            assert d.same_rows == 2, name
        else:
            assert d.changed_columns == {name: 1}, name


def test_exports_round_each_column_to_its_declared_decimals(rows, tmp_path):
    df = pd.DataFrame(rows[:1]).assign(parking_time_s=12.345678, M_e=0.123456789, plan_times_ms=[[1.26, 3.0]])
    back = read_results([export_table(df, tmp_path, "guide-only")])
    assert back.at[0, "parking_time_s"] == 12.35 and back.at[0, "M_e"] == 0.1235
    assert np.allclose(back.at[0, "plan_times_ms"], [1.3, 3.0])
    assert back.at[0, "y0"] == rows[0]["y0"]  # the case's factors as they are


def test_the_report_names_a_column_by_its_words_and_unit():
    assert column_label("parking_time_s") == "parking time [s]" and column_label("road_width") == "road width [m]"
    assert column_label("theta0_deg") == "theta0 [deg]" and column_label("M_e") == "M_e [m]"
    assert column_label("switches") == "switches"
    with pytest.raises(KeyError):
        column_label("not_a_column")


def test_a_report_over_a_run_whose_every_case_errored_is_written(rows, tmp_path):
    """Such a run has no outcome columns; the report reads every declared column all the same."""
    from evaluation.report import write_report

    report = write_report(pd.DataFrame(rows[-1:]), tmp_path / "r").read_text()
    assert "| guide-only | 1 | 0.0 % |" in report
