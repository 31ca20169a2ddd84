"""Behaviour cloning: the RL agent's actor taught to copy a planner's demonstrations.

The demonstrations are a Minari dataset written by ``mirrorpark collect``. The actor of
the same SAC / TQC model that ``train-rl`` builds is fitted by supervised regression of
its deterministic action on the expert's (mean squared error), so that the result loads
like any trained model (``--planner rl:PATH``) and can start RL fine-tuning.
"""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Any

import numpy as np

from .config import RLConfig


def dataset_path(demos: str | Path) -> Path:
    """The Minari data folder inside what ``collect`` wrote (or the folder itself)."""
    p = Path(demos)
    if (p / "metadata.json").exists() or p.name == "data":
        return p
    found = sorted(p.glob("minari/*/*/data")) + sorted(p.glob("*/*/data")) + sorted(p.glob("data"))
    if not found:
        raise ValueError(f"demos: no Minari dataset under {str(p)!r} (write one with mirrorpark collect)")
    return found[0]


def load_demos(demos: str | Path, successes_only: bool = True) -> tuple[dict[str, np.ndarray], np.ndarray, int]:
    """(observations by key, actions, episodes used): every step's observation before its action."""
    import minari

    ds = minari.MinariDataset(dataset_path(demos))
    obs: dict[str, list[np.ndarray]] = {}
    acts, used = [], 0
    for ep in ds.iterate_episodes():
        if successes_only and not bool(ep.infos["is_success"][-1, 0]):
            continue
        used += 1
        for key, v in ep.observations.items():
            obs.setdefault(key, []).append(np.asarray(v[:-1], np.float32))
        acts.append(np.asarray(ep.actions, np.float32))
    if not acts:
        raise ValueError(f"demos: {str(demos)!r} holds no usable episode")
    return {k: np.concatenate(v) for k, v in obs.items()}, np.concatenate(acts), used


def fit_actor(
    model, obs: dict[str, np.ndarray], actions: np.ndarray, cfg: RLConfig, progress: bool = True
) -> list[float]:
    """Regress the model's deterministic action on ``actions`` (``cfg.bc.loss``); the mean loss of each epoch.

    Raises ``ValueError`` where ``obs`` lacks a part of what the model observes (a dataset
    recorded without the lidar the config asks for)."""
    import torch
    from tqdm import tqdm

    missing = sorted(set(model.observation_space.spaces) - set(obs))
    if missing:
        raise ValueError(
            f"the demonstrations hold no {', '.join(missing)} observations, which this config's model "
            f"observes (lidar.rays: {cfg.lidar.rays}); set lidar.rays: 0 to clone them"
        )

    torch.manual_seed(cfg.seed)
    rng = np.random.default_rng(cfg.seed)
    actor = model.actor
    opt = torch.optim.Adam(actor.parameters(), lr=cfg.bc.learning_rate)
    target_all = np.clip(actions, -0.999, 0.999)  # a tanh-squashed actor cannot reach +-1
    n = len(actions)
    loss_fn = {"mse": torch.nn.functional.mse_loss, "l1": torch.nn.functional.l1_loss}[cfg.bc.loss]
    history = []
    for _ in tqdm(range(cfg.bc.epochs), desc="behaviour cloning", unit="epoch", disable=not progress):
        order = rng.permutation(n)
        total = 0.0
        for b0 in range(0, n, cfg.bc.batch_size):
            idx = order[b0 : b0 + cfg.bc.batch_size]
            batch, _ = model.policy.obs_to_tensor({k: v[idx] for k, v in obs.items()})
            target = torch.as_tensor(target_all[idx], device=model.device)
            loss = loss_fn(actor(batch, deterministic=True), target)
            opt.zero_grad()
            loss.backward()
            opt.step()
            total += float(loss.detach()) * len(idx)
        history.append(total / n)
    return history


def action_error(model, obs: dict[str, np.ndarray], actions: np.ndarray) -> float:
    """Mean squared difference between the model's deterministic actions and ``actions``."""
    pred, _ = model.predict(obs, deterministic=True)
    return float(np.mean((pred - actions) ** 2))


def behaviour_clone(cfg: RLConfig, demos: str | Path, out: str | Path, progress: bool = True) -> dict[str, Any]:
    """Fit a fresh model's actor to the demonstrations; save ``model.zip`` and ``train.json``."""
    import torch

    from mirrorpark_env.grid import Grid

    from .train import make_model, make_train_env

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    torch.set_num_threads(cfg.torch_threads)
    obs, actions, episodes = load_demos(demos, cfg.bc.successes_only)
    model = make_model(cfg, make_train_env(cfg, Grid.from_config()))
    before = action_error(model, obs, actions)
    t0 = time.perf_counter()
    history = fit_actor(model, obs, actions, cfg, progress)
    wall = time.perf_counter() - t0
    return save_trained(
        model,
        cfg,
        out,
        "bc",
        demos,
        episodes,
        len(actions),
        wall,
        epochs=cfg.bc.epochs,
        loss_per_epoch=[round(v, 6) for v in history],
        action_error_before=round(before, 6),
        action_error_after=round(action_error(model, obs, actions), 6),
    )


def save_trained(
    model, cfg: RLConfig, out: Path, method: str, demos, episodes: int, samples: int, wall: float, **extra
) -> dict[str, Any]:
    """``model.zip`` and ``train.json`` (what was trained, on what, how long) in ``out``."""
    model.save(out / "model.zip")
    summary = {
        "algo": cfg.algo,
        "method": method,
        "demos": str(dataset_path(demos)) if demos is not None else None,
        "episodes": episodes,
        "samples": int(samples),
        **extra,
        "wall_time_s": round(wall, 1),
        "device": str(model.device),
        "config": cfg.model_dump(),
    }
    (out / "train.json").write_text(json.dumps(summary, indent=2))
    return summary
