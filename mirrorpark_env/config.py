"""Validated configuration: the YAML files in ``configs/`` read through pydantic models.

A bad file or dict raises ``ValueError`` naming the file, the field, the allowed range
and the value given, e.g. ``vehicle.yaml: wheelbase: Input should be greater than 0
(got -2.5)``.
"""

from __future__ import annotations

import math
import types
from enum import Enum
from importlib import resources
from pathlib import Path
from typing import Annotated, Any, Literal, TypeVar, Union, get_args, get_origin

from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from .textfile import parse_yaml, read_text


class ParkingType(str, Enum):
    PARALLEL = "parallel"
    REVERSE = "reverse"
    ANGLE = "angle"

    @classmethod
    def parse(cls, value: object) -> ParkingType:
        if isinstance(value, ParkingType):
            return value
        try:
            return cls(str(value).lower())
        except ValueError:
            allowed = ", ".join(t.value for t in cls)
            raise ValueError(f"parking_type: unknown {value!r}; allowed: {allowed}") from None


PARKING_TYPES: tuple[str, ...] = tuple(t.value for t in ParkingType)  # the one list, in this order
ParkingTypeName = Literal["parallel", "reverse", "angle"]  # for validation; must equal PARKING_TYPES
assert get_args(ParkingTypeName) == PARKING_TYPES

M = TypeVar("M", bound=BaseModel)


def _takes_number(annotation: Any) -> bool:
    """Whether a field of this type holds a number (not a boolean)."""
    args = get_args(annotation)
    if get_origin(annotation) in (Union, types.UnionType):
        return any(_takes_number(a) for a in args) and bool not in args
    if get_origin(annotation) is Annotated:
        return _takes_number(args[0])
    return annotation in (int, float)


