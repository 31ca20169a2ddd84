"""The report's figures: the paper's Figs. 20, 21, 23, 24, 25, planning time and clearance."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from .metrics import TYPES
from .schema import column_label

SLOT = {"parallel": "slot_length", "reverse": "slot_width", "angle": "slot_width"}


def pyplot():
    """matplotlib's pyplot on the file-writing Agg backend, imported when a figure is drawn:
    importing evaluation must not change the backend of a notebook that imports it."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _save(fig, path: Path) -> Path:
    plt = pyplot()
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _rate_by(df: pd.DataFrame, col: str) -> pd.Series:
    return df.assign(success=df["success"].fillna(False).astype(float)).groupby(col)["success"].mean()


def fig_success_by_type(df, planners, out: Path) -> Path:
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(7.2, 3.5))
    w = 0.8 / max(len(planners), 1)
    for j, p in enumerate(planners):
        d = df[df["planner"] == p]
        r = _rate_by(d, "parking_type")
        vals = [100 * r.get(t, np.nan) for t in TYPES]
        ax.bar(np.arange(3) + j * w, vals, w, label=p)
    ax.set_xticks(np.arange(3) + w * (len(planners) - 1) / 2, TYPES)
    ax.set_ylabel("success rate [%]")
    ax.set_ylim(0, 100)
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8)  # beside the bars, not over them
    ax.set_title("Success rate per parking type (paper Fig. 20)")
    return _save(fig, out / "success_by_type.png")


def _per_type_lines(df, planners, col, out: Path, name: str, title: str, xlabel_fn) -> Path:
    plt = pyplot()
    fig, axes = plt.subplots(1, 3, figsize=(12, 3.3), sharey=True)
    for ax, t in zip(axes, TYPES):
        for p in planners:
            d = df[(df["planner"] == p) & (df["parking_type"] == t)]
            c = col(t) if callable(col) else col
            if len(d):
                r = _rate_by(d, c)
                ax.plot(r.index, 100 * r.values, "o-", ms=3, label=p)
        ax.set_title(t)
        ax.set_xlabel(xlabel_fn(t))
        ax.set_ylim(-3, 103)
    axes[0].set_ylabel("success rate [%]")
    axes[0].legend()
    fig.suptitle(title)
    return _save(fig, out / name)


def fig_odd(cells: pd.DataFrame, planners, t: str, out: Path, sizes) -> Path:
    """The paper's Fig. 24 from the ODD cells: per slot size and y0, the share of start
    headings theta0 whose cell (road widths pooled) parks in >= 95 % of its runs."""
    plt = pyplot()
    fig, axes = plt.subplots(1, len(planners), figsize=(5.5 * len(planners), 4), squeeze=False)
    slot = SLOT[t]
    for ax, p in zip(axes[0], planners):
        c = cells[(cells["planner"] == p) & (cells["parking_type"] == t)]
        if not len(c):
            ax.set_axis_off()
            continue
        share = c.groupby([slot, "y0"])["in_odd"].mean().unstack(slot)  # rows y0, columns slot size
        xs, ys = share.columns.to_numpy(float), share.index.to_numpy(float)
        mesh = ax.pcolormesh(_edges(xs), _edges(ys), share.to_numpy(float), vmin=0, vmax=1, cmap="viridis")
        ax.set_xlabel(column_label(slot))
        ax.set_ylabel(column_label("y0"))
        ax.set_title(f"{p}: {sizes.get(p, {}).get(t, 0)} ODD cells")
    fig.colorbar(mesh, ax=axes[0].tolist(), label="share of theta0 in the ODD")
    fig.suptitle(f"{t}: ODD (paper Fig. 24; cells pool road widths)")
    fig.savefig(out / f"odd_{t}.png", dpi=110)
    plt.close(fig)
    return out / f"odd_{t}.png"


def _edges(v: np.ndarray) -> np.ndarray:
    """Cell edges around sorted centres (pcolormesh)."""
    if len(v) == 1:
        return np.array([v[0] - 0.05, v[0] + 0.05])
    mid = 0.5 * (v[1:] + v[:-1])
    return np.concatenate([[2 * v[0] - mid[0]], mid, [2 * v[-1] - mid[-1]]])


def fig_clearance(df, planners, out: Path) -> Path:
    """Each episode's closest approach to an obstacle, and how fast the car was going there."""
    plt = pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(11, 3.5))
    bins = np.arange(0, 21)  # [cm]
    for p in planners:
        d = df[(df["planner"] == p) & df["min_clearance_m"].notna()]
        gap = 100 * d["min_clearance_m"].clip(lower=0).to_numpy(float)
        speed = d["speed_at_min_clearance"].to_numpy(float)
        axes[0].hist(gap, bins=np.linspace(0, 50, 51), histtype="step", lw=1.5, label=p)
        which = np.digitize(gap, bins) - 1
        med = [np.median(speed[which == k]) if (which == k).any() else np.nan for k in range(len(bins) - 1)]
        axes[1].plot(bins[:-1] + 0.5, med, "o-", ms=3, label=p)
    axes[0].set_xlabel("minimum clearance in the episode [cm]")
    axes[0].set_ylabel("episodes")
    axes[0].legend()
    axes[1].set_xlabel("minimum clearance [cm] (1 cm bins)")
    axes[1].set_ylabel("median speed there [m/s]")
    axes[1].legend()
    fig.suptitle("Safety margin: closest approach to any obstacle (separating-axis gap)")
    return _save(fig, out / "clearance.png")


def fig_efficiency(df, planners, out: Path) -> Path:
    plt = pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(11, 3.5))
    ok = df[df["success"].fillna(False).astype(bool)]
    for ax, col, label in (
        (axes[0], "switches", "direction switches"),
        (axes[1], "parking_time_s", column_label("parking_time_s")),
    ):
        data, labels = [], []
        for t in TYPES:
            for p in planners:
                v = ok.loc[(ok["planner"] == p) & (ok["parking_type"] == t), col].dropna().values
                data.append(v if len(v) else [np.nan])
                labels.append(f"{p} ({t})")
        ax.boxplot(data, tick_labels=labels)
        ax.set_ylabel(label)
        ax.tick_params(axis="x", labelsize=7, labelrotation=35)  # one label per box: upright they overlap
        for tick in ax.get_xticklabels():
            tick.set_horizontalalignment("right")
    fig.suptitle("Completion efficiency over successful episodes (paper Fig. 25)")
    return _save(fig, out / "efficiency.png")


def fig_plan_time(df, planners, out: Path) -> Path:
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(6, 3.5))
    for p in planners:
        d = df[df["planner"] == p]
        times = [t for ts in d["plan_times_ms"].dropna() for t in (() if ts is None else ts)]
        if times:
            ax.hist(np.log10(np.maximum(times, 1e-3)), bins=40, alpha=0.6, label=p)
    ax.axvline(np.log10(74.0), color="k", ls="--", lw=1, label="paper mean (74 ms)")
    ax.set_xlabel("log10 planning time per call [ms]")
    ax.set_ylabel("calls")
    ax.legend()
    ax.set_title("Planning time per call")
    return _save(fig, out / "plan_time.png")
