"""The policy interface every planner implements, and per-call planning statistics.

A policy sees what a real parking system sees: the scenario's geometry once at reset
(``info["geometry"]`` of ``env.reset``, and again in the step where the scene changes:
``Policy.changed_scene``) and the measured vehicle state each step (``info["vehicle_state"]``).
It returns the environment's normalised action.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from mirrorpark_env.scenario import ScenarioGeometry


@dataclass(frozen=True)
class PlanStats:
    """One planning call: wall time, solver effort and outcome."""

    wall_time_s: float
    status: str  # "ok", "infeasible", "budget", "failed", ...
    iterations: int = 0  # outer iterations (SCP / Algorithm I / search expansions)
    qp_solves: int = 0
    nodes: int = 0  # branch-and-bound or search nodes
    cost: float = float("nan")
    detail: dict[str, Any] = field(default_factory=dict)


class Policy(ABC):
    """A parking planner as a policy: reset with the geometry, then act every step."""

    name: str = "policy"

    def __init__(self) -> None:
        self.stats: list[PlanStats] = []
        self.gave_up = False  # True once the policy has stopped trying (it only brakes now)
        self.setup_time_s = 0.0  # wall time of the last reset's per-episode preparation

    @abstractmethod
    def reset(self, geometry: ScenarioGeometry) -> None:
        """Start a new episode in ``geometry``; forget the last one's plans and stats."""

    @abstractmethod
    def act(self, obs: dict[str, np.ndarray], info: dict[str, Any]) -> np.ndarray:
        """The next normalised action [accel, steer] for the measured state in ``info``."""

    @staticmethod
    def changed_scene(info: dict[str, Any], known: ScenarioGeometry | None) -> ScenarioGeometry | None:
        """The scene in ``info`` where it is not the one ``known`` (the environment sends a
        changed scene, a late obstacle, once in that step's info), else None."""
        g = info.get("geometry")
        return g if g is not None and g is not known else None

    @property
    def status(self) -> str:
        """The last planning call's status ("none" before any)."""
        return self.stats[-1].status if self.stats else "none"


def run_episode(
    env,
    policy: Policy,
    scenario=None,
    seed: int | None = None,
    max_steps: int = 100_000,
    trace: list[dict] | None = None,
    record: list[tuple] | None = None,
    actions: list | None = None,
):
    """Roll ``policy`` out in ``env`` for one episode; return (last info, steps).

    ``scenario``: a grid ``Scenario`` or case id, a ``Layout``, or None (a random case).
    ``trace``, if given, receives the info of the reset and of every step; ``record`` the
    reset's (obs, info) and then every step's (action, obs, reward, terminated, truncated,
    info); ``actions`` every action the policy gave. An episode the policy gives up ends
    once the car stands, as truncated."""
    from mirrorpark_env.layout import Layout

    key = "layout" if isinstance(scenario, Layout) else "scenario"
    options = {key: scenario} if scenario is not None else None
    obs, info = env.reset(seed=seed, options=options)
    policy.reset(info["geometry"])
    if trace is not None:
        trace.append(info)
    if record is not None:
        record.append((obs, info))
    steps = 0
    while steps < max_steps:
        action = policy.act(obs, info)
        if actions is not None:
            actions.append(action)
        obs, reward, terminated, truncated, info = env.step(action)
        steps += 1
        if trace is not None:
            trace.append(info)
        stop = terminated or truncated or (policy.gave_up and info["stopped"])
        if record is not None:
            record.append((action, obs, reward, terminated, truncated or (stop and not terminated), info))
        if stop:
            break
    return info, steps
