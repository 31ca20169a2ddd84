"""The report of a run over layouts: a row per layout and planner, and a figure of each.

Written by ``mirrorpark evaluate --layouts`` next to its results: ``layouts.md`` (success,
parking time, switches, path length, planning time per layout and planner; a layout's
slot and whether it is comfortable), ``img/<layout>.png`` (the layout's obstacles,
slot, start and target, and every planner's driven path) and
``trajectories/<layout>-<planner>.csv``: the driven trajectory in TPCAP's form, one row per
0.1 s step, ``t, x, y, theta`` (s, m, m, rad) of the rear axle in the file's own frame
(a recentred layout's shift added back).
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pandas as pd
from matplotlib.patches import Polygon as Patch

from mirrorpark_env.layout import Layout
from mirrorpark_env.vehicle import VehicleParams, footprint

from .compare import markdown
from .figures import pyplot
from .metrics import comfortable
from .schema import with_every_column
from .trajectories import tpcap_table


def _cell(v, fmt: str) -> str:
    return "–" if v is None or (isinstance(v, float) and math.isnan(v)) else format(v, fmt)


def layout_table(df: pd.DataFrame) -> pd.DataFrame:
    """Per planner and layout: the outcome and its measures."""
    df = df.copy()
    df["comfortable"] = comfortable(df) & (df["parking_type"] != "none")
    cols = [
        "layout",
        "planner",
        "parking_type",
        "slot_length",
        "slot_width",
        "comfortable",
        "success",
        "failure_cause",
        "parking_time_s",
        "switches",
        "path_length_m",
        "planning_calls",
        "plan_time_median_ms",
        "planner_status",
    ]
    return df[[c for c in cols if c in df]].sort_values(["layout", "planner"]).reset_index(drop=True)


def summary_lines(df: pd.DataFrame) -> list[str]:
    lines = []
    for planner, d in df.groupby("planner"):
        ok = d["success"].fillna(False).astype(bool)
        comf = comfortable(d) & (d["parking_type"] != "none")
        times = np.concatenate([np.asarray(t, float) for t in d["plan_times_ms"].dropna()] or [np.empty(0)])
        med = f"{np.median(times):.1f} ms" if len(times) else "–"
        lines.append(
            f"- `{planner}`: {int(ok.sum())} of {len(d)} layouts parked; comfortable slots "
            f"{int(ok[comf].sum())} of {int(comf.sum())}; median planning call {med} over {len(times)} calls; "
            f"{int(d['collision'].fillna(False).astype(bool).sum())} collisions."
        )
    return lines


def draw_layout(layout: Layout, rows: pd.DataFrame, path: Path) -> Path:
    """The layout with each planner's driven path (``path_x``/``path_y`` of its rows)."""
    plt = pyplot()

    v = layout.vehicle or VehicleParams.table_ii()
    fig, ax = plt.subplots(figsize=(6.4, 4.8))
    for poly in layout.obstacles:
        ax.add_patch(Patch(poly, closed=True, fc="0.45", ec="0.2", lw=0.8))
    if layout.boundary is not None:
        ax.add_patch(Patch(layout.boundary, closed=True, fill=False, ec="0.2", lw=2.5, label="boundary"))
    if layout.slot is not None:
        c = layout.slot.corners
        ax.add_patch(Patch(c, closed=True, fill=False, ec="tab:orange", lw=1.2))
        e = layout.slot.entrance
        ax.plot(*np.array([c[e], c[(e + 1) % 4]]).T, color="tab:orange", lw=2.5)
    for pose, style, label in ((layout.start, "-", "start"), (layout.target, "--", "target")):
        fp = footprint(v, *pose)
        ax.add_patch(Patch(fp, closed=True, fill=False, ec="k", ls=style, lw=1.0, label=label))
    for _, r in rows.iterrows():
        if isinstance(r.get("path_x"), (list, np.ndarray)) and len(r["path_x"]):
            mark = "parked" if r["success"] else "not parked"
            ax.plot(r["path_x"], r["path_y"], lw=1.2, label=f"{r['planner']} ({mark})")
    ax.set_aspect("equal")
    shapes = [*layout.obstacles, *([layout.boundary] if layout.boundary is not None else [])]
    xs = np.concatenate([np.asarray(p)[:, 0] for p in shapes] + [[layout.start[0], layout.target[0]]])
    ys = np.concatenate([np.asarray(p)[:, 1] for p in shapes] + [[layout.start[1], layout.target[1]]])
    cx, cy = 0.5 * (layout.start[0] + layout.target[0]), 0.5 * (layout.start[1] + layout.target[1])
    half = 12.0
    ax.set_xlim(max(xs.min(), cx - half) - 0.5, min(xs.max(), cx + half) + 0.5)
    ax.set_ylim(max(ys.min(), cy - half) - 0.5, min(ys.max(), cy + half) + 0.5)
    frame = "" if layout.origin == (0.0, 0.0) else f" (frame origin at {layout.origin[0]:.0f}, {layout.origin[1]:.0f})"
    ax.set_title(f"{layout.name}{frame}", fontsize=9)
    ax.legend(fontsize=7, loc="best")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(fig)
    return path


