"""Planners on perturbation ladders (``mirrorpark robustness``): each level a resumable run
per planner, then one table and one figure per ladder, every rate with its 95 % interval.

A ladder (``configs/robustness.yaml``) is a list of perturbations of rising strength above
the unperturbed level, which every ladder shares and which runs exactly as ``evaluate``
does. Level ``L`` of a run in ``OUT`` lands in ``OUT/levels/L/`` (one folder per level, all
its planners in it), so a stopped run resumes level by level and case by case.
"""

from __future__ import annotations

import math
import sys
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from mirrorpark_env.config import PERTURB_PRESETS, PerturbConfig, default_config_path, perturb_preset, read_yaml
from mirrorpark_env.config import validate as validate_config

from .compare import wilson
from .figures import pyplot
from .perturbations import of_folder
from .runner import evaluate
from .store import REQUIRED, read_results

NONE = "none"  # the unperturbed level, shared by every ladder


@dataclass(frozen=True)
class Level:
    """One rung: its ladder, its rank on it (0: unperturbed) and its perturbation."""

    ladder: str
    rank: int
    perturb: PerturbConfig | None

    @property
    def name(self) -> str:
        return NONE if self.perturb is None else self.perturb.name


def load_ladders(path: str | Path | None = None) -> dict[str, list[Level]]:
    """The ladders of ``path`` (default ``configs/robustness.yaml``), each from the unperturbed
    level up; ``ValueError`` naming a bad level or a level name used twice."""
    source = Path(path) if path else default_config_path("robustness.yaml")
    data = read_yaml(source)
    out: dict[str, list[Level]] = {}
    seen: dict[str, str] = {}
    for ladder, items in data.items():
        if not isinstance(items, list) or not items:
            raise ValueError(f"{source.name}: {ladder}: expected a list of perturbations")
        levels = [Level(ladder, 0, None)]
        for k, item in enumerate(items, 1):
            where = f"{source.name}: {ladder}[{k}]"
            cfg = perturb_preset(item) if isinstance(item, str) else validate_config(PerturbConfig, item, where)
            if cfg.name in seen or cfg.name == NONE:
                raise ValueError(f"{where}: level name {cfg.name!r} is used twice (also in {seen.get(cfg.name, NONE)})")
            seen[cfg.name] = ladder
            levels.append(Level(ladder, k, cfg))
        out[ladder] = levels
    return out


def chosen(ladders: dict[str, list[Level]], names: Iterable[str]) -> dict[str, list[Level]]:
    """The ladders named (``all``: every one); ``ValueError`` naming the ladders there are."""
    names = list(names)
    if "all" in names:
        return ladders
    unknown = [n for n in names if n not in ladders]
    if unknown:
        raise ValueError(f"--ladder: unknown {unknown}; allowed: {[*ladders, 'all']}")
    return {n: ladders[n] for n in dict.fromkeys(names)}


def run(
    planners: list[str],
    cases: list,
    ladders: dict[str, list[Level]],
    out: Path,
    workers: int | None = None,
    progress: bool = True,
    mixed_code: bool = False,
    call_limit_s: float | None = None,
) -> None:
    """Every level of ``ladders`` (the unperturbed one once) for every planner, into
    ``out/levels/<level>/``; finished cases are kept, as ``evaluate`` keeps them."""
    todo = {lev.name: lev for levels in ladders.values() for lev in levels}
    for i, lev in enumerate(todo.values(), 1):
        for planner in planners:
            if progress:
                print(f"level {i}/{len(todo)} {lev.name}: {planner}", file=sys.stderr)
            evaluate(
                planner,
                cases,
                out / "levels" / lev.name,
                workers=workers,
                progress=progress,
                mixed_code=mixed_code,
                call_limit_s=call_limit_s,
                perturb=lev.perturb,
            )


def table(out: Path, planners: list[str], ladders: dict[str, list[Level]], case_ids: set[str]) -> pd.DataFrame:
    """Per ladder, level and planner over the cases run: success with its Wilson interval,
    collisions, and over parked cases the mean switches and parking time; planning time per
    call (median and p95)."""
    rows = []
    for ladder, levels in ladders.items():
        for lev in levels:
            folder = out / "levels" / lev.name
            if of_folder(folder) != lev.perturb:
                raise ValueError(f"{folder}: ran under another perturbation than level {lev.name!r} names")
            df = read_results([folder], REQUIRED)
            for planner in planners:
                d = df[(df["planner"] == planner) & df["case_id"].isin(case_ids)]
                rows.append({"ladder": ladder, "rank": lev.rank, "level": lev.name, "planner": planner, **_stats(d)})
    return pd.DataFrame(rows)


