"""The ``mirrorpark`` command line."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path


def cmd_grid(args: argparse.Namespace) -> int:
    from mirrorpark_env.config import default_grid, load, GridConfig
    from mirrorpark_env.grid import Grid

    cfg = load(GridConfig, args.config) if args.config else default_grid()
    counts = Grid.from_config(cfg).counts()
    if args.json:
        print(json.dumps(counts))
    else:
        for k, v in counts.items():
            print(f"{k:>9}: {v:,}")
    return 0


def cmd_demo(args: argparse.Namespace) -> int:
    from .demo import run_demo

    for name, path in run_demo(Path(args.out)).items():
        print(f"wrote {path}  ({name})")
    return 0


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog="mirrorpark", description="MirrorPark: parking planners scored side by side.")
    sub = ap.add_subparsers(dest="command", required=True)
    g = sub.add_parser("grid", help="count the Table III scenario grid")
    g.add_argument("--count", action="store_true", help="print case counts per parking type (the default)")
    g.add_argument("--json", action="store_true", help="print the counts as one JSON object")
    g.add_argument("--config", help="a grid YAML file (default: configs/grid.yaml)")
    g.set_defaults(func=cmd_grid)
    d = sub.add_parser("demo", help="render one scene per parking type and a scripted episode to PNG")
    d.add_argument("--out", default="out/demo", help="output folder (default: out/demo)")
    d.set_defaults(func=cmd_demo)
    return ap


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return args.func(args)
    except ValueError as err:  # bad input: one clear line, no traceback
        print(f"mirrorpark: error: {err}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    raise SystemExit(main())
