"""DAgger: the learner drives, a planner riding along says what it would do there.

The expert is a named planner policy that tracks its path in feedback (``guide-only`` by
default, or ``hybrid-astar``), run in the shadow of the learner: each step it sees the
state the learner's actions led to, as it would see its own, and answers with its
action: the tracker's correction back to its path, or a brake and a new plan from where
the car stands once it has drifted too far. So every label is what the expert does from
that state, with the expert's own memory of the manoeuvre it is in, never a fresh start
(an earlier version labelled with the first command of a fresh plan, which at a moving
state is "stop": the learner learned to hesitate).

With ``dagger.expert_markov`` the expert keeps no such memory: it plans afresh from every
state, and a path that starts in the other gear than the car moves pays a direction
switch, so it drives on where it can (``TrackingPolicy.markov``). Its label is then a
function of what the learner observes, as DAgger's analysis assumes; measured, this is
what made the learner park (docs/rl.md).

Round ``r`` (from 1) executes the expert's action with probability
``beta0 * beta_decay ** (r - 1)`` and the learner's otherwise (Ross et al., 2011); with
``beta0 = 1`` the first round is plain demonstration. Each round's states and labels join
the data, and the actor is fitted again on all of it (``bc.fit_actor``). Rollouts end
when the episode does, or when the expert gives up (it has no label to give then).
Training cases come from the grid with a seed per round, and cases of the smoke and
standard samples are left out, so that those samples stay unseen.

Each finished round leaves its model, all data so far and the log under ``OUT/rounds``;
``train-rl --resume OUT`` goes on from the last finished round (and ``--dagger-rounds``
there may raise the number of rounds). Every round's cases, coins and fit are seeded, so a
resumed run ends with the very weights of one run without a break.
"""

from __future__ import annotations

import json
import multiprocessing as mp
import os
import time
from collections.abc import Callable
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from mirrorpark_env.scenario import ParkingType, Scenario

from ..base import Policy
from .bc import action_error, fit_actor, load_demos, save_trained
from .config import RLConfig, env_config
from .gear import (
    STAND_SPEED,
    GearedModel,
    fit_head,
    go_accels,
    learner_action,
    load_head,
    make_head,
    second_choice,
)


class ShadowExpert:
    """A planner policy asked for its action at the states the learner visits."""

    def __init__(
        self,
        policy: Policy,
        max_plans: int,
        replan_moving: bool = False,
        markov: bool = False,
        cruise_speed: float | None = None,
    ) -> None:
        from planners.common.tracking import TrackingPolicy

        self.policy = policy
        inner = getattr(self.policy, "inner", self.policy)  # under the slot-frame wrapper
        planner = getattr(inner, "name", type(inner).__name__)
        if not isinstance(inner, TrackingPolicy):
            raise ValueError(
                f"dagger.expert: {planner!r} does not track a path in feedback; use guide-only or hybrid-astar"
            )
        if markov and not inner.prices_start_gear:
            raise ValueError(f"dagger.expert_markov: {planner!r} does not price the gear it starts in; use guide-only")
        inner.max_plans = max_plans
        inner.replan_moving = replan_moving
        inner.markov = markov
        if cruise_speed is not None:
            inner.tracker_config = inner.tracker_config.model_copy(update={"cruise_speed": cruise_speed})
        self.inner = inner  # the tracking policy itself, whose plan and stops label the gear
        self.calls = 0
        self.gear = 0

    def reset(self, geometry) -> None:
        self.policy.reset(geometry)

    def label(self, obs: dict, info: dict) -> np.ndarray:
        """The expert's action here; ``gear`` then holds the gear its path starts in where the
        car stands and a Markov expert has a path it may start on (+1, -1), else 0."""
        self.calls += 1
        inner = self.inner
        vetoed = inner.safety_stops
        action = np.asarray(self.policy.act(obs, info), np.float32)
        s = info["vehicle_state"]
        tr = inner.tracker
        self.gear = 0
        if inner.markov and tr is not None and abs(s.v) <= STAND_SPEED and inner.safety_stops == vetoed:
            self.gear = tr.first_gear
        return action

    @property
    def gave_up(self) -> bool:
        return self.policy.gave_up


