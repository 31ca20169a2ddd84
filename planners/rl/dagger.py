"""DAgger: the learner drives, the planner says what it would have done there.

Each round rolls the current learner (the cloned actor) out on training cases of the
grid; at every state it visits, the expert (a fresh plan of the mirror planner from that
state: its first command) labels the action. The labelled states join the dataset, and
the actor is fitted again on all of it (Ross et al., 2011). Training cases are drawn
from the grid with a seed per round, apart from the smoke and standard samples' seed.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import numpy as np

from mirrorpark_env.scenario import Scenario, ScenarioGeometry
from mirrorpark_env.vehicle import VehicleState, to_action

from .bc import action_error, fit_actor, load_demos, save_trained
from .config import RLConfig


class PlannerExpert:
    """The mirror planner asked at any state: the first command of a plan from there
    (a hold-and-brake command where it finds none)."""

    def __init__(self) -> None:
        self.calls = 0

    def reset(self, geometry: ScenarioGeometry) -> None:
        from planners.mirror.planner import MirrorPlanner

        self.planner = MirrorPlanner(geometry)
        self.planner.prepare()
        self.params = geometry.vehicle

    def label(self, s: VehicleState) -> np.ndarray:
        from planners.common.tracker import hold_accel

        self.calls += 1
        plan = self.planner.plan(s)
        if plan is None:
            return to_action(self.params, hold_accel(self.params, s.v, s.a), s.delta)
        a, d = plan.commands[0]
        return to_action(self.params, float(a), float(d))


def dagger_round(model, env, expert: PlannerExpert, cases: list[Scenario], max_steps: int):
    """The learner's visited observations on ``cases`` with the expert's actions there."""
    obs_out: dict[str, list[np.ndarray]] = {}
    labels = []
    for sc in cases:
        obs, info = env.reset(options={"scenario": sc})
        expert.reset(info["geometry"])
        for _ in range(max_steps):
            for k, v in obs.items():
                obs_out.setdefault(k, []).append(np.asarray(v, np.float32))
            labels.append(expert.label(info["vehicle_state"]))
            action, _ = model.predict(obs, deterministic=True)
            obs, _, term, trunc, info = env.step(action)
            if term or trunc:
                break
    return {k: np.stack(v) for k, v in obs_out.items()}, np.asarray(labels, np.float32)


def dagger(
    cfg: RLConfig,
    demos: str | Path,
    out: str | Path,
    rounds: int = 3,
    cases_per_round: int = 60,
    progress: bool = True,
) -> dict[str, Any]:
    """Behaviour cloning on ``demos``, then ``rounds`` DAgger rounds; saves model.zip, train.json."""
    import gymnasium as gym
    import torch

    from mirrorpark_env.grid import Grid

    from .train import make_model, make_train_env

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    torch.set_num_threads(cfg.torch_threads)
    grid = Grid.from_config()
    obs, actions, episodes = load_demos(demos, cfg.bc.successes_only)
    model = make_model(cfg, make_train_env(cfg, grid))
    t0 = time.perf_counter()
    fit_actor(model, obs, actions, cfg, progress)
    env = gym.make("MirrorPark-v0")
    expert = PlannerExpert()
    log = []
    per_type = max(1, cases_per_round // len(cfg.parking_types))
    for r in range(rounds):
        cases = grid.sample(per_type, seed=10_000 + cfg.seed * 100 + r, types=tuple(cfg.parking_types))
        new_obs, new_actions = dagger_round(model, env, expert, cases, cfg.max_episode_steps)
        obs = {k: np.concatenate([obs[k], new_obs[k]]) for k in obs}
        actions = np.concatenate([actions, new_actions])
        err = action_error(model, new_obs, new_actions)  # before refitting: how far the learner strayed
        fit_actor(model, obs, actions, cfg, progress)
        log.append({"round": r + 1, "labelled": int(len(new_actions)), "error_on_new": round(err, 6)})
    wall = time.perf_counter() - t0
    return save_trained(
        model,
        cfg,
        out,
        "dagger",
        demos,
        episodes,
        len(actions),
        wall,
        rounds=log,
        expert_calls=expert.calls,
        epochs_per_fit=cfg.bc.epochs,
    )
