"""MirrorPark: parallel, reverse and angle parking as a Gymnasium environment.

``import mirrorpark_env`` registers ``MirrorPark-v0``; ``gym.make("mirrorpark_env:MirrorPark-v0")``
works without the import.
"""

from gymnasium.envs.registration import register, registry

from .config import EnvConfig, GridConfig, VehicleConfig
from .criteria import SuccessCriteria, Verdict
from .grid import Grid, default_grid_cases
from .scenario import ParkingType, Scenario, ScenarioGeometry
from .vehicle import TruthModel, VehicleParams, VehicleState, footprint, from_action, to_action

__all__ = [
    "EnvConfig",
    "GridConfig",
    "Grid",
    "ParkingType",
    "Scenario",
    "ScenarioGeometry",
    "SuccessCriteria",
    "TruthModel",
    "VehicleConfig",
    "VehicleParams",
    "VehicleState",
    "Verdict",
    "default_grid_cases",
    "footprint",
    "from_action",
    "to_action",
]

MAX_EPISODE_STEPS = 1800  # 180 s, the ISO time limit, at the default 0.1 s control step

if "MirrorPark-v0" not in registry:
    register(
        id="MirrorPark-v0",
        entry_point="mirrorpark_env.env:MirrorParkEnv",
        max_episode_steps=MAX_EPISODE_STEPS,
        # The env is checked in the tests (check_env); Gymnasium's passive checker would
        # also keep a failed first reset's state and break every later step.
        disable_env_checker=True,
    )