def rollouts(
    model,
    expert: ShadowExpert,
    cases: list[Scenario],
    beta: float,
    max_steps: int,
    seed: int,
    env_config: dict[str, Any] | None = None,
    shield: bool = False,
    second_gear: bool = False,
) -> tuple[dict[str, np.ndarray], np.ndarray, np.ndarray, dict[str, int]]:
    """States visited on ``cases`` under the mixed policy, with the expert's labels and the
    gears it starts in where the car stands (``ShadowExpert.label``). ``env_config``: the
    MirrorPark-v0 config the learner observes through; ``shield``: the learner's actions
    pass the safety filter (``shield.py``), with ``second_gear`` trying the learner's other
    gear where it blocks a standing start."""
    import gymnasium as gym

    import mirrorpark_env  # noqa: F401

    from .shield import Shield

    env = gym.make("MirrorPark-v0", config=env_config or {})
    rng = np.random.default_rng(seed)
    obs_out: dict[str, list[np.ndarray]] = {}
    labels: list[np.ndarray] = []
    gears: list[int] = []
    counts = {"episodes": 0, "parked": 0, "collided": 0, "expert_gave_up": 0, "shielded_steps": 0, "gear_swaps": 0}
    second = partial(second_choice, model)
    for sc in cases:
        obs, info = env.reset(options={"scenario": sc})
        expert.reset(info["geometry"])
        guard = Shield(info["geometry"], env.unwrapped.cfg.dt) if shield else None
        counts["episodes"] += 1
        for _ in range(max_steps):
            label = expert.label(obs, info)
            if expert.gave_up:
                counts["expert_gave_up"] += 1
                break
            for k, v in obs.items():
                obs_out.setdefault(k, []).append(np.asarray(v, np.float32))
            labels.append(label)
            gears.append(expert.gear)
            if beta >= 1.0 or (beta > 0.0 and rng.random() < beta):
                action = label
            else:
                action = learner_action(model, obs)
                if guard is not None:
                    action, how = guard.decide(info["vehicle_state"], action, second if second_gear else None)
                    counts["shielded_steps"] += int(how != "clear")
                    counts["gear_swaps"] += int(how == "other")
            obs, _, term, trunc, info = env.step(action)
            if term or trunc:
                break
        counts["parked"] += int(bool(info["is_success"]))
        counts["collided"] += int(bool(info["collision"]))
    acts = np.asarray(labels, np.float32).reshape(-1, 2)
    return {k: np.stack(v) for k, v in obs_out.items()}, acts, np.asarray(gears, np.int8), counts


def _worker(job: tuple) -> tuple:
    """One process's share of a round (the model loaded from its file, on the CPU)."""
    model_path, dc, cases, beta, seed, env_cfg, make_expert = job
    import torch

    torch.set_num_threads(1)
    model = None
    if beta < 1.0:
        from .policy import load_model

        model = load_model(str(model_path))
    expert = ShadowExpert(
        make_expert(dc.expert), dc.expert_max_plans, dc.expert_replans_moving, dc.expert_markov, dc.expert_cruise_speed
    )
    obs, labels, gears, counts = rollouts(
        model, expert, cases, beta, dc.max_steps, seed, env_cfg, dc.shield, dc.shield_second_gear
    )
    return obs, labels, gears, counts, expert.calls


def save_round(
    out: Path, model, obs: dict, actions: np.ndarray, gears: np.ndarray, log: list, expert_calls: int, episodes: int
) -> None:
    """The finished round's model (with its gear head, if any) and all data so far, then the
    log that points to them (written last and atomically: a run killed at any moment resumes
    from a whole round)."""
    r = len(log)
    model.save(out / "rounds" / f"model-r{r}.zip")
    tmp = out / "rounds" / f"data-r{r}.tmp.npz"
    np.savez(tmp, actions=actions, gears=gears, **{f"obs/{k}": v for k, v in obs.items()})
    os.replace(tmp, out / "rounds" / f"data-r{r}.npz")
    _write_json(out / "rounds" / "progress.json", {"log": log, "expert_calls": expert_calls, "episodes": episodes})
    for old in (out / "rounds").glob("data-r*.npz"):  # the earlier rounds' data is part of this one's
        if old.name != f"data-r{r}.npz":
            old.unlink()


def _load_data(out: Path, r: int) -> tuple[dict[str, np.ndarray], np.ndarray, np.ndarray]:
    with np.load(out / "rounds" / f"data-r{r}.npz") as d:
        gears = d["gears"] if "gears" in d.files else np.zeros(len(d["actions"]), np.int8)
        return {k[4:]: d[k] for k in d.files if k.startswith("obs/")}, d["actions"], gears


def load_progress(out: Path) -> dict | None:
    """What ``save_round`` last wrote in ``out`` (None: no round finished there)."""
    p = Path(out) / "rounds" / "progress.json"
    return json.loads(p.read_text()) if p.exists() else None


