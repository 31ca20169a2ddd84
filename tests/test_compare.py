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


def test_against_takes_exactly_the_runs_cases_and_refuses_other_code(tmp_path, capsys):
    """``--against``: committed rows (here a grid folder made of a guide-only run over 3 cases)
    for exactly the 2 cases of the run; refused where the table's stamp is other code."""
    import json
    import shutil

    from evaluation.committed import MANIFEST

    grid = tmp_path / "grid"
    base = ["evaluate", "--planner", "guide-only", "--sample", "smoke", "--quiet"]
    assert main([*base, "--chunk", "1/30", "--out", str(tmp_path / "all"), "--export", str(grid)]) == 0
    table = next(grid.glob("guide-only*.parquet"))
    shutil.move(table, grid / "guide-only-chunk01-of-01.parquet")  # named like the committed chunks
    committed = pd.read_parquet(grid / "guide-only-chunk01-of-01.parquet")
    assert len(committed) == 3
    run = tmp_path / "run"
    cases = tmp_path / "cases.csv"
    fields = ["parking_type", "road_width", "slot_length", "slot_width", "theta0_deg", "y0"]
    committed[fields].iloc[:2].to_csv(cases, index=False)
    assert main([*base[:-1], "--cases", str(cases), "--out", str(run), "--quiet"]) == 0
    capsys.readouterr()
    out = tmp_path / "cmp"
    assert main(["compare", str(run), "--against", "guide-only", "--grid", str(grid), "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "# 2 runs on 2 common cases" in text and "guide-only (committed)" in text
    assert list(pd.read_csv(out / "compare.csv")["run"]) == ["guide-only", "guide-only (committed)"]
    # The same rows, said to come from other code (a table committed before stamps, in the manifest).
    old = tmp_path / "old"
    old.mkdir()
    committed.to_parquet(old / "guide-only-chunk01-of-01.parquet")  # no metadata: no stamp of its own
    stamp = {"guide-only-chunk01-of-01.parquet": {"code_id": "0" * 12, "commit": "abc"}}
    (old / MANIFEST).write_text(json.dumps(stamp))
    assert main(["compare", str(run), "--against", "guide-only", "--grid", str(old)]) == 2
    err = capsys.readouterr().err
    assert "other code (000000000000 of abc)" in err and "--allow-other-code" in err and "Traceback" not in err
    assert main(["compare", str(run), "--against", "guide-only", "--grid", str(old), "--allow-other-code"]) == 0
    assert "guide-only (committed, other code)" in capsys.readouterr().out
    # A case with no committed row, and a planner with none, are refused by name.
    committed.iloc[1:].to_parquet(old / "guide-only-chunk01-of-01.parquet")
    assert main(["compare", str(run), "--against", "guide-only", "--grid", str(old), "--allow-other-code"]) == 2
    assert "1 of the run's 2 cases have no committed row" in capsys.readouterr().err
    assert main(["compare", str(run), "--against", "nobody", "--grid", str(grid)]) == 2
    assert "no committed rows of 'nobody'" in capsys.readouterr().err


def test_a_planners_code_stamp_covers_its_own_code_and_not_the_others():
    """``code_id`` hashes what decides a planner's rows: its package, the shared planner code,
    the environment and the row-building modules; not another planner's package, so that a
    change to hybrid A* leaves the committed rows of ``mirror`` valid."""
    from evaluation.code_stamp import ROW_MODULES, code_files, code_id, policy_modules

    mirror = code_files([*policy_modules("mirror"), *ROW_MODULES])
    hybrid = code_files([*policy_modules("hybrid-astar"), *ROW_MODULES])
    for files in (mirror, hybrid):
        assert {"mirrorpark_env.env", "mirrorpark_env.vehicle", "planners.base", "evaluation.episode"} <= set(files)
        assert not any(n.startswith(("evaluation.registry", "evaluation.cli", "planners.rl")) for n in files)
    assert "planners.mirror.scp" in mirror and not any(n.startswith("planners.hybrid_astar") for n in mirror)
    assert "planners.hybrid_astar.search" in hybrid and not any(n.startswith("planners.mirror") for n in hybrid)
    assert code_id("mirror") == code_id("mirror-cold")  # one code, two presets of it
    assert code_id("mirror") != code_id("hybrid-astar")