def _stats(d: pd.DataFrame) -> dict:
    n = len(d)
    ok = d["success"].fillna(False).astype(bool) if n else pd.Series(dtype=bool)
    k = int(ok.sum())
    lo, hi = wilson(k, n)
    times = np.concatenate([np.asarray(t, float) for t in d["plan_times_ms"].dropna()] or [np.empty(0)]) if n else []
    hit = d["collision"].fillna(False).astype(bool) if n else pd.Series(dtype=bool)
    return {
        "cases": n,
        "success": k / n if n else math.nan,
        "success_lo": lo,
        "success_hi": hi,
        "collisions": int(hit.sum()),
        "collision_rate": float(hit.mean()) if n else math.nan,
        "switches": float(d["switches"][ok].mean()) if k else math.nan,
        "parking_time_s": float(d["parking_time_s"][ok].mean()) if k else math.nan,
        "plan_ms_median": float(np.median(times)) if len(times) else math.nan,
        "plan_ms_p95": float(np.percentile(times, 95)) if len(times) else math.nan,
    }


def markdown(df: pd.DataFrame) -> str:
    """One Markdown table per ladder."""
    parts = []
    for ladder, d in df.groupby("ladder", sort=False):
        parts += [
            f"## {ladder}",
            "",
            "| level | planner | cases | success [95 % CI] | collisions | switches | parking time [s] "
            "| plan ms median / p95 |",
            "|---|---|---:|---|---:|---:|---:|---|",
        ]
        for r in d.itertuples():
            parts.append(
                f"| {r.level} | {r.planner} | {r.cases} | {100 * r.success:.1f} % [{100 * r.success_lo:.1f}, "
                f"{100 * r.success_hi:.1f}] | {r.collisions} | {_num(r.switches, 2)} | {_num(r.parking_time_s, 1)} "
                f"| {_num(r.plan_ms_median, 1)} / {_num(r.plan_ms_p95, 1)} |"
            )
        parts.append("")
    return "\n".join(parts)


def _num(x: float, digits: int) -> str:
    return "–" if x != x else f"{x:.{digits}f}"


def figure(df: pd.DataFrame, ladder: str, path: Path) -> Path:
    """Success (with its interval) and collision rate per level of one ladder, a line per planner."""
    plt = pyplot()
    d = df[df["ladder"] == ladder]
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(10, 3.6))
    for planner, p in d.groupby("planner", sort=False):
        p = p.sort_values("rank")
        err = np.clip(np.vstack([p["success"] - p["success_lo"], p["success_hi"] - p["success"]]), 0, None) * 100
        ax.errorbar(p["rank"], 100 * p["success"], yerr=err, marker="o", capsize=3, label=planner)
        bx.plot(p["rank"], 100 * p["collision_rate"], marker="o", label=planner)
    levels = d.drop_duplicates("rank").sort_values("rank")
    for a, title in ((ax, "success [%]"), (bx, "collisions [% of cases]")):
        a.set_xticks(levels["rank"], levels["level"], rotation=30, ha="right")
        a.set_title(title)
        a.grid(alpha=0.3)
    ax.set_ylim(0, 101)
    ax.legend(fontsize=8)
    fig.suptitle(f"ladder: {ladder}")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def write(df: pd.DataFrame, out: Path) -> Path:
    """``out/robustness.md`` (tables and figures), ``robustness.csv`` and ``<ladder>.png``."""
    out.mkdir(parents=True, exist_ok=True)
    df.to_csv(out / "robustness.csv", index=False)
    figs = [figure(df, ladder, out / f"{ladder}.png") for ladder in df["ladder"].unique()]
    body = markdown(df)
    for f in figs:
        body = body.replace(f"## {f.stem}\n", f"## {f.stem}\n\n![{f.stem}]({f.name})\n", 1)
    md = out / "robustness.md"
    md.write_text("# Robustness\n\n" + body)
    return md


__all__ = ["NONE", "PERTURB_PRESETS", "Level", "chosen", "load_ladders", "markdown", "run", "table", "write"]
