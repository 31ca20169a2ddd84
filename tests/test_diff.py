"""``mirrorpark diff``: two runs over the same cases compared row by row."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from evaluation.cli import main as cli
from evaluation.diff import compare, format_diff


def _rows(planner: str = "mirror", n: int = 4) -> pd.DataFrame:
    """``n`` hand-made result rows: case k parks when k is even."""
    return pd.DataFrame(
        {
            "planner": planner,
            "case_id": [f"case{k}" for k in range(n)],
            **{"parking_type": "reverse", "road_width": 6.0, "slot_length": 4.82, "slot_width": 2.3, "theta0_deg": 0.0},
            "success": [k % 2 == 0 for k in range(n)],
            "failed_criterion": [None if k % 2 == 0 else "gave_up" for k in range(n)],
            "feasible": True,
            "collision": False,
            "failure_cause": [None if k % 2 == 0 else "gave_up" for k in range(n)],
            "switches": [k + 1 for k in range(n)],
            "parking_time_s": [10.0 + k for k in range(n)],
            "planning_calls": 2,
            "plan_iterations": [[3, 4]] * n,
            "plan_times_ms": [[100.0, 50.0]] * n,
            "episode_wall_s": 1.0,
            "M_fl": [0.25, np.nan, 0.3, np.nan][:n],
        }
    )


def test_a_rerun_that_differs_only_in_its_times_keeps_every_row():
    before, after = _rows(), _rows()
    after["plan_times_ms"] = [[90.0, 40.0]] * 4
    after["episode_wall_s"] = 0.5
    after["M_fl"] = after["M_fl"] + 1e-7  # below what an exported table keeps (0.1 mm)
    d = compare(before, after)
    assert (d.cases, d.same_rows, d.changed_columns) == (4, 4, {})
    assert d.gained == d.lost == ()
    assert d.planning_s_before == pytest.approx(0.6) and d.planning_s_after == pytest.approx(0.52)
    assert "Every row the same" in format_diff(d)


def test_gained_and_lost_cases_are_named_with_what_changed():
    before, after = _rows(), _rows()
    after.loc[1, ["success", "failure_cause"]] = [True, None]  # case1 now parks
    after.loc[2, ["success", "failure_cause"]] = [False, "parked_outside_margin:M_fl"]  # case2 no longer
    after.loc[3, "M_fl"] = 0.001  # NaN before
    after.at[0, "plan_iterations"] = [3, 5]
    d = compare(before, after)
    assert d.gained == ("case1",) and d.lost == ("case2",)
    assert d.causes_lost == {"parked_outside_margin": 1}
    assert d.changed_columns == {"success": 2, "failure_cause": 2, "M_fl": 1, "plan_iterations": 1}
    assert d.same_rows == 0
    assert (d.success_before, d.success_after) == (0.5, 0.5)
    assert d.both_parked == 1 and d.switches_before == d.switches_after == 1.0
    text = format_diff(d, list_cases=5)
    assert "**4 of 4 rows differ**" in text and "- `case1`" in text and "- `case2`" in text


def test_success_per_value_of_a_case_column():
    before, after = _rows(), _rows()
    before["parking_type"] = after["parking_type"] = ["parallel", "parallel", "reverse", "reverse"]
    after.loc[1, "success"] = True  # parallel gains case1
    after.loc[2, "success"] = False  # reverse loses case2
    d = compare(before, after, by="parking_type")
    assert d.groups == {
        "parallel": {"cases": 2, "success_before": 0.5, "success_after": 1.0, "gained": 1, "lost": 0},
        "reverse": {"cases": 2, "success_before": 0.5, "success_after": 0.0, "gained": 0, "lost": 1},
    }
    assert "| parallel | 2 | 50.0 % | 100.0 % | 1 | 0 |" in format_diff(d)
    with pytest.raises(ValueError, match="by: must be one of parking_type"):
        compare(before, after, by="success")
    with pytest.raises(ValueError, match="by: the results hold no column 'y0'"):
        compare(before, after, by="y0")


def test_missing_values_compare_equal_whatever_their_kind():
    from evaluation.diff import _equal

    assert _equal(None, float("nan")) and _equal(pd.NA, None) and _equal([1, None], [1, np.nan])
    assert not _equal(None, 0.0) and not _equal([1, 2], None) and not _equal([1, 2], [1, 2, 3])


def test_only_common_cases_are_compared():
    d = compare(_rows(n=4), _rows(n=3))
    assert (d.cases, d.only_before, d.only_after, d.same_rows) == (3, 1, 0, 3)


def test_bad_inputs_are_rejected_with_the_side_named():
    mixed = pd.concat([_rows("mirror"), _rows("hybrid-astar")], ignore_index=True)
    with pytest.raises(ValueError, match="before: expected the rows of one planner, got 2"):
        compare(mixed, _rows())
    twice = pd.concat([_rows(), _rows().iloc[:1]], ignore_index=True)
    with pytest.raises(ValueError, match="after: case 'case0' appears more than once"):
        compare(_rows(), twice)
    with pytest.raises(ValueError, match="after: the results lack the column.s. switches"):
        compare(_rows(), _rows().drop(columns="switches"))
    other = _rows()
    other["case_id"] = other["case_id"] + "x"
    with pytest.raises(ValueError, match="share no case"):
        compare(_rows(), other)


def test_the_command_reads_exported_tables(tmp_path, capsys):
    before, after = _rows(), _rows("mirror-cold")
    after.loc[1, ["success", "failure_cause"]] = [True, None]
    before.to_parquet(tmp_path / "a.parquet")
    after.to_parquet(tmp_path / "b.parquet")
    args = ["diff", "--before", str(tmp_path / "a.parquet"), "--after", str(tmp_path / "b.parquet")]
    assert cli([*args, "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert (out["before"], out["after"], out["gained"], out["lost"]) == ("mirror", "mirror-cold", ["case1"], [])
    assert cli(args) == 0
    assert "# `mirror-cold` against `mirror` on 4 common cases" in capsys.readouterr().out
    assert cli(["diff", "--before", str(tmp_path / "missing.parquet"), "--after", str(tmp_path / "b.parquet")]) == 2
    assert "missing.parquet: no such results folder or file" in capsys.readouterr().err
