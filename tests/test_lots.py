"""Generated lots (``mirrorpark_env.lots``): every one loads, resets and steps; seeded."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import mirrorpark_env  # noqa: F401
from evaluation.cli import main
from mirrorpark_env.layout_io import load_layout
from mirrorpark_env.lots import LEVELS, generate_lot
from mirrorpark_env.vehicle import VehicleParams, vehicle_named

ENV = gym.make("MirrorPark-v0").unwrapped


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    seed=st.integers(0, 2**31 - 1),
    level=st.sampled_from(LEVELS),
    actions=st.lists(st.tuples(st.floats(-1, 1), st.floats(-1, 1)), min_size=1, max_size=5),
)
def test_any_generated_lot_loads_resets_and_steps(seed, level, actions):
    lot = generate_lot(seed, level)
    lot.check()  # what a file's layouts go through at load
    _, info = ENV.reset(options={"layout": lot})
    g = info["geometry"]
    assert not info["collision"] and g.vehicle == VehicleParams.table_ii()
    assert (g.slot is None) == (lot.slot is None)
    if lot.slot is None:  # open space: nothing within reach of the car at the target
        assert level >= 3
    for a in actions:
        _, _, term, trunc, _ = ENV.step(np.array(a, dtype=np.float32))
        if term or trunc:
            break


def test_a_seed_and_level_give_one_lot_anywhere_and_others_differ():
    a, b = generate_lot(7, 3), generate_lot(7, 3)
    assert a.start == b.start and a.target == b.target and len(a.obstacles) == len(b.obstacles)
    assert all(np.array_equal(p, q) for p, q in zip(a.obstacles, b.obstacles))
    assert generate_lot(8, 3).start != a.start and generate_lot(7, 2).start != a.start


def test_every_level_holds_each_slot_type_and_level_three_open_space():
    kinds = {lvl: {getattr(generate_lot(s, lvl).slot, "parking_type", None) for s in range(40)} for lvl in LEVELS}
    for lvl in LEVELS:
        assert {k.value for k in kinds[lvl] if k is not None} == {"parallel", "reverse", "angle"}
    assert None not in kinds[1] and None not in kinds[2] and None in kinds[3]


def test_gaps_narrow_with_the_level():
    def parallel_lengths(level):
        lots = [generate_lot(s, level) for s in range(60)]
        return [lot.slot.length for lot in lots if lot.slot is not None and lot.slot.parking_type.value == "parallel"]

    car = VehicleParams.table_ii()
    assert min(parallel_lengths(1)) >= 1.45 * car.length - 1e-9
    assert max(parallel_lengths(4)) <= 1.3 * car.length + 1e-9


def test_lots_for_tpcaps_car_fit_it():
    car = vehicle_named("tpcap")
    for s in range(20):
        lot = generate_lot(s, 2, car)
        assert lot.vehicle == car
        lot.check()


@pytest.mark.parametrize(
    "level, seed, message", [(0, 1, "level: one of"), (2, -1, "seed: a whole number"), (2, 1.5, "seed")]
)
def test_bad_levels_and_seeds_are_refused(level, seed, message):
    with pytest.raises(ValueError, match=message):
        generate_lot(seed, level)


def test_reset_takes_a_lot_by_level_or_by_level_and_seed():
    _, info = ENV.reset(seed=1, options={"lot": 4})
    assert info["case_id"].startswith("lot-L4-")
    _, info = ENV.reset(options={"lot": {"level": 1, "seed": 5}})
    assert info["case_id"] == "lot-L1-5" and info["layout"].target == generate_lot(5, 1).target
    with pytest.raises(ValueError, match="'lot' must be a level"):
        ENV.reset(options={"lot": {"level": 2, "size": 3}})
    with pytest.raises(ValueError, match="one of 'scenario', 'layout' and 'lot'"):
        ENV.reset(options={"lot": 2, "scenario": "parallel_rw4.00_sl7.32_sw2.50_th+10_y1.30"})


def test_the_cli_writes_lots_that_load_back_as_generated(tmp_path, capsys):
    assert main(["lots", "--seed", "3", "--count", "4", "--level", "3", "--out", str(tmp_path)]) == 0
    files = sorted(tmp_path.glob("*.json"))
    assert [f.name for f in files] == [f"lot-L3-{s}.json" for s in range(3, 7)]
    for f, s in zip(files, range(3, 7)):
        back, made = load_layout(f), generate_lot(s, 3)
        assert back.target == pytest.approx(made.target, abs=1e-12) and back.vehicle == made.vehicle
        assert (back.slot is None) == (made.slot is None)
    assert main(["lots", "--seed", "-2", "--out", str(tmp_path)]) == 2
    assert "--seed: a whole number >= 0" in capsys.readouterr().err