class StrictModel(BaseModel):
    """Frozen, hashable, finite numbers only, no unknown fields, no boolean where a number
    belongs (pydantic alone reads ``True`` as 1): the base of every config model."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    @model_validator(mode="before")
    @classmethod
    def _no_bool_for_a_number(cls, data: Any) -> Any:
        for name, field in cls.model_fields.items() if isinstance(data, dict) else ():
            if isinstance(data.get(name), bool) and _takes_number(field.annotation):
                raise ValueError(f"{name}: expected a number, got {data[name]}")
        return data


class VehicleConfig(StrictModel):
    """A vehicle (SI units): types and ranges only; the values of Table II are in
    ``configs/vehicle.yaml``, their one source."""

    wheelbase: float = Field(gt=0, le=10)
    rear_overhang: float = Field(ge=0, le=5)
    front_length: float = Field(gt=0, le=10)
    width: float = Field(gt=0, le=5)
    max_steer_rad: float = Field(gt=0, lt=math.pi / 2)
    accel_min: float = Field(lt=0, ge=-20)
    accel_max: float = Field(gt=0, le=20)
    speed_min: float = Field(lt=0, ge=-30)
    speed_max: float = Field(gt=0, le=30)
    tau_accel_s: float = Field(gt=0, le=5)
    tau_steer_s: float = Field(gt=0, le=5)

    @model_validator(mode="after")
    def _front_beyond_axle(self) -> VehicleConfig:
        if self.front_length <= self.wheelbase:
            raise ValueError(f"front_length ({self.front_length}) must exceed wheelbase ({self.wheelbase})")
        return self


class Levels(StrictModel):
    """Factor levels start + step * k for k = 0 .. count - 1."""

    start: float
    step: float = Field(ge=0)
    count: int = Field(ge=1, le=10_000)

    def values(self) -> list[float]:
        return [round(self.start + self.step * k, 10) for k in range(self.count)]


class TypeGrid(StrictModel):
    road_widths: list[float] = Field(min_length=1)
    slot_length: Levels
    slot_width: Levels

    @model_validator(mode="after")
    def _positive(self) -> TypeGrid:
        for rw in self.road_widths:
            if not 0 < rw <= 50:
                raise ValueError(f"road_widths: each must be in (0, 50] m (got {rw})")
        return self


class GridConfig(StrictModel):
    """Table III: factor levels per parking type."""

    theta0_deg: Levels
    y0_step: float = Field(0.1, gt=0, le=5)
    start_x_offset: float = Field(0.0, ge=-50, le=50)
    types: dict[ParkingTypeName, TypeGrid]
    samples: dict[str, int] = Field(default_factory=lambda: {"smoke": 30, "standard": 500})
    seed: int = 0

    @model_validator(mode="after")
    def _heading_range(self) -> GridConfig:
        vals = self.theta0_deg.values()
        if min(vals) < -180 or max(vals) > 180:
            raise ValueError("theta0_deg: levels must lie in [-180, 180] deg")
        for name, n in self.samples.items():
            if n < 1:
                raise ValueError(f"samples.{name}: must be >= 1 (got {n})")
        return self


class CriteriaConfig(StrictModel):
    heading_tol_deg: float = Field(3.0, gt=0, le=45)
    min_margin_perpendicular: float = Field(0.1, ge=0, le=2)
    stop_speed: float = Field(0.05, gt=0, le=1)
    time_limit_s: float = Field(180.0, gt=0, le=3600)
    target_position_tol: float = Field(0.15, gt=0, le=5)  # [m] layouts without a slot: rear axle to target


class RewardConfig(StrictModel):
    distance_scale: float = Field(10.0, gt=0)
    heading_weight: float = Field(1.0, ge=0)
    collision_penalty: float = Field(-10.0, le=0)
    success_bonus: float = Field(10.0, ge=0)
    goal_position_tol: float = Field(0.15, gt=0, le=5)
    goal_heading_tol_deg: float = Field(3.0, gt=0, le=90)


class RenderConfig(StrictModel):
    screen_width: int = Field(800, ge=64, le=4096)
    screen_height: int = Field(420, ge=64, le=4096)
    scaling: float = Field(26.0, gt=0, le=500)


class LidarConfig(StrictModel):
    rays: int = Field(0, ge=0, le=720)  # 0: no lidar in the observation
    max_range: float = Field(10.0, gt=0, le=200)  # [m]


class NoiseConfig(StrictModel):
    """Measurement error on the observed pose, heading and speed (``perturb.MeasurementNoise``):
    a zero-mean Gaussian per channel (independent per step, or first-order Gauss-Markov with
    ``correlation_time_s``) plus a constant bias; positions in the car's own frame."""

    position_std: float = Field(0.0, ge=0, le=2)  # [m] per axis (longitudinal, lateral)
    heading_std_deg: float = Field(0.0, ge=0, le=20)
    speed_std: float = Field(0.0, ge=0, le=2)  # [m/s]
    longitudinal_bias: float = Field(0.0, ge=-2, le=2)  # [m] along the car's heading
    lateral_bias: float = Field(0.0, ge=-2, le=2)  # [m] to the car's left
    heading_bias_deg: float = Field(0.0, ge=-20, le=20)
    speed_bias: float = Field(0.0, ge=-2, le=2)  # [m/s]
    correlation_time_s: float = Field(0.0, ge=0, le=600)  # 0: white; else each channel's time constant


class ActuatorConfig(StrictModel):
    """The truth's actuators differ from the model the planners are told
    (``perturb.CommandPath``): lags scaled, gains and an offset on the commands, and rate
    limits on the commands the actuators take (0: none)."""

    tau_accel_scale: float = Field(1.0, ge=0.2, le=10)
    tau_steer_scale: float = Field(1.0, ge=0.2, le=10)
    accel_gain: float = Field(1.0, ge=0.5, le=1.5)
    steer_gain: float = Field(1.0, ge=0.5, le=1.5)
    steer_offset_deg: float = Field(0.0, ge=-10, le=10)  # [deg] of front-wheel angle
    steer_rate_max_deg_s: float = Field(0.0, ge=0, le=2000)  # [deg/s] front wheel; 0: no limit
    jerk_max: float = Field(0.0, ge=0, le=1000)  # [m/s^3] on the acceleration command; 0: no limit


