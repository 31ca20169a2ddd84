"""A Markdown report with the paper's figures (Figs. 20, 21, 23, 24, 25) and tables."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from mirrorpark_env.criteria import iso_pose_slack
from mirrorpark_env.textfile import read_text
from mirrorpark_env.vehicle import VehicleParams

from .figures import (
    SLOT,
    _per_type_lines,
    fig_clearance,
    fig_efficiency,
    fig_odd,
    fig_plan_time,
    fig_success_by_type,
)
from .metrics import TYPES, far_out, headline, odd_cells, odd_size, summary
from .schema import column_label, with_every_column

SPARE = 0.01  # [m] room to spare that the report's "to spare" columns ask of a slot


def _fmt(v, pct=False) -> str:
    if v is None or (isinstance(v, float) and np.isnan(v)):
        return "n/a"
    return f"{v:+.1f} %" if pct else f"{v:.3g}"


def write_report(
    df: pd.DataFrame, out: str | Path, baseline: str | None = None, notes: str | Path | None = None
) -> Path:
    """The report and its figures; returns the report's path.

    ``out`` a folder: ``out/report.md`` and the figures beside it; ``out`` a ``.md`` file:
    the report there and its figures in the folder of the same stem beside it
    (``docs/results.md``, ``docs/results/``). ``notes``: a Markdown file appended as is
    (what the author reads in the figures: it is kept apart so that the rest regenerates).
    """
    out = Path(out)
    if out.suffix == ".md":
        path, out = out, out.with_suffix("")
        prefix = f"{out.name}/"
    else:
        path, prefix = out / "report.md", ""
    out.mkdir(parents=True, exist_ok=True)
    notes_text = read_text(notes, "notes file") if notes is not None else None
    if "y1" not in df:
        df = df.assign(y1=df["road_width"] - df["y0"])
    df = with_every_column(df)  # a run whose every case errored has no outcome columns
    planners = sorted(df["planner"].unique())
    if baseline is None:  # the paper compares against its search-based baseline
        baseline = "hybrid-astar" if "hybrid-astar" in planners else None
    main = "mirror" if "mirror" in planners else next((p for p in planners if p != baseline), planners[0])
    figs = [fig_success_by_type(df, planners, out)]
    figs.append(
        _per_type_lines(
            df,
            planners,
            "road_width",
            out,
            "success_vs_road_width.png",
            "Success vs road width (paper Fig. 21)",
            lambda t: column_label("road_width"),
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
            lambda t: column_label(SLOT[t]),
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
            lambda t: column_label("y0"),
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
            lambda t: column_label("y1"),
        )
    )
    cells = odd_cells(df)
    sizes = odd_size(df)
    # a type's ODD map where it has cells (layouts, without the grid's y0, have none)
    figs += [fig_odd(cells, planners, t, out, sizes) for t in TYPES if (cells["parking_type"] == t).any()]
    figs.append(fig_efficiency(df, planners, out))
    figs.append(fig_plan_time(df, planners, out))
    if "min_clearance_m" in df and df["min_clearance_m"].notna().any():
        figs.append(fig_clearance(df, planners, out))

    lines = ["# MirrorPark evaluation report", ""]
    per_type = ", ".join(f"{t}: {df[df.parking_type == t].case_id.nunique()}" for t in TYPES)
    lines += [f"Cases: {df['case_id'].nunique()} ({per_type}); planners: {', '.join(planners)}.", ""]
    lines += _summary_table(df, planners, sizes)
    lines += _success_tables(df, planners)
    lines += _headline_table(df, main, baseline)
    lines += _failure_table(df, planners)
    lines += _clearance_table(df, planners)
    lines += ["## Figures", ""]
    lines += [f"![{f.stem}]({prefix}{f.name})" for f in figs]
    if notes_text is not None:
        lines += ["", notes_text.rstrip()]
    path.write_text("\n".join(lines) + "\n")
    return path


def _pct(v) -> str:
    return "n/a" if v is None or (isinstance(v, float) and np.isnan(v)) else f"{100 * v:.1f} %"


def _summary_table(df, planners, sizes) -> list[str]:
    lines = [
        "## Summary",
        "",
        "| planner | cases | success | over feasible | switches | parking time [s] | plan ms median | p95"
        " | setup ms | ODD cells |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for p in planners:
        s = summary(df, p)
        lines.append(
            f"| {p} | {s['cases']} | {_pct(s['success_rate']['all'])} | {_pct(s['success_rate_feasible']['all'])}"
            f" | {_fmt(s['mean_switches'])} | {_fmt(s['mean_parking_time_s'])} | {_fmt(s['plan_time_ms']['median'])}"
            f" | {_fmt(s['plan_time_ms']['p95'])} | {_fmt(s['setup_ms']['median'])}"
            f" | {sizes.get(p, {}).get('all', 0)} |"
        )
    nets = {p: summary(df, p)["safety_net_calls"] for p in planners}
    fired = ", ".join(f"{p} {n}" for p, n in nets.items() if n is not None)
    return lines + [
        "",
        f"Planning calls ended by a wall-clock safety net rather than their work budget: {fired or 'not recorded'}.",
        "",
        "Success over feasible: over the cases whose slot admits an ISO-compliant final pose at all. "
        "Switches and parking time: over successful episodes. Plan ms: per planning call, pooled. "
        "Setup ms: median per episode of the policy's preparation at reset, not counted in plan ms. "
        "ODD cells: (type, SL, SW, theta0, y0) with road widths pooled, parking in >= 95 % of their runs.",
        "",
    ]


def _success_tables(df, planners) -> list[str]:
    lines = [
        "## Success per parking type",
        "",
        "| planner | type | cases | success | feasible cases | over feasible | y0 >= 1.6 m, feasible "
        "| over feasible, >= 1 cm to spare | y0 >= 1.6 m, >= 1 cm to spare |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    ok = df["success"].fillna(False).astype(bool)
    feasible = df["feasible"].fillna(True).astype(bool) if "feasible" in df else pd.Series(True, index=df.index)
    slack = pd.Series(
        iso_pose_slack(df["parking_type"], df["slot_length"], df["slot_width"], VehicleParams.table_ii()),
        index=df.index,
    )
    roomy = feasible & (slack >= SPARE - 1e-9)
    far_all = far_out(df)
    for p in planners:
        for t in TYPES:
            m = (df["planner"] == p) & (df["parking_type"] == t)
            if not m.any():
                continue
            f = m & feasible
            far = f & far_all
            r, r_far = m & roomy, m & roomy & far_all
            cells = [ok[x].mean() if x.any() else None for x in (m, f, far, r, r_far)]
            lines.append(
                f"| {p} | {t} | {int(m.sum())} | {_pct(cells[0])} | {int(f.sum())} | {_pct(cells[1])}"
                f" | {_pct(cells[2])} | {_pct(cells[3])} | {_pct(cells[4])} |"
            )
    return lines + [
        "",
        "The paper reports success around 100 % from y0 >= 1.6 m. To spare: how far every ISO margin of the "
        "slot's best pose can exceed its limit at once (`criteria.iso_pose_slack`); a feasible slot with "
        "none to spare (reverse and angle SW = car width + 0.2 m) holds exactly one compliant pose, centred "
        "and aligned exactly (the margins' tolerance is 1e-12 m), which no real car hits.",
        "",
    ]


def _headline_table(df, main, baseline) -> list[str]:
    lines = [
        f"## The paper's headline comparisons ({main} vs {baseline or 'no baseline in these results'})",
        "",
        "| measure | paper | ours |",
        "|---|---|---|",
    ]
    for h in headline(df, main, baseline):
        if h["paper"] is None:
            paper = "not stated"
        else:
            paper = f"{h['paper']:+.1f} %" if h["relative"] else f"{h['paper']:g}"
        lines.append(f"| {h['measure']} | {paper} | {_fmt(h['ours'], h['relative'])} |")
    return lines + [
        "",
        "Relative changes compare the two planners on the cases both ran: success rate, ODD size (cells "
        "as above), mean direction switches and parking time over each planner's successes (the paper's "
        "reading: each mean mixes in the hard cases only that planner parks), and the same two over the "
        "cases both park (paired). The paper's planning time is a mean on an i7-9750H with Gurobi; ours is "
        "the pooled mean of every planning call.",
        "",
    ]


def _failure_table(df, planners) -> list[str]:
    failed = df[~df["success"].fillna(False).astype(bool)]
    if not len(failed):
        return []
    cause = failed["failure_cause"] if "failure_cause" in failed else pd.Series(index=failed.index, dtype=object)
    cause = cause.fillna("(not recorded) " + failed["failed_criterion"].fillna("?"))
    table = failed.assign(cause=cause).groupby(["planner", "cause", "parking_type"]).size().unstack(fill_value=0)
    lines = ["## Failures by cause", "", "| planner | cause | " + " | ".join(TYPES) + " |", "|---|---|---|---|---|"]
    for (p, c), row in table.iterrows():
        lines.append(f"| {p} | {c} | " + " | ".join(str(int(row.get(t, 0))) for t in TYPES) + " |")
    return lines + [
        "",
        "Causes (evaluation/causes.py, first match): error, collision, out_of_scene, no_iso_pose (the slot "
        "admits no ISO pose), parked_outside_margin:<criterion> (standing inside the slot, outside that "
        "criterion), timeout (180 s), gave_up (the planner stopped trying).",
        "",
    ]


def _clearance_table(df, planners) -> list[str]:
    if "min_clearance_m" not in df or not df["min_clearance_m"].notna().any():
        return []
    lines = [
        "## Closest approach to an obstacle",
        "",
        "| planner | measured | episodes | median [cm] | p5 [cm] | p1 [cm] | min [cm] | under 1 cm"
        " | under 1 cm above 0.5 m/s |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    spans = [("whole episode", "min_clearance_m", "speed_at_min_clearance")]
    if "min_clearance_away_m" in df:
        spans.append(("> 1 m from the start", "min_clearance_away_m", "speed_at_min_clearance_away"))
    for p in planners:
        for label, gap_col, speed_col in spans:
            d = df[(df["planner"] == p) & np.isfinite(df[gap_col].astype(float))]
            if not len(d):
                continue
            g = 100 * d[gap_col].to_numpy(float)
            close = g < 1.0
            fast = close & (d[speed_col].to_numpy(float) > 0.5)
            q = np.percentile(g, [50, 5, 1])
            lines.append(
                f"| {p} | {label} | {len(d)} | {q[0]:.1f} | {q[1]:.1f} | {q[2]:.2f} | {g.min():.2f}"
                f" | {int(close.sum())} | {int(fast.sum())} |"
            )
    return lines + [
        "",
        "Per episode, the smallest separating-axis gap between the car's footprint and any obstacle over "
        "every 0.01 s sub-step (a lower bound on the Euclidean distance), and the speed at that moment; "
        "then the same over the poses more than 1 m from the start (grid starts may touch a kerb, and "
        "driving off along it is not a close pass).",
        "",
    ]
