"""A Markdown report with the paper's figures (Figs. 20, 21, 23, 24, 25) and tables."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from .metrics import TYPES, headline, odd_size, summary

SLOT = {"parallel": "slot_length", "reverse": "slot_width", "angle": "slot_width"}


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _save(fig, path: Path) -> Path:
    import matplotlib.pyplot as plt

    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _rate_by(df: pd.DataFrame, col: str) -> pd.Series:
    return df.assign(success=df["success"].fillna(False).astype(float)).groupby(col)["success"].mean()


def fig_success_by_type(df, planners, out: Path) -> Path:
    plt = _plt()
    fig, ax = plt.subplots(figsize=(6, 3.5))
    w = 0.8 / max(len(planners), 1)
    for j, p in enumerate(planners):
        d = df[df["planner"] == p]
        r = _rate_by(d, "parking_type")
        vals = [100 * r.get(t, np.nan) for t in TYPES]
        ax.bar(np.arange(3) + j * w, vals, w, label=p)
    ax.set_xticks(np.arange(3) + w * (len(planners) - 1) / 2, TYPES)
    ax.set_ylabel("success rate [%]")
    ax.set_ylim(0, 100)
    ax.legend()
    ax.set_title("Success rate per parking type (paper Fig. 20)")
    return _save(fig, out / "success_by_type.png")


def _per_type_lines(df, planners, col, out: Path, name: str, title: str, xlabel_fn) -> Path:
    plt = _plt()
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


def fig_odd(df, planners, t: str, out: Path, sizes) -> Path:
    plt = _plt()
    fig, axes = plt.subplots(1, len(planners), figsize=(5.5 * len(planners), 4), squeeze=False)
    for ax, p in zip(axes[0], planners):
        d = df[(df["planner"] == p) & (df["parking_type"] == t)]
        ok = d["success"].fillna(False).astype(bool)
        x = d[SLOT[t]] + 0.02 * d["theta0_deg"] / 90.0  # theta0 spreads the points of one slot size
        ax.scatter(x[ok], d["y0"][ok], s=10, c="tab:green", label="success")
        ax.scatter(x[~ok], d["y0"][~ok], s=10, c="tab:red", marker="x", label="failure")
        ax.set_xlabel(f"{SLOT[t].replace('_', ' ')} [m] (offset by theta0)")
        ax.set_ylabel("y0 [m]")
        ax.set_title(f"{p}: ODD {sizes.get(p, {}).get(t, 0)} cells")
        ax.legend(fontsize=7)
    fig.suptitle(f"{t}: results and ODD (paper Fig. 24)")
    return _save(fig, out / f"odd_{t}.png")


def fig_efficiency(df, planners, out: Path) -> Path:
    plt = _plt()
    fig, axes = plt.subplots(1, 2, figsize=(11, 3.5))
    ok = df[df["success"].fillna(False).astype(bool)]
    for ax, col, label in (
        (axes[0], "switches", "direction switches"),
        (axes[1], "parking_time_s", "parking time [s]"),
    ):
        data, labels = [], []
        for t in TYPES:
            for p in planners:
                v = ok.loc[(ok["planner"] == p) & (ok["parking_type"] == t), col].dropna().values
                data.append(v if len(v) else [np.nan])
                labels.append(f"{t}\n{p}")
        ax.boxplot(data, tick_labels=labels)
        ax.set_ylabel(label)
        ax.tick_params(axis="x", labelsize=7)
    fig.suptitle("Completion efficiency over successful episodes (paper Fig. 25)")
    return _save(fig, out / "efficiency.png")


def fig_plan_time(df, planners, out: Path) -> Path:
    plt = _plt()
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


def _fmt(v, pct=False) -> str:
    if v is None or (isinstance(v, float) and np.isnan(v)):
        return "n/a"
    return f"{v:+.1f} %" if pct else f"{v:.3g}"


def write_report(df: pd.DataFrame, out: str | Path, baseline: str | None = None) -> Path:
    """Figures and ``report.md`` in ``out``; returns the report's path."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    if "y1" not in df:
        df = df.assign(y1=df["road_width"] - df["y0"])
    planners = sorted(df["planner"].unique())
    if baseline is None:  # the paper compares against its search-based baseline
        baseline = "hybrid-astar" if "hybrid-astar" in planners else None
    main = "mirror" if "mirror" in planners else planners[0]
    figs = [fig_success_by_type(df, planners, out)]
    figs.append(
        _per_type_lines(
            df,
            planners,
            "road_width",
            out,
            "success_vs_road_width.png",
            "Success vs road width (paper Fig. 21)",
            lambda t: "road width [m]",
        )
    )
    figs.append(
        _per_type_lines(
            df,
            planners,
            lambda t: SLOT[t],
            out,
            "sensitivity_slot.png",
            "Sensitivity to slot size (paper Fig. 23, column I)",
            lambda t: f"{SLOT[t]} [m]",
        )
    )
    figs.append(
        _per_type_lines(
            df,
            planners,
            "y0",
            out,
            "sensitivity_y0.png",
            "Sensitivity to the distance to the slot y0 (Fig. 23, II)",
            lambda t: "y0 [m]",
        )
    )
    figs.append(
        _per_type_lines(
            df,
            planners,
            "y1",
            out,
            "sensitivity_y1.png",
            "Sensitivity to the distance to the road boundary y1 (Fig. 23, III)",
            lambda t: "y1 [m]",
        )
    )
    sizes = odd_size(df)
    figs += [fig_odd(df, planners, t, out, sizes) for t in TYPES if (df["parking_type"] == t).any()]
    figs.append(fig_efficiency(df, planners, out))
    figs.append(fig_plan_time(df, planners, out))

    lines = ["# MirrorPark evaluation report", ""]
    per_type = ", ".join(f"{t}: {df[df.parking_type == t].case_id.nunique()}" for t in TYPES)
    lines += [
        f"Cases: {df['case_id'].nunique()} ({per_type}); planners: {', '.join(planners)}.",
        "",
    ]
    lines += [
        "## Summary",
        "",
        "| planner | cases | success all | parallel | reverse | angle | switches | parking time [s] | plan ms median"
        " | p95 | setup ms | ODD cells |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for p in planners:
        s = summary(df, p)
        r = s["success_rate"]
        pct = lambda v: "n/a" if v is None else f"{100 * v:.1f} %"  # noqa: E731
        lines.append(
            f"| {p} | {s['cases']} | {pct(r['all'])} | {pct(r['parallel'])} | {pct(r['reverse'])} | {pct(r['angle'])}"
            " | "
            f"{_fmt(s['mean_switches'])} | {_fmt(s['mean_parking_time_s'])} | {_fmt(s['plan_time_ms']['median'])} | "
            f"{_fmt(s['plan_time_ms']['p95'])} | {_fmt(s['setup_ms']['median'])} | {sizes.get(p, {}).get('all', 0)} |"
        )
    lines += [
        "",
        "Plan ms: per planning call, pooled. Setup ms: median per episode of the policy's "
        "preparation at reset (what depends on the slot alone), not counted in plan ms.",
    ]
    lines += [
        "",
        f"## The paper's headline comparisons ({main} vs {baseline or 'no baseline in these results'})",
        "",
        "| measure | paper | ours |",
        "|---|---|---|",
    ]
    for h in headline(df, main, baseline):
        paper = f"{h['paper']:+.1f} %" if h["relative"] else f"{h['paper']:g}"
        lines.append(f"| {h['measure']} | {paper} | {_fmt(h['ours'], h['relative'])} |")
    lines += [
        "",
        "Relative changes compare the two planners on the cases both ran. The paper's planning time "
        "is a mean on an i7-9750H with Gurobi; ours is the pooled mean of every planning call here.",
        "",
    ]
    failures = df[~df["success"].fillna(False).astype(bool)]
    if len(failures):
        lines += ["## Failures by first failing criterion", "", "| planner | criterion | cases |", "|---|---|---|"]
        for (p, c), n in failures.groupby(["planner", failures["failed_criterion"].fillna("none")]).size().items():
            lines.append(f"| {p} | {c} | {n} |")
        lines.append("")
    lines += ["## Figures", ""]
    lines += [f"![{f.stem}]({f.name})" for f in figs]
    path = out / "report.md"
    path.write_text("\n".join(lines) + "\n")
    return path