class ModelErrorConfig(StrictModel):
    """The truth car minus the car the planners are told (``geometry.vehicle``): lengths in
    metres, the steering limit as a factor. Collision and ISO verdicts use the truth car."""

    wheelbase: float = Field(0.0, ge=-0.5, le=0.5)
    rear_overhang: float = Field(0.0, ge=-0.5, le=0.5)
    front_length: float = Field(0.0, ge=-0.5, le=0.5)
    width: float = Field(0.0, ge=-0.3, le=0.3)
    max_steer_scale: float = Field(1.0, ge=0.7, le=1.2)


class LateObstacleConfig(StrictModel):
    """A pedestrian-sized box that appears ``time_s`` into the episode, ``ahead`` metres beyond
    the bumper the car drives toward (``lateral`` to its left), and stays."""

    time_s: float = Field(ge=0, le=3600)
    ahead: float = Field(2.0, ge=0.2, le=30)  # [m] from the bumper to the box
    lateral: float = Field(0.0, ge=-5, le=5)  # [m] the box's centre, left of the car's axis
    length: float = Field(0.5, gt=0, le=5)  # [m] along the car's heading
    width: float = Field(0.5, gt=0, le=5)  # [m]


class PerturbConfig(StrictModel):
    """How the world differs from what the planners know (``perturb.py``); every part off by
    default. ``seed`` with the case's id seeds the noise: a case, seed and perturbation give
    the same episode on any worker."""

    name: str = Field("custom", min_length=1, max_length=64, pattern=r"^[A-Za-z0-9_.+-]+$")
    seed: int = Field(0, ge=0, le=2**31 - 1)
    noise: NoiseConfig = NoiseConfig()
    actuator: ActuatorConfig = ActuatorConfig()
    delay_steps: int = Field(0, ge=0, le=20)  # control steps between a command and its actuation
    model: ModelErrorConfig = ModelErrorConfig()
    late_obstacle: LateObstacleConfig | None = None


class EnvConfig(StrictModel):
    """Everything ``MirrorPark-v0`` can be configured with."""

    dt: float = Field(0.1, ge=0.01, le=1.0)  # [s] control step
    substep: float = Field(0.01, ge=0.001, le=0.02)  # [s] integration and collision-check sub-step
    criteria: CriteriaConfig = CriteriaConfig()
    reward: RewardConfig = RewardConfig()
    parking_types: list[ParkingTypeName] = Field(default_factory=lambda: list(PARKING_TYPES), min_length=1)
    scene_margin: float = Field(25.0, ge=5, le=200)
    render: RenderConfig = RenderConfig()
    lidar: LidarConfig = LidarConfig()
    vehicle: VehicleConfig  # default_env() reads configs/vehicle.yaml
    perturb: PerturbConfig | None = None  # None: the world is what the planners are told

    @model_validator(mode="before")
    @classmethod
    def _perturb_preset(cls, data: Any) -> Any:
        if isinstance(data, dict) and isinstance(data.get("perturb"), str):  # a preset by name
            data = {**data, "perturb": perturb_preset(data["perturb"]).model_dump()}
        return data

    @model_validator(mode="after")
    def _substeps_divide(self) -> EnvConfig:
        n = self.dt / self.substep
        if abs(n - round(n)) > 1e-9:
            raise ValueError(f"substep ({self.substep}) must divide dt ({self.dt}) evenly")
        return self


