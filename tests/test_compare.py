"""``mirrorpark compare``: Wilson intervals by hand, paired differences on built rows, the CLI."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from evaluation.cli import main
from evaluation.compare import paired_table, run_table, wilson


def test_wilson_intervals_by_hand():
    # 84 of 100: centre (0.84 + 1.92/100) / 1.0384 = 0.8274, half 1.96 x 0.03795 / 1.0384 = 0.0716
    assert wilson(84, 100) == pytest.approx((0.7558, 0.8991), abs=1e-4)
    assert wilson(0, 10) == pytest.approx((0.0, 0.2775), abs=1e-4)  # never below 0
    assert wilson(10, 10) == pytest.approx((0.7225, 1.0), abs=1e-4)
    assert all(np.isnan(wilson(0, 0)))


def _rows(success, switches, parking):
    n = len(success)
    return pd.DataFrame(
        {
            "case_id": [f"c{i}" for i in range(n)],
            "parking_type": ["reverse"] * n,
            "slot_length": [5.0] * n,
            "slot_width": [2.5] * n,
            "y0": [2.0] * n,
            "feasible": [True] * n,
            "success": success,
            "collision": [False] * n,
            "switches": switches,
            "parking_time_s": parking,
            "path_length_m": [10.0] * n,
            "plan_times_ms": [[5.0, 7.0]] * n,
        }
    )


def test_paired_differences_count_gains_losses_and_mean_differences():
    a = _rows([True, True, False, False, False, True], [1, 2, 0, 0, 0, 3], [10.0, 12.0, 0, 0, 0, 14.0])
    b = _rows([True, False, True, True, True, True], [2, 0, 1, 1, 1, 4], [11.0, 0, 9.0, 9.0, 9.0, 15.0])
    table = run_table({"a": a, "b": b})
    assert table.loc[0, "success"].startswith("50.0 % [") and table.loc[1, "success"].startswith("83.3 % [")
    paired = paired_table({"a": a, "b": b}, "a").iloc[0]
    assert paired["gained / lost"] == "3 / 1" and paired["McNemar p"] == "0.625"  # binomial: 5/8
    assert paired["both park"] == 2  # c0 and c5: each one more switch and 1 s longer
    assert paired["switches difference"].startswith("+1.00 [+1.00, +1.00]")
    assert paired["success difference [points]"].startswith("+33.3 [")


def test_the_cli_compares_two_runs_on_their_common_cases(tmp_path, capsys):
    for planner in ("guide-only", "hybrid-astar"):
        args = ["evaluate", "--planner", planner, "--sample", "smoke", "--chunk", "1/30"]
        assert main([*args, "--out", str(tmp_path / planner), "--quiet"]) == 0
    capsys.readouterr()
    out = tmp_path / "cmp"
    assert main(["compare", str(tmp_path / "guide-only"), str(tmp_path / "hybrid-astar"), "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "# 2 runs on 3 common cases" in text and "Against `guide-only`, paired by case" in text
    assert (out / "compare.md").read_text() == text.rstrip("\n") + "\n"
    assert list(pd.read_csv(out / "compare.csv")["run"]) == ["guide-only", "hybrid-astar"]
    assert (out / "compare.png").stat().st_size > 1000  # success per type with its intervals
    assert main(["compare", str(tmp_path / "guide-only"), "--reference", "nope"]) == 2
