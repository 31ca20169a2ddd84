"""scripts/grid_splice.py: a partial rerun's rows replace those cases' rows in the chunk
tables, in place, and nothing else; a rerun it cannot place is refused."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pandas as pd
import pytest

_spec = importlib.util.spec_from_file_location("grid_splice", Path(__file__).parents[1] / "scripts" / "grid_splice.py")
grid_splice = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(grid_splice)


def _table(ids, switches, success):
    return pd.DataFrame({"case_id": ids, "switches": switches, "success": success, "note": [None] * len(ids)})


@pytest.fixture
def grid(tmp_path):
    _table(["a", "b", "c"], [1, 2, 3], [True, True, False]).to_parquet(tmp_path / "mirror-chunk01-of-02.parquet")
    _table(["d", "e"], [4, 5], [True, False]).to_parquet(tmp_path / "mirror-chunk02-of-02.parquet")
    return tmp_path


def test_rows_are_replaced_in_place_and_nothing_else(grid, capsys):
    rerun = grid / "rerun.parquet"
    _table(["e", "b"], [9, 8], [True, False]).to_parquet(rerun)
    grid_splice.main(str(rerun), "mirror", str(grid))
    one = pd.read_parquet(grid / "mirror-chunk01-of-02.parquet")
    two = pd.read_parquet(grid / "mirror-chunk02-of-02.parquet")
    assert one.case_id.tolist() == ["a", "b", "c"] and one.switches.tolist() == [1, 8, 3]
    assert one.success.tolist() == [True, False, False]
    assert two.case_id.tolist() == ["d", "e"] and two.switches.tolist() == [4, 9]
    assert one.dtypes.equals(_table(["a"], [1], [True]).dtypes)
    assert "2 rows replaced" in capsys.readouterr().out


def test_a_rerun_it_cannot_place_is_refused(grid):
    twice = grid / "twice.parquet"
    _table(["a", "a"], [1, 1], [True, True]).to_parquet(twice)
    with pytest.raises(SystemExit, match="appears twice"):
        grid_splice.main(str(twice), "mirror", str(grid))
    stranger = grid / "stranger.parquet"
    _table(["a", "z"], [1, 1], [True, True]).to_parquet(stranger)
    before = (grid / "mirror-chunk01-of-02.parquet").read_bytes()
    with pytest.raises(SystemExit, match="only 1 of 2"):
        grid_splice.main(str(stranger), "mirror", str(grid))
    assert (grid / "mirror-chunk01-of-02.parquet").read_bytes() == before  # nothing written
