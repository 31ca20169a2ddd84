"""Configs: the shipped YAML validates; bad values name the field and the range."""

from __future__ import annotations

import gymnasium as gym
import pytest

import mirrorpark_env  # noqa: F401
from mirrorpark_env.config import EnvConfig, GridConfig, VehicleConfig, default_env, default_grid, load
from mirrorpark_env.vehicle import VehicleParams


def test_shipped_configs_are_the_paper_values():
    assert VehicleParams.from_config(default_env().vehicle) == VehicleParams.table_ii()
    g = default_grid()
    assert g.types["parallel"].slot_length.values()[-1] == pytest.approx(7.32)
    assert g.types["reverse"].slot_width.values()[-1] == pytest.approx(3.27)


def test_bad_vehicle_file_names_field_and_range(tmp_path):
    f = tmp_path / "vehicle.yaml"
    f.write_text("wheelbase: -2.5\nwidth: 1.67\n")
    with pytest.raises(ValueError, match=r"vehicle.yaml: wheelbase: Input should be greater than 0 \(got -2.5\)"):
        load(VehicleConfig, f)


def test_unknown_key_and_malformed_yaml(tmp_path):
    f = tmp_path / "grid.yaml"
    f.write_text("theta0_deg: {start: -90, step: 10, count: 19}\ntypes: {}\nroad_wdth: 3\n")
    with pytest.raises(ValueError, match=r"grid.yaml: road_wdth: Extra inputs are not permitted"):
        load(GridConfig, f)
    f.write_text("types: [unclosed\n")
    with pytest.raises(ValueError, match="not valid YAML"):
        load(GridConfig, f)
    with pytest.raises(ValueError, match="cannot read config file"):
        load(GridConfig, tmp_path / "missing.yaml")


def test_env_config_overrides_are_validated():
    with pytest.raises(ValueError, match=r"substep: Input should be less than or equal to 0.02"):
        gym.make("MirrorPark-v0", config={"substep": 0.05})
    with pytest.raises(ValueError, match=r"criteria.heading_tol_deg: Input should be greater than 0"):
        gym.make("MirrorPark-v0", config={"criteria": {"heading_tol_deg": -3}})
    with pytest.raises(ValueError, match=r"parking_types.0: Input should be 'parallel', 'reverse' or 'angle'"):
        gym.make("MirrorPark-v0", config={"parking_types": ["diagonal"]})
    env = gym.make("MirrorPark-v0", config={"criteria": {"stop_speed": 0.02}})
    cfg: EnvConfig = env.unwrapped.cfg
    assert cfg.criteria.stop_speed == 0.02 and cfg.criteria.heading_tol_deg == 3.0
