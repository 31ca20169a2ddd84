"""The ``mirrorpark`` command line."""

from __future__ import annotations

import argparse
import json
import os
import signal
import sys
import warnings
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from mirrorpark_env.config import PARKING_TYPES, GridConfig, default_grid, load
from mirrorpark_env.grid import Grid

from . import registry
from .call_limit import CALL_LIMIT_S
from .cases import selected
from .cli_bench import add_bench
from .cli_compare import add_compare
from .cli_export import add_export
from .cli_lots import add_lots
from .cli_rl import add_train_rl
from .cli_robustness import add_robustness
from .collect import collect
from .demo import run_demo
from .diff import compare, format_diff
from .layout_report import write_layout_report
from .metrics import summary
from .mirror_demo import mirror_demo
from .perturbations import resolve
from .registry import MAIN
from .report import write_report
from .runner import WorkerDied, evaluate
from .store import REQUIRED, export_table, read_results


def cmd_grid(args: argparse.Namespace) -> int:

    cfg = load(GridConfig, args.config) if args.config else default_grid()
    counts = Grid.from_config(cfg).counts()
    if args.json:
        print(json.dumps(counts))
    else:
        feasible = counts.pop("feasible")
        for k, v in counts.items():
            print(f"{k:>9}: {v:>6,}  ({feasible[k]:,} with an ISO-compliant final pose)")
    return 0


def cmd_demo(args: argparse.Namespace) -> int:

    for name, path in run_demo(Path(args.out)).items():
        print(f"wrote {path}  ({name})")
    for e in mirror_demo(Path(args.out), tuple(args.types)):
        verdict = "parked" if e.success else "NOT parked"
        print(
            f"mirror planner, {e.case_id}: {verdict}, {e.switches} switches, {e.parking_time_s:.1f} s, "
            f"{e.plans} plans; wrote {e.figure} and {e.animation}"
        )
    return 0


def cmd_evaluate(args: argparse.Namespace) -> int:

    scenarios = selected(args)
    out = Path(args.out)
    if args.export:
        _writable_folder(Path(args.export), "--export")  # before any case runs, not after all of them
    store = evaluate(
        args.planner,
        scenarios,
        out,
        workers=args.workers,
        backend=args.backend,
        ray_address=args.address,
        progress=not args.quiet,
        mixed_code=args.mixed_code,
        trajectories=args.trajectories,
        call_limit_s=args.call_limit,
        perturb=resolve(args.perturb),
    )
    df = read_results([out], REQUIRED)
    ids = {sc.case_id for sc in scenarios}
    df = df[df["case_id"].isin(ids) & (df["planner"] == args.planner)]
    if args.export:
        envs = store.environments()  # every run into this results folder
        print(f"wrote {export_table(df, args.export, args.planner, args.chunk, envs)}", file=sys.stderr)
    s = summary(df, args.planner)
    if args.layouts:
        report = write_layout_report(read_results([out], REQUIRED), scenarios, out)
        if not args.json:
            print(f"{args.planner}: {s['cases']} layouts; report in {report}")
    if args.json:
        print(json.dumps(s))
    elif not args.layouts:
        r = s["success_rate"]
        pct = lambda v: "n/a" if v is None else f"{100 * v:.1f} %"  # noqa: E731
        print(
            f"{args.planner}: {s['cases']} cases, success {pct(r['all'])} (parallel {pct(r['parallel'])}, "
            f"reverse {pct(r['reverse'])}, angle {pct(r['angle'])}); results in {store.parquet}"
        )
    return 0


def _writable_folder(folder: Path, what: str) -> None:
    """Make ``folder`` or refuse, naming ``what``, where it cannot be made or written."""
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise ValueError(f"{what}: cannot create {folder} ({err.strerror})") from None
    if not os.access(folder, os.W_OK):
        raise ValueError(f"{what}: {folder} is not writable")


def cmd_collect(args: argparse.Namespace) -> int:

    path = collect(
        args.planner, selected(args), Path(args.out), args.workers, progress=not args.quiet, mixed_code=args.mixed_code
    )
    print(f"wrote {path} (load it with minari.MinariDataset('{path / 'data'}'))")
    return 0


def cmd_report(args: argparse.Namespace) -> int:

    path = write_report(read_results(args.results, REQUIRED), args.out, baseline=args.baseline, notes=args.notes)
    print(f"wrote {path}")
    return 0


def cmd_diff(args: argparse.Namespace) -> int:

    d = compare(read_results(args.before, REQUIRED), read_results(args.after, REQUIRED), by=args.by)
    if args.json:
        print(json.dumps(d.to_json()))
    else:
        print(format_diff(d, args.list), end="")
    return 0


