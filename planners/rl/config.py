"""Validated hyper-parameters of the RL baseline (``configs/rl.yaml``)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any, Literal

from pydantic import Field, model_validator

from mirrorpark_env.config import (
    PARKING_TYPES,
    LidarConfig,
    ParkingTypeName,
    StrictModel,
    default_config_path,
    merged,
    read_yaml,
    validate,
)


class HerConfig(StrictModel):
    enabled: bool = True  # off: a plain replay buffer (runs with ``shaping``, which HER's relabelling would drop)
    n_sampled_goal: int = Field(4, ge=1, le=32)
    goal_selection_strategy: Literal["future", "final", "episode"] = "future"


class CurriculumConfig(StrictModel):
    enabled: bool = True
    start_fraction: float = Field(0.2, gt=0, le=1)
    # schedule: the open fraction grows linearly to 1 at ``full_at`` x total_steps; success:
    # it grows by ``step`` each time ``window`` episodes at the current level parked at least
    # ``threshold`` of the time (``curriculum.SuccessLadder``)
    mode: Literal["schedule", "success"] = "schedule"
    full_at: float = Field(0.6, gt=0, le=1)
    step: float = Field(0.1, gt=0, le=1)
    threshold: float = Field(0.6, gt=0, le=1)
    window: int = Field(50, ge=1, le=100_000)


class ShapingConfig(StrictModel):
    """Potential-based shaping with the scene's cost to go (``shaping.CostToGoShaping``)."""

    enabled: bool = False
    scale: float = Field(10.0, gt=0, le=1000)  # [m] of cost to go per unit of reward
    cap: float = Field(60.0, gt=0, le=10_000)  # [m] the cost to go read where it is larger or unknown


class EvalConfig(StrictModel):
    every_steps: int = Field(10_000, ge=1)
    episodes: int = Field(30, ge=1, le=10_000)


class BCConfig(StrictModel):
    """Behaviour cloning of the actor from demonstrations (``train-rl --demos``)."""

    epochs: int = Field(20, ge=1, le=10_000)
    batch_size: int = Field(256, ge=1)
    learning_rate: float = Field(1e-3, gt=0, le=1)
    successes_only: bool = True  # clone only the episodes that ended parked
    # mse fits the mean action, l1 the median: where the labels of nearby states split between
    # two gears, the mean creeps between them and the median takes the majority's, which on
    # DAgger's labels of a standing car is the hold (docs/rl.md: l1 parks less there)
    loss: Literal["mse", "l1"] = "mse"


class DaggerConfig(StrictModel):
    """DAgger with a planner as the expert (``train-rl --dagger-rounds``, ``dagger.py``)."""

    expert: str = "guide-only"  # a named planner that tracks a path in feedback (guide-only, hybrid-astar)
    cases_per_round: int = Field(600, ge=1)  # training cases per round, split evenly over the types
    beta0: float = Field(1.0, ge=0, le=1)  # chance that the expert's action is the one executed, round 1 ...
    beta_decay: float = Field(0.5, ge=0, le=1)  # ... times this each further round
    max_steps: int = Field(900, ge=1, le=1800)  # steps per rollout (0.1 s each)
    expert_max_plans: int = Field(20, ge=1)  # plans the expert may make per rollout (it replans after drifts)
    # After a drift the expert plans again at once, moving or not (TrackingPolicy.replan_moving);
    # false: it brakes to a stand first, and its labels there say "brake".
    expert_replans_moving: bool = False
    # The expert plans afresh from every state it is asked about, a switch priced where its
    # path starts in the other gear than the car moves (TrackingPolicy.markov): its label is a
    # function of the state alone. Needs an expert that prices the start gear (guide-only).
    expert_markov: bool = False
    # [m/s] the expert's cruising speed on its path (None: its tracker's own, 1 m/s); a slower
    # expert leaves a learner's error in speed or steering more room before an obstacle.
    expert_cruise_speed: float | None = Field(None, gt=0, le=3)
    # The learner's actions in the rollouts pass the safety filter of ``rl-shield:`` (shield.py):
    # where one would lead into an obstacle the car brakes instead, and the episode goes on from
    # there, so the expert labels the states a shielded learner meets (near-misses and what
    # follows them) rather than ending at a collision. For models meant to run as rl-shield.
    shield: bool = False
    # With shield: where a standing learner's start is blocked, the filter takes its second
    # choice in the other gear where that is clear, as rl-shield does since 2026-12-02; false
    # keeps the brake alone, as the runs before then did. Needs shield.
    shield_second_gear: bool = False
    # The expert's labels at a stand also carry the gear its path starts in, a gear head learns
    # it, and a standing learner re-steers, then goes in that gear (gear.py). Needs expert_markov.
    gear: bool = False
    workers: int = Field(0, ge=0)  # rollout processes (0: all cores)

    @model_validator(mode="after")
    def _gear_needs_markov(self) -> DaggerConfig:
        if self.gear and not self.expert_markov:
            raise ValueError("dagger.gear: needs dagger.expert_markov: true (only a Markov expert labels a gear)")
        return self

    @model_validator(mode="after")
    def _second_gear_needs_shield(self) -> DaggerConfig:
        if self.shield_second_gear and not self.shield:
            raise ValueError("dagger.shield_second_gear: needs dagger.shield: true (it is a choice the filter makes)")
        return self


