"""RL fine-tuning from demonstrations: SAC / TQC + HER whose actor starts from the cloned
policy and whose replay buffer holds the demonstrations (``train-rl --demos D --finetune``).

The recipe of Nair et al. (2018), "Overcoming exploration in reinforcement learning with
demonstrations", on stable-baselines3's public API:

1. behaviour cloning of the actor (``bc.fit_actor``);
2. every demonstration step added to the HER replay buffer (relabelled like the agent's);
3. the critics warmed up on that buffer with the actor held at its cloned weights, so that
   the first actor updates follow a critic that has seen the expert's returns;
4. SAC + HER on the environment, plus, every ``bc_every`` steps, gradient steps on a
   behaviour-cloning loss over demonstration states, kept only where the critic rates the
   expert's action above the actor's (the Q-filter), with a weight that falls linearly to
   zero over ``bc_anneal_steps``: the demonstrations guide while they matter.
"""

from __future__ import annotations

import copy
import time
from pathlib import Path
from typing import Any

import numpy as np

from .bc import action_error, dataset_path, fit_actor, load_demos, save_trained
from .config import RLConfig


def demo_transitions(demos: str | Path, successes_only: bool = True):
    """Per demonstration episode: (observations n + 1 by key, actions, rewards, terminations,
    truncations, per-step infos with ``is_success`` and ``collision``)."""
    import minari

    ds = minari.MinariDataset(dataset_path(demos))
    for ep in ds.iterate_episodes():
        if successes_only and not bool(ep.infos["is_success"][-1, 0]):
            continue
        infos = [
            {"is_success": bool(s), "collision": bool(c)}
            for s, c in zip(ep.infos["is_success"][1:, 0], ep.infos["collision"][1:, 0])
        ]
        yield ep.observations, ep.actions, ep.rewards, ep.terminations, ep.truncations, infos


def add_demos_to_buffer(model, demos: str | Path, successes_only: bool = True) -> int:
    """Every demonstration step into ``model.replay_buffer`` (env 0, episode by episode); the count."""
    n = 0
    for obs, actions, rewards, terms, truncs, infos in demo_transitions(demos, successes_only):
        steps = len(actions)
        for t in range(steps):
            now = {k: np.asarray(v[t : t + 1]) for k, v in obs.items()}
            nxt = {k: np.asarray(v[t + 1 : t + 2]) for k, v in obs.items()}
            last = t == steps - 1
            info = dict(infos[t])
            if last and bool(truncs[t]) and not bool(terms[t]):
                info["TimeLimit.truncated"] = True
            model.replay_buffer.add(
                now, nxt, np.asarray(actions[t : t + 1]), np.asarray([rewards[t]]), np.asarray([last]), [info]
            )
            n += 1
    return n


def warm_up_critic(model, gradient_steps: int) -> None:
    """SAC updates on the buffer with the actor restored to its weights afterwards."""
    if gradient_steps <= 0:
        return
    actor = copy.deepcopy(model.actor.state_dict())
    model.train(gradient_steps=gradient_steps, batch_size=model.batch_size)
    model.actor.load_state_dict(actor)
    model.actor.optimizer.state.clear()  # Adam's moments belonged to the discarded steps


def q_filtered_bc_step(
    model, obs: dict[str, np.ndarray], actions: np.ndarray, weight: float, rng, q_filter: bool = True
) -> float:
    """One actor step on ``weight`` x the mean squared gap to the expert's action over a
    batch of demonstration states, where the critic prefers the expert's action (all of
    them without ``q_filter``); the share of states kept."""
    import torch

    idx = rng.integers(0, len(actions), size=model.batch_size)
    batch, _ = model.policy.obs_to_tensor({k: v[idx] for k, v in obs.items()})
    expert = torch.as_tensor(np.clip(actions[idx], -0.999, 0.999), device=model.device)
    pi = model.actor(batch, deterministic=True)
    with torch.no_grad():
        q_expert = torch.cat(model.critic(batch, expert), dim=1).min(dim=1).values
        q_pi = torch.cat(model.critic(batch, pi.detach()), dim=1).min(dim=1).values
        keep = (q_expert > q_pi).float() if q_filter else torch.ones_like(q_pi)
    loss = weight * (keep * ((pi - expert) ** 2).sum(dim=1)).mean()
    model.actor.optimizer.zero_grad()
    loss.backward()
    model.actor.optimizer.step()
    return float(keep.mean())


def finetune(cfg: RLConfig, demos: str | Path, out: str | Path, progress: bool = True) -> dict[str, Any]:
    """BC, demonstrations in the buffer, critic warm-up, then SAC/TQC + HER with the
    Q-filtered BC term for ``cfg.total_steps``; ``model.zip`` and ``train.json`` in ``out``."""
    import torch
    from stable_baselines3.common.callbacks import BaseCallback, CallbackList
    from stable_baselines3.common.logger import Logger, make_output_format

    from mirrorpark_env.grid import Grid

    from .train import (
        eval_callback,
        learning_curve,
        make_eval_env,
        make_model,
        make_train_env,
        plot_learning_curve,
        progress_callback,
    )

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    torch.set_num_threads(cfg.torch_threads)
    ft = cfg.finetune
    grid = Grid.from_config()
    model = make_model(cfg, make_train_env(cfg, grid))
    model.set_logger(Logger(str(out), [make_output_format("csv", str(out))]))
    obs, actions, episodes = load_demos(demos, cfg.bc.successes_only)
    t0 = time.perf_counter()
    fit_actor(model, obs, actions, cfg, progress)
    bc_error = action_error(model, obs, actions)
    n_demo = add_demos_to_buffer(model, demos, cfg.bc.successes_only)
    warm_up_critic(model, ft.critic_warmup_steps)
    rng = np.random.default_rng(cfg.seed)
    kept: list[float] = []

    class BCTerm(BaseCallback):
        def _on_step(self) -> bool:
            t = self.model.num_timesteps
            weight = ft.bc_weight * max(0.0, 1.0 - t / ft.bc_anneal_steps)
            if weight > 0 and t % ft.bc_every == 0:
                for _ in range(ft.bc_gradient_steps):
                    kept.append(q_filtered_bc_step(self.model, obs, actions, weight, rng, ft.q_filter))
                self.logger.record("train/bc_weight", weight)
            return True

    callbacks = [
        BCTerm(),
        progress_callback(cfg.total_steps, "fine-tune", progress),
        eval_callback(cfg, make_eval_env(cfg, grid), out),
    ]
    model.learn(total_timesteps=cfg.total_steps, callback=CallbackList(callbacks))
    wall = time.perf_counter() - t0
    curve = learning_curve(out)
    if curve:
        plot_learning_curve(curve, out / "learning_curve.png")
    return save_trained(
        model,
        cfg,
        out,
        "bc+" + cfg.algo,
        demos,
        episodes,
        len(actions),
        wall,
        steps_done=int(model.num_timesteps),
        demo_transitions_in_buffer=n_demo,
        action_error_after_bc=round(bc_error, 6),
        action_error_after_finetune=round(action_error(model, obs, actions), 6),
        q_filter_kept=round(float(np.mean(kept)), 3) if kept else None,
        final_eval_success_rate=curve[-1][1] if curve else None,
    )
