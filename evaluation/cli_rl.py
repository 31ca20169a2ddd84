"""``mirrorpark train-rl``: the learned policies' training (``planners/rl/``), from the command line."""

from __future__ import annotations

import argparse
import json
from collections.abc import Callable
from pathlib import Path

from mirrorpark_env.config import PARKING_TYPES

from .registry import make_policy


def add_train_rl(sub, positive_int: Callable[[str], int]) -> None:
    """The ``train-rl`` subcommand and its arguments."""
    t = sub.add_parser("train-rl", help="train the RL baseline (SAC/TQC + HER); needs the rl extra")
    t.add_argument("--algo", choices=["sac", "tqc"], default=None, help="default: configs/rl.yaml (sac)")
    t.add_argument("--steps", type=int, default=None, help="environment steps (default: configs/rl.yaml)")
    t.add_argument(
        "--parking-type",
        nargs="+",
        choices=list(PARKING_TYPES),
        default=None,
        dest="parking_types",
        help="train on these types (default: all three)",
    )
    t.add_argument("--config", default=None, help="hyper-parameter YAML (default: configs/rl.yaml)")
    t.add_argument("--no-curriculum", action="store_true", help="draw from all cases from the start")
    t.add_argument("--seed", type=int, default=None)
    t.add_argument("--out", default="results/rl", help="output folder (default: results/rl)")
    t.add_argument(
        "--demos",
        default=None,
        help="behaviour cloning instead of RL: the actor copies this dataset (a mirrorpark collect folder)",
    )
    t.add_argument(
        "--epochs", type=positive_int, default=None, help="behaviour-cloning epochs (default: configs/rl.yaml)"
    )
    t.add_argument(
        "--resume",
        default=None,
        metavar="DIR",
        help="continue the interrupted run in DIR from its last checkpoint (--steps may raise its total; "
        "a DAgger run goes on from its last finished round, and --dagger-rounds may raise their number)",
    )
    t.add_argument(
        "--dagger-rounds",
        type=positive_int,
        default=None,
        help="DAgger rounds with a planner as the expert (the dagger section of --config; "
        "with --demos, after cloning them; without, the first round is the expert's own driving)",
    )
    t.set_defaults(func=cmd_train_rl)


def _rl_config(args: argparse.Namespace):
    """The run's config: a resumed run's own (``--steps`` may raise its total), else
    configs/rl.yaml (or ``--config``) with the flags' overrides."""
    if args.resume:
        from planners.rl.train import resume_config

        cfg = resume_config(args.resume)
        return cfg.model_copy(update={"total_steps": args.steps}) if args.steps is not None else cfg
    from planners.rl.config import load_rl_config

    over = {"algo": args.algo, "total_steps": args.steps, "parking_types": args.parking_types, "seed": args.seed}
    cfg = load_rl_config(args.config, over)
    if args.epochs is not None:
        cfg = cfg.model_copy(update={"bc": cfg.bc.model_copy(update={"epochs": args.epochs})})
    if args.no_curriculum:
        cfg = cfg.model_copy(update={"curriculum": cfg.curriculum.model_copy(update={"enabled": False})})
    return cfg


def cmd_train_rl(args: argparse.Namespace) -> int:
    try:
        import stable_baselines3  # noqa: F401
        import torch  # noqa: F401

        from planners.rl.bc import behaviour_clone
        from planners.rl.dagger import dagger
        from planners.rl.train import train
    except ImportError as err:
        raise ValueError(
            f"train-rl needs the rl extra ({err.name} is missing): pip install torch==2.13.0 && pip install -e '.[rl]'"
        ) from None

    cfg = _rl_config(args)
    if cfg.algo == "tqc":
        try:
            import sb3_contrib  # noqa: F401
        except ImportError:
            raise ValueError("algo tqc needs sb3-contrib (the rl extra): pip install -e '.[rl]'") from None
    out = args.resume or args.out
    if args.resume and (Path(out) / "dagger.json").exists():  # a DAgger run: on from its last round
        run = json.loads((Path(out) / "dagger.json").read_text())
        summary = dagger(
            cfg, run["demos"], out, rounds=args.dagger_rounds or run["rounds"], resume=True, make_expert=make_policy
        )
    elif args.resume:
        summary = train(cfg, out, resume=True)
    elif args.dagger_rounds:
        summary = dagger(cfg, args.demos, out, rounds=args.dagger_rounds, make_expert=make_policy)
    elif args.demos:
        summary = behaviour_clone(cfg, args.demos, out)
    else:
        summary = train(cfg, out)
    print(json.dumps({k: v for k, v in summary.items() if k != "config"}))
    print(f"model: {Path(out) / 'model.zip'}  (evaluate it with --planner rl:{Path(out) / 'model.zip'})")
    return 0
