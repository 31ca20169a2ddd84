"""Train the RL baseline: SAC or TQC with HER on MirrorPark-v0 (``mirrorpark train-rl``).

Writes to ``out``: ``model.zip`` (the final policy), ``train.json`` (algorithm, config,
steps, wall time, device, final evaluation), ``checkpoints/``, ``progress.csv`` and
TensorBoard event files (``tb/``), ``evaluations.npz`` (the periodic ISO evaluations)
and ``learning_curve.png``. Needs the ``rl`` extra (torch, stable-baselines3, sb3-contrib).
"""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

import mirrorpark_env  # noqa: F401  (registers MirrorPark-v0)
from mirrorpark_env.grid import Grid

from .config import RLConfig, algo_class, env_config
from .curriculum import CurriculumScenarios, FixedScenarios, LeanInfo, SuccessLadder
from .shaping import CostToGoShaping


def make_train_env(cfg: RLConfig, grid: Grid) -> gym.Env:
    from stable_baselines3.common.monitor import Monitor

    env = gym.make("MirrorPark-v0", max_episode_steps=cfg.max_episode_steps, config=env_config(cfg))
    start = cfg.curriculum.start_fraction if cfg.curriculum.enabled else 1.0
    env = CurriculumScenarios(env, cfg.parking_types, level=start, grid=grid)
    if cfg.shaping.enabled:
        env = CostToGoShaping(env, cfg.gamma, cfg.shaping.scale, cfg.shaping.cap)
    return Monitor(LeanInfo(env))