def _format_errors(source: str, err: ValidationError) -> str:
    lines = []
    for e in err.errors():
        loc = ".".join(str(p) for p in e["loc"])
        where = f"{loc}: " if loc else ""
        got = e.get("input")
        shown = repr(got)
        shown = shown if len(shown) <= 80 else f"{shown[:60]}... ({len(shown)} characters)"  # one readable line
        got_s = "" if isinstance(got, dict) else f" (got {shown})"
        lines.append(f"{where}{e['msg'].removeprefix('Value error, ')}{got_s}")
    if len(lines) > 8:  # one readable line: the first problems, and how many more
        lines = [*lines[:8], f"and {len(lines) - 8} more"]
    text = f"{source}: " + "; ".join(lines)  # one line, each bad field named
    return "".join(c if c.isprintable() else repr(c)[1:-1] for c in text)  # a key's newline stays escaped


def validate(model: type[M], data: Any, source: str = "config") -> M:
    """Validate ``data`` against ``model``; raise ``ValueError`` naming each bad field."""
    if isinstance(data, model):
        return data
    if data is None:
        data = {}
    if not isinstance(data, dict):
        raise ValueError(f"{source}: expected a mapping of fields, got {type(data).__name__}")
    try:
        return model.model_validate(data)
    except ValidationError as err:
        raise ValueError(_format_errors(source, err)) from None


def read_yaml(path: str | Path) -> dict[str, Any]:
    """Read a YAML mapping; a missing or malformed file raises ``ValueError``."""
    p = Path(path)
    data = parse_yaml(read_text(p, "config file"), p)
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise ValueError(f"{p}: expected a mapping at the top level, got {type(data).__name__}")
    return data


def load(model: type[M], path: str | Path) -> M:
    """Load and validate one YAML file."""
    return validate(model, read_yaml(path), source=Path(path).name)


def default_config_path(name: str) -> Path:
    """Path of a config file shipped with the package (``configs/`` in the source tree)."""
    source_tree = Path(__file__).resolve().parent.parent / "configs" / name
    if source_tree.exists():  # a checkout or an editable install
        return source_tree
    try:  # a wheel install ships configs/ as the package data mirrorpark_env.configs
        return Path(str(resources.files("mirrorpark_env.configs").joinpath(name)))
    except ModuleNotFoundError:
        raise ValueError(f"config file {name!r} not found (looked in {source_tree.parent})") from None


def default_vehicle() -> VehicleConfig:
    return load(VehicleConfig, default_config_path("vehicle.yaml"))


def default_grid() -> GridConfig:
    return load(GridConfig, default_config_path("grid.yaml"))


PERTURB_PRESETS = ("mild", "moderate", "severe")  # configs/perturb/<name>.yaml


def perturb_preset(name: str) -> PerturbConfig:
    """A named perturbation (``PERTURB_PRESETS``); ``ValueError`` naming the presets otherwise."""
    if name not in PERTURB_PRESETS:
        raise ValueError(f"perturb: a preset in {list(PERTURB_PRESETS)} or a mapping of fields, got {name!r}")
    return load(PerturbConfig, default_config_path(f"perturb/{name}.yaml"))


def default_env() -> EnvConfig:
    data = read_yaml(default_config_path("env.yaml"))
    data.setdefault("vehicle", read_yaml(default_config_path("vehicle.yaml")))
    return validate(EnvConfig, data, source="env.yaml")


def merge(base: BaseModel, overrides: dict[str, Any] | None, source: str = "config") -> Any:
    """``base`` with ``overrides`` merged in (nested dicts merge key by key), validated."""
    if overrides is not None and not isinstance(overrides, dict):
        raise ValueError(f"{source}: expected a dict of settings, got {type(overrides).__name__}")
    return validate(type(base), merged(base.model_dump(), overrides or {}), source=source)


def merged(base: dict[str, Any], changes: dict[str, Any]) -> dict[str, Any]:
    """A copy of ``base`` with ``changes``: nested dicts merge key by key, anything else
    (a model given as a value counts as its dict) replaces."""
    out = dict(base)
    for k, v in changes.items():
        if isinstance(v, BaseModel):
            v = v.model_dump()
        old = out.get(k)
        out[k] = merged(old, v) if isinstance(v, dict) and isinstance(old, dict) else v
    return out