class RLConfig(StrictModel):
    algo: Literal["sac", "tqc"] = "sac"
    total_steps: int = Field(200_000, ge=1)
    max_episode_steps: int = Field(300, ge=1, le=1800)
    learning_starts: int = Field(2000, ge=0)
    buffer_size: int = Field(1_000_000, ge=1000)
    batch_size: int = Field(256, ge=1)
    learning_rate: float = Field(1e-3, gt=0, le=1)
    # SAC/TQC entropy coefficient: a fixed number, or "auto" / "auto_<initial value>" (learned)
    ent_coef: Annotated[str, Field(pattern=r"^auto(_[0-9]*\.?[0-9]+)?$")] | Annotated[float, Field(gt=0)] = "auto"
    gamma: float = Field(0.95, gt=0, le=1)
    tau: float = Field(0.05, gt=0, le=1)
    train_freq: int = Field(1, ge=1)
    gradient_steps: int = Field(1, ge=1)
    net_arch: list[int] = Field(default_factory=lambda: [256, 256], min_length=1)
    # flat: the observation as the env gives it; slot_frame: the pose relative to the target,
    # in its frame, at scene and slot scale (features.SlotFrameFeatures)
    features: Literal["flat", "slot_frame"] = "flat"
    # a ring of ranges from the body centre to the obstacles in the observation (the env's
    # ``lidar``): what a policy needs to keep clear of what it cannot infer from the pose
    lidar: LidarConfig = LidarConfig()
    her: HerConfig = HerConfig()
    curriculum: CurriculumConfig = CurriculumConfig()
    shaping: ShapingConfig = ShapingConfig()
    eval: EvalConfig = EvalConfig()
    bc: BCConfig = BCConfig()
    dagger: DaggerConfig = DaggerConfig()
    checkpoint_every_steps: int = Field(50_000, ge=1)
    parking_types: list[ParkingTypeName] = Field(default_factory=lambda: list(PARKING_TYPES), min_length=1)
    device: str = "auto"
    torch_threads: int = Field(1, ge=1, le=256)
    seed: int = 0


def env_config(cfg: RLConfig) -> dict[str, Any]:
    """The MirrorPark-v0 config a policy trained with ``cfg`` observes through."""
    return {"lidar": cfg.lidar.model_dump()} if cfg.lidar.rays else {}


def algo_class(name: str):
    """The stable-baselines3 class of ``name`` ("sac" or "tqc"); imports the rl extra."""
    if name == "tqc":
        from sb3_contrib import TQC

        return TQC
    from stable_baselines3 import SAC

    return SAC


def load_rl_config(path: str | Path | None = None, overrides: dict[str, Any] | None = None) -> RLConfig:
    """``configs/rl.yaml`` (or ``path``, with the files it ``extends``) with ``overrides``
    (whole top-level fields), validated field by field."""
    p = Path(path) if path is not None else default_config_path("rl.yaml")
    data = read_recipe(p)
    data.update({k: v for k, v in (overrides or {}).items() if v is not None})
    return validate(RLConfig, data, source=p.name)


def read_recipe(path: str | Path, _chain: tuple[Path, ...] = ()) -> dict[str, Any]:
    """A recipe file's mapping. ``extends: FILE`` (relative to the file) starts from FILE's
    recipe and changes only what this file names, nested sections key by key, so that a
    recipe says how it differs from the one it builds on."""
    p = Path(path).resolve()
    if p in _chain:
        raise ValueError(f"{p.name}: extends: a cycle ({' -> '.join(q.name for q in (*_chain, p))})")
    data = read_yaml(p)
    base = data.pop("extends", None)
    if base is None:
        return data
    if not isinstance(base, str) or not base:
        raise ValueError(f"{p.name}: extends: must be a YAML file name, relative to this file, got {base!r}")
    return merged(read_recipe(p.parent / base, (*_chain, p)), data)
