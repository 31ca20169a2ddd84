"""The full grid in pieces: chunks partition the cases; each chunk's compact table."""

from __future__ import annotations

import math

import pandas as pd
import pytest

from evaluation.cases import chunk
from evaluation.schema import EXPORT_COLUMNS
from evaluation.store import export_table, read_results


@pytest.mark.parametrize(("n_items", "n"), [(10, 3), (70_434, 16), (5, 5), (7, 7)])
def test_chunks_partition_the_cases_in_order(n_items, n):
    items = list(range(n_items))
    parts = [chunk(items, f"{k}/{n}") for k in range(1, n + 1)]
    assert [i for p in parts for i in p] == items
    assert max(map(len, parts)) - min(map(len, parts)) <= 1


@pytest.mark.parametrize("spec", ["0/4", "5/4", "a/b", "3", "1/0"])
def test_a_bad_chunk_is_rejected_naming_the_option(spec):
    with pytest.raises(ValueError, match="--chunk"):
        chunk([1, 2, 3], spec)


def test_a_chunk_that_holds_no_case_is_refused_before_a_folder_is_made(tmp_path, capsys):
    """3 cases in 4 chunks: one chunk is empty. It said "results folder is empty" and left
    an empty folder behind."""
    from evaluation.cli import main as cli

    with pytest.raises(ValueError, match=r"--chunk 1/4: holds no case \(3 case\(s\) in 4 chunks\)"):
        chunk([1, 2, 3], "1/4")
    layouts = [f"configs/layouts/tpcap/{n}.csv" for n in ("per03", "par02", "par03")]
    out = tmp_path / "out"
    assert cli(["evaluate", "--planner", "guide-only", "--layouts", *layouts, "--chunk", "1/4", "--out", str(out)]) == 2
    assert "--chunk 1/4: holds no case" in capsys.readouterr().err and not out.exists()


def test_the_export_keeps_the_report_columns_rounded_and_reads_back(tmp_path):
    row = {
        "planner": "mirror",
        "case_id": "b",
        "parking_type": "reverse",
        "slot_width": 2.123456789,
        "y0": 1.6,
        "success": True,
        "M_fl": 0.123456789,
        "path_length_m": 7.123456,
        "parking_time_s": 19.1,
        "plan_times_ms": [10.04, 3.26],
        "traceback": "long text",
        "plan_time_median_ms": 6.6,
    }
    df = pd.DataFrame([row, {**row, "case_id": "a", "plan_times_ms": [1.0]}])
    path = export_table(df, tmp_path, "mirror", "3/16")
    assert path.name == "mirror-chunk03-of-16.parquet"
    back = read_results([path])
    assert list(back["case_id"]) == ["a", "b"]  # sorted by case
    assert set(back.columns) <= set(EXPORT_COLUMNS) and "traceback" not in back
    b = back.iloc[1]
    assert b["slot_width"] == 2.123456789  # case values exact
    assert b["M_fl"] == 0.1235 and b["path_length_m"] == 7.123  # margins to 0.1 mm, lengths to 1 mm
    assert list(b["plan_times_ms"]) == [10.0, 3.3]
    assert not math.isnan(b["y0"])
    export_table(df.assign(case_id=["c", "d"]), tmp_path, "mirror", "4/16")
    folder = read_results([tmp_path])  # a folder of exported tables reads as all of them
    assert sorted(folder["case_id"]) == ["a", "b", "c", "d"]
