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


def test_a_recipe_extends_another_and_changes_only_what_it_names(tmp_path):
    from planners.rl.config import load_rl_config

    (tmp_path / "base.yaml").write_text(
        "total_steps: 500\nlidar: {rays: 8, max_range: 4.0}\ndagger:\n  cases_per_round: 7\n  beta0: 0.5\n"
    )
    (tmp_path / "sub").mkdir()
    child = tmp_path / "sub" / "child.yaml"
    child.write_text("extends: ../base.yaml\nseed: 3\ndagger:\n  beta0: 0.25\n")  # relative to the child
    cfg = load_rl_config(child, {"total_steps": 900})
    assert cfg.seed == 3 and cfg.total_steps == 900  # its own field; the command line's override
    assert cfg.lidar.rays == 8 and cfg.lidar.max_range == 4.0  # the base's section, untouched
    assert cfg.dagger.beta0 == 0.25 and cfg.dagger.cases_per_round == 7  # one key changed, the other kept

    # The shipped recipes: the filter's recipe is the gear recipe but for its two switches.
    gear = load_rl_config("configs/rl_dagger_gear.yaml").model_dump()
    shield = load_rl_config("configs/rl_dagger_gear_shield.yaml").model_dump()
    assert not gear["dagger"]["shield"] and shield["dagger"]["shield"] and shield["dagger"]["shield_second_gear"]
    shield["dagger"].update(shield=False, shield_second_gear=False)
    assert shield == gear


def test_a_recipe_with_a_bad_extends_is_rejected_naming_it(tmp_path):
    from planners.rl.config import load_rl_config

    (tmp_path / "a.yaml").write_text("extends: b.yaml\n")
    (tmp_path / "b.yaml").write_text("extends: a.yaml\n")
    with pytest.raises(ValueError, match=r"extends: a cycle \(a.yaml -> b.yaml -> a.yaml\)"):
        load_rl_config(tmp_path / "a.yaml")
    (tmp_path / "c.yaml").write_text("extends: 5\n")
    with pytest.raises(ValueError, match="c.yaml: extends: must be a YAML file name"):
        load_rl_config(tmp_path / "c.yaml")
    (tmp_path / "d.yaml").write_text("extends: missing.yaml\n")
    with pytest.raises(ValueError, match="missing.yaml: cannot read config file"):
        load_rl_config(tmp_path / "d.yaml")
