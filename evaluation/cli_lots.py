"""``mirrorpark lots``: generated parking lots (``mirrorpark_env.lots``) written as layout files."""

from __future__ import annotations

import argparse
from pathlib import Path

from mirrorpark_env.layout_io import write_layout
from mirrorpark_env.lots import generate_lot
from mirrorpark_env.vehicle import vehicle_named


def add_lots(sub, positive_int) -> None:
    p = sub.add_parser("lots", help="write generated parking lots (seeded, levels 1-4) as layout files")
    p.add_argument("--seed", type=int, default=0, help="the first lot's seed (then seed + 1, ...)")
    p.add_argument("--count", type=positive_int, default=10, help="how many lots (default 10)")
    p.add_argument("--level", type=int, default=2, choices=(1, 2, 3, 4), help="difficulty, 1 (easy) to 4 (default 2)")
    p.add_argument("--vehicle", default="paper", help="the car the gaps are drawn for: paper, tpcap or a YAML file")
    p.add_argument("--out", required=True, help="folder for the files (lot-L<level>-<seed>.json)")
    p.set_defaults(func=cmd_lots)


def cmd_lots(args: argparse.Namespace) -> int:

    if args.seed < 0:
        raise ValueError(f"--seed: a whole number >= 0, got {args.seed}")
    car = vehicle_named(args.vehicle)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    for seed in range(args.seed, args.seed + args.count):
        lot = generate_lot(seed, args.level, car)
        write_layout(lot, out / f"{lot.name}.json")
    print(f"wrote {args.count} level-{args.level} lots to {out} (seeds {args.seed}-{args.seed + args.count - 1})")
    return 0