def cmd_main(args: argparse.Namespace) -> int:
    """The main job: a smoke evaluation of the main planners (registry.MAIN), then the report."""

    scenarios = selected(args)
    out = Path(args.out)
    planners = list(MAIN) if args.planners is None else args.planners
    for p in planners:
        evaluate(
            p,
            scenarios,
            out / p,
            workers=args.workers,
            progress=not args.quiet,
            mixed_code=args.mixed_code,
            call_limit_s=args.call_limit,
        )
    df = read_results([out / p for p in planners], REQUIRED)
    path = write_report(df, out / "report")
    print(f"wrote {path}")
    return 0


def _positive_int(text: str) -> int:
    try:
        n = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number >= 1, got {text!r}") from None
    if n < 1:
        raise argparse.ArgumentTypeError(f"must be >= 1, got {n}")
    return n


def _seconds(text: str) -> float:
    try:
        s = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected seconds >= 0, got {text!r}") from None
    if not s >= 0 or s == float("inf"):
        raise argparse.ArgumentTypeError(f"expected finite seconds >= 0, got {text!r}")
    return s


def call_limit_arg(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--call-limit",
        type=_seconds,
        default=CALL_LIMIT_S,
        metavar="SECONDS",
        help=f"wall-clock safety net per planner call (default {CALL_LIMIT_S:g}; 0: none): a call past it "
        "ends its case as an error row; budgets in work stay the planners' real limit",
    )


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog="mirrorpark", description="MirrorPark: parking planners scored side by side.")
    sub = ap.add_subparsers(dest="command", required=True)
    g = sub.add_parser("grid", help="count the Table III scenario grid")
    g.add_argument("--count", action="store_true", help="print case counts per parking type (the default)")
    g.add_argument("--json", action="store_true", help="print the counts as one JSON object")
    g.add_argument("--config", help="a grid YAML file (default: configs/grid.yaml)")
    g.set_defaults(func=cmd_grid)
    d = sub.add_parser(
        "demo",
        help="render one scene per parking type and a scripted episode to PNG; "
        "drive the mirror planner once per type (Fig. 19-like PNG and a GIF)",
    )
    d.add_argument("--out", default="out/demo", help="output folder (default: out/demo)")
    d.add_argument(
        "--types",
        nargs="+",
        default=list(PARKING_TYPES),
        choices=list(PARKING_TYPES),
        help="parking types the mirror planner drives",
    )
    d.set_defaults(func=cmd_demo)

    def case_args(p: argparse.ArgumentParser) -> None:
        p.add_argument(
            "--sample",
            default="smoke",
            choices=["smoke", "standard", "full"],
            help="grid sample: smoke (30 per type), standard (500 per type), full (70,434)",
        )
        p.add_argument(
            "--cases",
            help="a JSON or CSV file of cases (fields: parking_type, road_width, "
            "slot_length, slot_width, theta0_deg, y0); overrides --sample",
        )
        p.add_argument("--types", nargs="+", choices=list(PARKING_TYPES), help="only these parking types")
        p.add_argument("--workers", type=_positive_int, default=None, help="processes (default: all cores)")
        p.add_argument("--quiet", action="store_true", help="no progress bar")
        p.add_argument(
            "--mixed-code",
            action="store_true",
            help="resume a results folder whose rows came from other code than this "
            "(refused by default: the old rows would pass for the new code's)",
        )

    e = sub.add_parser("evaluate", help="run a planner over grid cases or layouts; resumable")
    e.add_argument(
        "--planner",
        required=True,
        help=f"{', '.join(registry.available())}, or rl:PATH (a model.zip from train-rl; "
        "loading it runs pickled code: name only files you trust)",
    )
    case_args(e)
    e.add_argument(
        "--layouts",
        nargs="+",
        default=None,
        help="layout files or folders (native .yaml/.json, TPCAP .csv) instead of grid cases; "
        "writes OUT/layouts.md and a figure per layout",
    )
    e.add_argument(
        "--vehicle",
        default=None,
        help="with --layouts: the car of every layout, paper, tpcap or a YAML file of vehicle fields "
        "(default: each file's own; TPCAP .csv files: tpcap)",
    )
    e.add_argument(
        "--chunk",
        default=None,
        help="K/N: run only the K-th of N equal slices of the cases (a long run in pieces)",
    )
    e.add_argument(
        "--export",
        default=None,
        help="folder for the run's compact table (the report's columns, Parquet): "
        "<planner>[-chunkK-of-N].parquet, a file small enough to commit",
    )
    e.add_argument(
        "--trajectories",
        action="store_true",
        help="keep each episode's states and commands (for `mirrorpark export --trajectories`; layouts always)",
    )
    call_limit_arg(e)
    e.add_argument(
        "--perturb",
        default=None,
        metavar="NAME|FILE",
        help="run in a perturbed world: mild, moderate, severe or a YAML file of perturbation fields "
        "(docs/robustness.md); verdicts stay on the true state",
    )
    e.add_argument("--backend", default="local", choices=["local", "ray"])
    e.add_argument("--address", default=None, help="Ray cluster address (default: start a local Ray)")
    e.add_argument("--out", default=None, help="results folder (default: results/<planner>-<sample>)")
    e.add_argument("--json", action="store_true", help="end with one JSON summary line")
    e.set_defaults(func=cmd_evaluate)

    c = sub.add_parser("collect", help="record a planner's episodes as a Minari dataset (demonstrations); resumable")
    c.add_argument("--planner", required=True, help="a planner name, as for evaluate")
    case_args(c)
    c.add_argument("--out", required=True, help="folder for the episodes and the dataset")
    c.set_defaults(func=cmd_collect)

    r = sub.add_parser("report", help="write a Markdown report with figures from result folders or files")
    r.add_argument("results", nargs="+", help="results folders, .parquet or .jsonl files")
    r.add_argument("--out", required=True, help="a folder (report.md and figures), or a .md file (figures beside it)")
    r.add_argument("--notes", default=None, help="a Markdown file appended to the report (the author's reading)")
    r.add_argument("--baseline", default=None, help="planner to compare against (default: hybrid-astar if present)")
    r.set_defaults(func=cmd_report)

    f = sub.add_parser(
        "diff",
        help="compare two runs over the same cases: rows kept or changed, cases gained and lost, cost",
    )
    f.add_argument("--before", nargs="+", required=True, help="results folders, .parquet or .jsonl files")
    f.add_argument("--after", nargs="+", required=True, help="the same for the other run")
    f.add_argument("--list", type=int, default=10, help="gained and lost cases to list (default 10)")
    f.add_argument("--by", default=None, help="also per value of a case column: parking_type, road_width, y0, ...")
    f.add_argument("--json", action="store_true", help="one JSON object instead of Markdown")
    f.set_defaults(func=cmd_diff)

    m = sub.add_parser(
        "main",
        help="the main job: smoke-evaluate mirror, hybrid-astar and guide-only (or --planners) and write the report",
    )
    case_args(m)
    m.add_argument("--planners", nargs="+", default=None)
    call_limit_arg(m)
    m.add_argument("--out", default="results/main")
    m.set_defaults(func=cmd_main)

    add_bench(sub, _positive_int)
    add_train_rl(sub, _positive_int)
    add_lots(sub, _positive_int)
    add_robustness(sub, _positive_int, _seconds)
    add_compare(sub)
    add_export(sub)
    return ap


