"""Several runs on the same cases in one table, every rate with its 95 % interval, and each
run's differences against a reference paired by case (``mirrorpark compare``).

Rates carry Wilson score intervals (a success rate over 1,500 cases moves by about 2
points of binomial noise). Against the reference, on the cases both ran: the difference in
success with a paired bootstrap interval and McNemar's exact test (on the cases one parks
and the other does not), and, over the cases both park, the mean differences in switches
and parking time with paired bootstrap intervals. The bootstrap is seeded: the same runs
give the same table.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
from scipy.stats import binomtest

from .figures import pyplot
from .metrics import comfortable, far_out

Z = 1.959963984540054  # the normal's 97.5 % point
RESAMPLES = 2000


def wilson(k: int, n: int) -> tuple[float, float]:
    """The 95 % Wilson score interval of a rate of ``k`` in ``n`` (nan, nan for n = 0)."""
    if n == 0:
        return math.nan, math.nan
    p, z2 = k / n, Z * Z
    centre = (p + z2 / (2 * n)) / (1 + z2 / n)
    half = Z * math.sqrt(p * (1 - p) / n + z2 / (4 * n * n)) / (1 + z2 / n)
    return max(0.0, centre - half), min(1.0, centre + half)


def _rate(ok: pd.Series) -> str:
    k, n = int(ok.sum()), len(ok)
    if n == 0:
        return "–"
    lo, hi = wilson(k, n)
    return f"{100 * k / n:.1f} % [{100 * lo:.1f}, {100 * hi:.1f}] of {n}"


def run_table(runs: dict[str, pd.DataFrame]) -> pd.DataFrame:
    """Per run: success (all, over feasible, comfortable slots, y0 >= 1.6 m feasible) with
    intervals, collisions, switches, parking time and path length over parked cases, and
    planning time per call (median, mean, p95)."""
    rows = []
    for name, df in runs.items():
        ok = df["success"].fillna(False).astype(bool)
        feasible = df["feasible"].fillna(False).astype(bool)
        times = np.concatenate([np.asarray(t, float) for t in df["plan_times_ms"].dropna()] or [np.empty(0)])
        ms = lambda f, t=times: f"{f(t):.1f}" if len(t) else "–"  # noqa: E731
        rows.append(
            {
                "run": name,
                "cases": len(df),
                "success": _rate(ok),
                "over feasible": _rate(ok[feasible]),
                "comfortable": _rate(ok[comfortable(df)]),
                "y0 >= 1.6 m, feasible": _rate(ok[far_out(df) & feasible]) if "y0" in df else "–",
                "collisions": int(df["collision"].fillna(False).astype(bool).sum()),
                "switches": f"{df['switches'][ok].mean():.2f}" if ok.any() else "–",
                "parking time [s]": f"{df['parking_time_s'][ok].mean():.1f}" if ok.any() else "–",
                "path length [m]": f"{df['path_length_m'][ok].mean():.2f}" if ok.any() else "–",
                "plan ms median / mean / p95": " / ".join(
                    ms(f) for f in (np.median, np.mean, lambda t: np.percentile(t, 95))
                ),
            }
        )
    return pd.DataFrame(rows)


def _bootstrap(diff: np.ndarray, rng: np.random.Generator) -> tuple[float, float]:
    """A paired bootstrap 95 % interval of the mean of per-case differences."""
    if len(diff) == 0:
        return math.nan, math.nan
    means = diff[rng.integers(0, len(diff), size=(RESAMPLES, len(diff)))].mean(axis=1)
    return float(np.percentile(means, 2.5)), float(np.percentile(means, 97.5))


def paired_table(runs: dict[str, pd.DataFrame], reference: str) -> pd.DataFrame:
    """Each other run against ``reference`` on the cases both ran (see the module docstring)."""
    ref = runs[reference].set_index("case_id")
    rows = []
    for name, df in runs.items():
        if name == reference:
            continue
        other = df.set_index("case_id")
        common = ref.index.intersection(other.index)
        a = ref.loc[common, "success"].fillna(False).astype(bool).to_numpy()
        b = other.loc[common, "success"].fillna(False).astype(bool).to_numpy()
        rng = np.random.default_rng(0)
        lo, hi = _bootstrap(b.astype(float) - a.astype(float), rng)
        gained, lost = int((b & ~a).sum()), int((a & ~b).sum())
        p = binomtest(gained, gained + lost).pvalue if gained + lost else 1.0
        both = a & b
        row = {
            "run": name,
            "against": reference,
            "common cases": len(common),
            "success difference [points]": f"{100 * (b.mean() - a.mean()):+.1f} [{100 * lo:+.1f}, {100 * hi:+.1f}]"
            if len(common)
            else "–",
            "gained / lost": f"{gained} / {lost}",
            "McNemar p": f"{p:.3g}",
            "both park": int(both.sum()),
        }
        for col, label in (("switches", "switches"), ("parking_time_s", "parking time [s]")):
            d = other.loc[common, col].to_numpy(float)[both] - ref.loc[common, col].to_numpy(float)[both]
            dlo, dhi = _bootstrap(d, rng)
            row[f"{label} difference"] = f"{d.mean():+.2f} [{dlo:+.2f}, {dhi:+.2f}]" if len(d) else "–"
        rows.append(row)
    return pd.DataFrame(rows)


def markdown(df: pd.DataFrame) -> str:
    """``df`` as a Markdown table."""
    lines = ["| " + " | ".join(df.columns) + " |", "|" + "---|" * len(df.columns)]
    lines += ["| " + " | ".join(str(v) for v in r) + " |" for r in df.itertuples(index=False)]
    return "\n".join(lines)


def success_figure(runs: dict[str, pd.DataFrame], path) -> None:
    """Success per parking type and run, with 95 % Wilson intervals, to ``path`` (PNG)."""
    plt = pyplot()

    types = ["parallel", "reverse", "angle"]
    fig, ax = plt.subplots(figsize=(6.4, 3.6))
    width = 0.8 / max(len(runs), 1)
    for j, (name, df) in enumerate(runs.items()):
        rates, lows, highs = [], [], []
        for t in types:
            ok = df.loc[df["parking_type"] == t, "success"].fillna(False).astype(bool)
            lo, hi = wilson(int(ok.sum()), len(ok))
            rate = ok.mean() if len(ok) else math.nan
            rates.append(100 * rate)
            lows.append(100 * (rate - lo) if len(ok) else 0.0)
            highs.append(100 * (hi - rate) if len(ok) else 0.0)
        x = np.arange(len(types)) + (j - (len(runs) - 1) / 2) * width
        ax.bar(x, rates, width, yerr=[lows, highs], capsize=3, label=name)
    ax.set_xticks(np.arange(len(types)), types)
    ax.set_ylabel("success [%] (95 % Wilson interval)")
    ax.set_ylim(0, 100)
    ax.legend(fontsize=7)
    fig.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(fig)