def _write_json(path: Path, data) -> None:
    tmp = path.with_suffix(".tmp")
    tmp.write_text(json.dumps(data, indent=2))
    os.replace(tmp, path)


def training_cases(grid, n: int, seed: int, types: tuple[str, ...]) -> list[Scenario]:
    """``n`` grid cases drawn uniformly (split evenly over ``types``), none of them in the
    smoke or standard samples."""
    held_out = {int(i) for name in ("smoke", "standard") for i in grid.sample_indices(name)}
    rng = np.random.default_rng(seed)
    per_type = max(1, -(-n // len(types)))
    chosen: list[int] = []
    for t in types:
        pool = [int(i) for i in grid.indices(ParkingType.parse(t)) if int(i) not in held_out]
        chosen += sorted(rng.choice(pool, size=min(per_type, len(pool)), replace=False).tolist())
    return [grid.scenario(i) for i in chosen]


def dagger(
    cfg: RLConfig,
    demos: str | Path | None,
    out: str | Path,
    rounds: int = 3,
    progress: bool = True,
    resume: bool = False,
    *,
    make_expert: Callable[[str], Policy],
) -> dict[str, Any]:
    """Optionally cloning ``demos`` first, then ``rounds`` DAgger rounds; saves model.zip,
    train.json. ``resume``: go on from the last round finished in ``out``. ``make_expert``:
    the policy named by ``cfg.dagger.expert`` (the CLI hands in the registry's ``make_policy``;
    a module-level function, as each round's worker processes start afresh)."""
    import torch

    from mirrorpark_env.grid import Grid

    from .train import make_model, make_train_env

    out = Path(out)
    (out / "rounds").mkdir(parents=True, exist_ok=True)
    torch.set_num_threads(cfg.torch_threads)
    grid = Grid.from_config()
    model = make_model(cfg, make_train_env(cfg, grid))
    learner = GearedModel(model, make_head(model.actor.features_dim), (1.0, -1.0)) if cfg.dagger.gear else model
    t0 = time.perf_counter()
    obs: dict[str, np.ndarray] = {}
    actions = np.zeros((0, 2), np.float32)
    gears = np.zeros(0, np.int8)
    episodes, log, expert_calls = 0, [], 0
    if resume:
        state = load_progress(out)
        if state is None:
            raise ValueError(f"--resume: {out} holds no finished DAgger round to go on from")
        log, expert_calls, episodes = state["log"], state["expert_calls"], state["episodes"]
        _write_json(out / "dagger.json", {**json.loads((out / "dagger.json").read_text()), "rounds": rounds})
        last = out / "rounds" / f"model-r{len(log)}.zip"
        model.set_parameters(str(last), exact_match=True, device=model.device)
        if cfg.dagger.gear:
            learner = load_head(model, last) or learner
        obs, actions, gears = _load_data(out, len(log))
    else:
        (out / "config.json").write_text(cfg.model_dump_json(indent=2))
        _write_json(out / "dagger.json", {"demos": str(demos) if demos is not None else None, "rounds": rounds})
        if demos is not None:
            obs, actions, episodes = load_demos(demos, cfg.bc.successes_only)
            gears = np.zeros(len(actions), np.int8)  # demonstrations carry no gear labels
            fit_actor(model, obs, actions, cfg, progress)
        learner.save(out / "rounds" / "model-r0.zip")
    # How rl:PATH loads a round's model: its algorithm and what it observes.
    meta = {"algo": cfg.algo, "config": {"lidar": cfg.lidar.model_dump()}}
    (out / "rounds" / "train.json").write_text(json.dumps(meta))
    try:
        state = (obs, actions, gears, log, expert_calls, episodes)
        obs, actions, gears, log, expert_calls = _rounds(
            cfg, learner, grid, out, rounds, state, t0, progress, make_expert
        )
    except KeyboardInterrupt:
        done = len((load_progress(out) or {"log": []})["log"])
        raise KeyboardInterrupt(
            f"{done} DAgger round(s) finished in {out}; go on with: mirrorpark train-rl --resume {out}"
        ) from None
    wall = time.perf_counter() - t0
    plot_rounds(log, out / "learning_curve.png")
    extra = {}
    if cfg.dagger.gear:
        extra["gear_head"] = {"go": list(learner.go), "standing_labelled": int(np.sum(gears != 0))}
    return save_trained(
        learner,
        cfg,
        out,
        "dagger",
        demos,
        episodes,
        len(actions),
        wall,
        rounds=log,
        expert=cfg.dagger.expert,
        expert_calls=expert_calls,
        epochs_per_fit=cfg.bc.epochs,
        action_error_on_all=round(action_error(model, obs, actions), 6),
        **extra,
    )


def plot_rounds(log: list[dict[str, Any]], path: str | Path) -> Path:
    """DAgger's learning curve, a point per round: how its mixed rollouts ended (the expert's
    action taken with probability beta), and the learner's action error on the round's new
    states before it was fitted to them (how far the learner strayed from the expert)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    r = [x["round"] for x in log]
    share = lambda key: [100 * x[key] / max(x["episodes"], 1) for x in log]  # noqa: E731
    fig, ax = plt.subplots(1, 2, figsize=(9, 3.2))
    ax[0].plot(r, share("parked"), marker="o", label="parked")
    ax[0].plot(r, share("collided"), marker="o", label="collided")
    ax[0].set(xlabel="DAgger round", ylabel="rollouts [%]", title="mixed rollouts", ylim=(-2, 102), xticks=r)
    ax[0].legend()
    err = [(x["round"], x["error_on_new_before_fit"]) for x in log if x["error_on_new_before_fit"] is not None]
    ax[1].plot([e[0] for e in err], [e[1] for e in err], marker="o")
    ax[1].set(xlabel="DAgger round", ylabel="mean squared action error", title="learner on the new states", xticks=r)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return Path(path)


def _rounds(
    cfg: RLConfig, learner, grid, out: Path, rounds: int, state: tuple, t0: float, progress: bool, make_expert
) -> tuple:
    """Rounds ``len(log) + 1`` .. ``rounds`` from ``state`` = (obs, actions, gears, log,
    expert calls, episodes), each saved as it finishes; the state after the last.
    ``learner``: the model, or a ``GearedModel`` around it whose head is fitted too."""
    from tqdm import tqdm

    obs, actions, gears, log, expert_calls, episodes = state
    model = getattr(learner, "model", learner)
    dc = cfg.dagger
    workers = dc.workers or os.cpu_count() or 1
    env_cfg = env_config(cfg)
    types = tuple(cfg.parking_types)
    ctx = mp.get_context("spawn")  # the parent may hold a GPU: children start clean
    with ctx.Pool(workers) as pool:
        for r in range(len(log) + 1, rounds + 1):
            beta = dc.beta0 * dc.beta_decay ** (r - 1)
            if not len(actions) and beta < 1.0:
                raise ValueError("dagger: with no --demos the first round must be the expert's (dagger.beta0: 1.0)")
            model_path = out / "rounds" / f"model-r{r - 1}.zip"
            cases = training_cases(grid, dc.cases_per_round, 10_000 + cfg.seed * 100 + r, types)
            seed = cfg.seed * 1000 + r * 100
            jobs = [
                (model_path, dc, cases[w::workers], beta, seed + w, env_cfg, make_expert)
                for w in range(workers)
                if cases[w::workers]
            ]
            bar = dict(total=len(jobs), desc=f"DAgger round {r}", disable=not progress)
            done = list(tqdm(pool.imap(_worker, jobs), **bar))
            parts = [p for p in done if len(p[1])]
            new_obs = {k: np.concatenate([p[0][k] for p in parts]) for k in parts[0][0]}
            new_actions = np.concatenate([p[1] for p in parts])
            new_gears = np.concatenate([p[2] for p in parts])
            counts = {k: sum(p[3][k] for p in done) for k in done[0][3]}
            expert_calls += sum(p[4] for p in done)
            err = round(action_error(model, new_obs, new_actions), 6) if len(actions) else None
            obs = {k: np.concatenate([obs[k], new_obs[k]]) if obs else new_obs[k] for k in new_obs}
            actions = np.concatenate([actions, new_actions])
            gears = np.concatenate([gears, new_gears])
            fit_actor(model, obs, actions, cfg, progress)
            if learner is not model:
                fit_head(model, learner.head, obs, gears, cfg, progress)
                learner.go = go_accels(obs, actions, gears)
            log.append(
                {
                    "round": r,
                    "beta": beta,
                    "labelled": int(len(new_actions)),
                    "error_on_new_before_fit": err,  # how far the learner strayed (None in a first round)
                    **counts,
                    "wall_s": round(time.perf_counter() - t0, 1),  # of this run (a resumed run: of its part)
                }
            )
            save_round(out, learner, obs, actions, gears, log, expert_calls, episodes)
            if progress:
                print(log[-1], flush=True)
    return obs, actions, gears, log, expert_calls
