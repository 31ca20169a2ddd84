"""The Table III grid: exact counts, ids, filters, stratified samples."""

from __future__ import annotations

import numpy as np
import pytest

from mirrorpark_env import Grid, default_grid_cases


@pytest.fixture(scope="module")
def grid() -> Grid:
    return default_grid_cases()


def test_counts_follow_the_design_rule(grid):
    counts = grid.counts()
    assert counts.pop("feasible")["total"] == 63057  # checked slot by slot in test_verdicts.py
    assert counts == {"parallel": 12420, "reverse": 46629, "angle": 11385, "total": 70434}


def test_ids_are_unique_and_stable(grid):
    ids = grid.case_ids()
    assert len(set(ids)) == len(ids) == 70434
    assert ids[0] == "parallel_rw4.50_sl3.82_sw2.50_th-90_y3.20"
    assert grid.by_id("reverse_rw5.00_sl4.82_sw2.17_th+0_y2.50").slot_width == pytest.approx(2.17)
    with pytest.raises(KeyError):
        grid.by_id("reverse_rw5.00_sl4.82_sw2.17_th+0_y9.50")


def test_every_case_starts_inside_the_road(grid):
    c = grid.columns
    assert (c["y0"] >= 0).all() and (c["y0"] <= c["road_width"] + 1e-9).all()
    assert set(np.unique(c["theta0_deg"])) == set(range(-90, 91, 10))


def test_filters(grid):
    idx = grid.indices("parallel", road_width=4.5, y0=(1.6, 4.5))
    c = grid.columns
    assert len(idx) > 0
    assert (c["road_width"][idx] == 4.5).all() and (c["y0"][idx] >= 1.6 - 1e-9).all()
    assert len(grid.indices("reverse")) == 46629
    with pytest.raises(ValueError, match="filter: unknown factor 'speed'"):
        grid.indices(speed=1.0)


def test_samples_are_stratified_seeded_and_sized(grid):
    smoke = grid.sample_indices("smoke")
    assert len(smoke) == 90
    np.testing.assert_array_equal(smoke, grid.sample_indices("smoke"))
    assert not np.array_equal(smoke, grid.sample_indices("smoke", seed=1))
    c = grid.columns
    for t in range(3):
        sel = smoke[c["type"][smoke] == t]
        assert len(sel) == 30
        assert len(np.unique(c["road_width"][sel])) == 3  # every road width represented
    std = grid.sample_indices("standard")
    assert len(std) == 1500 and len(np.unique(std)) == 1500
    with pytest.raises(ValueError, match="sample: unknown 'huge'"):
        grid.sample_indices("huge")


def test_smoke_is_not_all_from_one_slot_size(grid):
    c = grid.columns
    smoke = grid.sample_indices("smoke")
    rev = smoke[c["type"][smoke] == 1]
    assert c["slot_width"][rev].min() < 2.2 < c["slot_width"][rev].max()