@contextmanager
def _one_line_warnings() -> Iterator[None]:
    """Warnings (a damaged results folder, say) as one line each, without source code, while
    a command runs (a caller's own hook is back afterwards)."""

    def show(message, category, filename, lineno, file=None, line=None):
        print(f"mirrorpark: warning: {message}", file=sys.stderr)

    before, warnings.showwarning = warnings.showwarning, show
    try:
        yield
    finally:
        warnings.showwarning = before


@contextmanager
def _stop_on_sigterm() -> Iterator[list[bool]]:
    """Make SIGTERM (``kill``, a scheduler's stop, ``timeout``) stop a run as Ctrl-C does while
    a command runs: without it the process dies at once, and its worker processes run on,
    orphaned, into the case in hand (1.4 s on with cases of 1 s). Yields a flag set when
    SIGTERM came; the caller's handler is back afterwards."""

    came = [False]

    def stop(signum, frame):
        came[0] = True
        raise KeyboardInterrupt

    try:
        before = signal.signal(signal.SIGTERM, stop)
    except ValueError:  # not the main thread: leave SIGTERM as it is
        yield came
        return
    try:
        yield came
    finally:
        signal.signal(signal.SIGTERM, before)


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    if getattr(args, "func", None) is cmd_evaluate and args.out is None:
        args.out = (
            f"results/{args.planner.replace(':', '_').replace('/', '_')}-"
            f"{'layouts' if args.layouts else 'cases' if args.cases else args.sample}"
            + (f"-{Path(args.perturb).stem}" if args.perturb else "")
        )
    with _one_line_warnings(), _stop_on_sigterm() as terminated:
        return _run(args, terminated)


def _run(args: argparse.Namespace, terminated: list[bool]) -> int:
    """The command, its failures as one line and an exit code."""
    try:
        return args.func(args)
    except ValueError as err:  # bad input: one clear line, no traceback
        print(f"mirrorpark: error: {err}", file=sys.stderr)
        return 2
    except OSError as err:  # a path the user gave: missing, a file for a folder, not writable
        where = f"{err.filename}: " if err.filename else ""
        print(f"mirrorpark: error: {where}{err.strerror or err}", file=sys.stderr)
        return 2
    except WorkerDied as err:  # a worker killed or crashed: which case, what is stored
        print(f"mirrorpark: error: {err}", file=sys.stderr)
        return 1
    except KeyboardInterrupt as err:  # Ctrl-C or SIGTERM: what is stored, and how to resume
        what = "terminated" if terminated[0] else "interrupted"
        print(f"mirrorpark: {what}{': ' + str(err) if str(err) else ''}", file=sys.stderr)
        return 143 if terminated[0] else 130


if __name__ == "__main__":
    raise SystemExit(main())