def write_trajectory(row: pd.Series, layout: Layout, path: Path) -> Path | None:
    """The row's driven trajectory as TPCAP's four columns (t, x, y, theta) in the layout
    file's frame; None for a row without one (an error)."""
    t = row.get("path_t")
    if not isinstance(t, (list, np.ndarray)) or not len(t):
        return None
    path.parent.mkdir(parents=True, exist_ok=True)
    tpcap_table(row, layout.origin).to_csv(path, index=False, float_format="%.6f")
    return path


def _file_stem(name: str, used: set[str]) -> str:
    """A file name for a layout's figure inside the report's folder, whatever its name holds
    (``../x``, ``a/b``, ``#``): letters, digits, ``.``, ``-`` and ``_`` only, unique among ``used``."""
    stem = re.sub(r"[^A-Za-z0-9._-]+", "_", name).strip("._") or "layout"
    unique, n = stem, 1
    while unique in used:
        n += 1
        unique = f"{stem}_{n}"
    used.add(unique)
    return unique


def write_layout_report(df: pd.DataFrame, layouts: list[Layout], out: str | Path) -> Path:
    """``out/layouts.md`` and ``out/img/<layout>.png`` for the rows of ``layouts``."""
    out = Path(out)
    names = {lay.name for lay in layouts}
    df = with_every_column(df[df["case_id"].isin(names)])  # a run whose every case errored has no outcomes
    table = layout_table(df)
    lines = ["# Layouts", "", *summary_lines(df), ""]
    show = table.copy()
    for c, f in (("slot_length", ".2f"), ("slot_width", ".2f"), ("parking_time_s", ".1f"), ("path_length_m", ".2f")):
        if c in show:
            show[c] = [_cell(v, f) for v in show[c]]
    if "failure_cause" in show:
        show["failure_cause"] = [v if isinstance(v, str) else "–" for v in show["failure_cause"]]
    if "plan_time_median_ms" in show:
        show["plan_time_median_ms"] = [_cell(v, ".1f") for v in show["plan_time_median_ms"]]
    lines += [markdown(show), ""]
    used: set[str] = set()
    for lay in layouts:
        rows = df[df["case_id"] == lay.name]
        stem = _file_stem(lay.name, used)
        img = draw_layout(lay, rows, out / "img" / f"{stem}.png")
        lines.append(f"![{lay.name}](img/{img.name})")
        for _, r in rows.iterrows():
            write_trajectory(r, lay, out / "trajectories" / f"{stem}-{_file_stem(str(r['planner']), set())}.csv")
    path = out / "layouts.md"
    path.write_text("\n".join(lines) + "\n")
    return path