def make_eval_env(cfg: RLConfig, grid: Grid) -> gym.Env:
    from stable_baselines3.common.monitor import Monitor

    per_type = max(1, -(-cfg.eval.episodes // len(cfg.parking_types)))
    cases = grid.sample(per_type, seed=cfg.seed + 1, types=tuple(cfg.parking_types))
    return Monitor(FixedScenarios(gym.make("MirrorPark-v0", config=env_config(cfg)), cases[: cfg.eval.episodes]))


def make_model(cfg: RLConfig, env: gym.Env):
    """The SAC or TQC model with HER that ``cfg`` describes, on ``env``."""
    from stable_baselines3 import HerReplayBuffer

    her = dict(
        replay_buffer_class=HerReplayBuffer,
        replay_buffer_kwargs=dict(
            n_sampled_goal=cfg.her.n_sampled_goal,
            goal_selection_strategy=cfg.her.goal_selection_strategy,
            copy_info_dict=True,  # relabelled rewards keep the collision penalty
        ),
    )
    return algo_class(cfg.algo)(
        "MultiInputPolicy",
        env,
        **(her if cfg.her.enabled else {}),
        learning_starts=cfg.learning_starts,
        buffer_size=min(cfg.buffer_size, max(cfg.total_steps, 1000)),
        batch_size=cfg.batch_size,
        learning_rate=cfg.learning_rate,
        ent_coef=cfg.ent_coef,
        gamma=cfg.gamma,
        tau=cfg.tau,
        train_freq=cfg.train_freq,
        gradient_steps=cfg.gradient_steps,
        policy_kwargs=policy_kwargs(cfg),
        device=cfg.device,
        seed=cfg.seed,
        verbose=0,
    )


def policy_kwargs(cfg: RLConfig) -> dict:
    """The network of ``cfg``: its layers and, for ``features: slot_frame``, the extractor."""
    kw: dict = dict(net_arch=list(cfg.net_arch))
    if cfg.features == "slot_frame":
        from .features import SlotFrameFeatures

        kw["features_extractor_class"] = SlotFrameFeatures
    return kw


def latest_checkpoint(out: Path, algo: str) -> tuple[Path, int] | None:
    """The checkpoint with the most steps in ``out/checkpoints`` and its step count."""
    found = []
    for p in (out / "checkpoints").glob(f"{algo}_*_steps.zip"):
        steps = p.stem[len(algo) + 1 : -len("_steps")]
        if steps.isdigit():
            found.append((int(steps), p))
    return (max(found)[1], max(found)[0]) if found else None


def resume_config(out: str | Path) -> RLConfig:
    """The config an interrupted run in ``out`` was started with."""
    p = Path(out) / "config.json"
    if not p.exists():
        raise ValueError(f"--resume: {str(p)!r} not found: {out} holds no run of train-rl")
    data = json.loads(p.read_text())
    data.pop("finetune", None)  # retired on 2026-12-06 (fine-tuning forgot the clone); runs before it still resume
    return RLConfig.model_validate(data)


def train(cfg: RLConfig, out: str | Path, progress: bool = True, resume: bool = False) -> dict[str, Any]:
    """Train per ``cfg``, save everything under ``out``; return the summary of train.json.

    ``resume``: continue from the latest checkpoint in ``out`` (its weights, replay buffer
    and step count) up to ``cfg.total_steps``, not from zero."""
    import torch
    from stable_baselines3.common.callbacks import CallbackList, CheckpointCallback
    from stable_baselines3.common.logger import Logger, make_output_format

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    torch.set_num_threads(cfg.torch_threads)
    grid = Grid.from_config()
    env = make_train_env(cfg, grid)
    eval_env = make_eval_env(cfg, grid)
    if resume:
        found = latest_checkpoint(out, cfg.algo)
        if found is None:
            raise ValueError(f"--resume: no checkpoint in {out / 'checkpoints'}")
        model = algo_class(cfg.algo).load(found[0], env=env, device=cfg.device)
        buffer = found[0].with_name(f"{cfg.algo}_replay_buffer_{found[1]}_steps.pkl")
        if buffer.exists():
            model.load_replay_buffer(buffer)
    else:
        model = make_model(cfg, env)
        (out / "config.json").write_text(cfg.model_dump_json(indent=2))
    formats = [make_output_format("csv", str(out))]  # progress.csv beside the model
    if _has_tensorboard():
        formats.append(make_output_format("tensorboard", str(out / "tb")))
    model.set_logger(Logger(str(out), formats))

    callbacks = CallbackList(
        [
            curriculum_callback(cfg),
            progress_callback(cfg.total_steps, f"train-rl {cfg.algo}", progress),
            CheckpointCallback(
                cfg.checkpoint_every_steps, str(out / "checkpoints"), name_prefix=cfg.algo, save_replay_buffer=True
            ),
            eval_callback(cfg, eval_env, out),
        ]
    )
    t0 = time.perf_counter()
    start = model.num_timesteps
    model.learn(total_timesteps=max(cfg.total_steps - start, 0), callback=callbacks, reset_num_timesteps=not resume)
    wall = time.perf_counter() - t0
    model.save(out / "model.zip")
    curve = learning_curve(out)
    summary = {
        "algo": cfg.algo,
        "total_steps": cfg.total_steps,
        "resumed_from_step": start if resume else None,
        "steps_done": int(model.num_timesteps),
        "wall_time_s": round(wall, 1),  # of this run (a resumed run: of its part)
        "steps_per_s": round((model.num_timesteps - start) / wall, 1) if wall > 0 else None,
        "device": str(model.device),
        "parking_types": list(cfg.parking_types),
        "final_eval_success_rate": curve[-1][1] if curve else None,
        "config": cfg.model_dump(),
    }
    (out / "train.json").write_text(json.dumps(summary, indent=2))
    if curve:
        plot_learning_curve(curve, out / "learning_curve.png")
    return summary


def curriculum_callback(cfg: RLConfig):
    """Sets the training cases' curriculum level each step: on ``cfg.curriculum.mode``'s
    schedule, or from the episodes' success (``SuccessLadder``); logged as
    ``train/curriculum_level``."""
    from stable_baselines3.common.callbacks import BaseCallback

    cc = cfg.curriculum

    class Curriculum(BaseCallback):
        def _on_training_start(self) -> None:
            self.ladder = SuccessLadder(cc.start_fraction, cc.step, cc.threshold, cc.window)

        def _on_step(self) -> bool:
            if not cc.enabled:
                return True
            if cc.mode == "success":
                for done, info in zip(self.locals["dones"], self.locals["infos"]):
                    if done:
                        self.ladder.record(bool(info.get("is_success", False)))
                level = self.ladder.level
            else:
                frac = min(1.0, self.num_timesteps / (cc.full_at * cfg.total_steps))
                level = cc.start_fraction + (1 - cc.start_fraction) * frac
            self.training_env.env_method("set_level", level)
            self.logger.record("train/curriculum_level", level)
            return True

    return Curriculum()


def progress_callback(total: int, desc: str, enabled: bool):
    """A tqdm bar over environment steps (tqdm is a core dependency; SB3's bar needs rich)."""
    from stable_baselines3.common.callbacks import BaseCallback

    class Progress(BaseCallback):
        def _on_training_start(self) -> None:
            from tqdm import tqdm

            self.bar = tqdm(total=total, desc=desc, unit="step", disable=not enabled)

        def _on_step(self) -> bool:
            self.bar.update(self.model.num_timesteps - self.bar.n)
            return True

        def _on_training_end(self) -> None:
            self.bar.close()

    return Progress()


def eval_callback(cfg: RLConfig, eval_env: gym.Env, out: Path):
    """The periodic ISO evaluation on fixed cases, saved in ``out/evaluations.npz``."""
    from stable_baselines3.common.callbacks import EvalCallback

    return EvalCallback(
        eval_env,
        n_eval_episodes=cfg.eval.episodes,
        eval_freq=cfg.eval.every_steps,
        log_path=str(out),
        deterministic=True,
        verbose=0,
    )


def learning_curve(out: str | Path) -> list[tuple[int, float, float]]:
    """(timestep, ISO success rate, mean return) of each periodic evaluation."""
    p = Path(out) / "evaluations.npz"
    if not p.exists():
        return []
    d = np.load(p)
    succ = (
        d["successes"].mean(axis=1)
        if "successes" in d and d["successes"].size
        else np.full(len(d["timesteps"]), np.nan)
    )
    return [(int(t), float(s), float(r)) for t, s, r in zip(d["timesteps"], succ, d["results"].mean(axis=1))]


def plot_learning_curve(curve: list[tuple[int, float, float]], path: str | Path) -> Path:
    """Success rate and mean return of the periodic evaluations against steps."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = [c[0] for c in curve]
    fig, ax = plt.subplots(1, 2, figsize=(9, 3.2))
    ax[0].plot(t, [100 * c[1] for c in curve], marker="o")
    ax[0].set(xlabel="environment steps", ylabel="ISO success [%]", title="evaluation success", ylim=(-2, 102))
    ax[1].plot(t, [c[2] for c in curve], marker="o")
    ax[1].set(xlabel="environment steps", ylabel="mean return", title="evaluation return")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return Path(path)


def _has_tensorboard() -> bool:
    try:
        import tensorboard  # noqa: F401
    except ImportError:
        return False
    return True
