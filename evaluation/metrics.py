"""Scores from a results table (docs/design.md, "Evaluation quantities").

- success rate per parking type and over all cases (error rows count as failures);
- completion: mean direction switches and parking time over successful episodes;
- computation: every planning call pooled, median and p95; episode wall time;
- ODD (the paper, III.A.c): "a collection of initial conditions which could successfully
  complete the parking process with a rate of 95 %. Initial conditions consist of SL, SW,
  theta0 and y0." A cell is (type, SL, SW, theta0, y0) and pools the runs of every road
  width that holds it; it is in the ODD when >= 95 % of its runs park. The ODD size is
  the count of such cells.
- success over feasible cases: those whose slot admits an ISO-compliant pose at all;
- success on comfortable slots (parallel SL >= 1.25 x car length, reverse and angle
  SW >= car width + 0.4 m, Table II's car), and over feasible cases with y0 >= 1.6 m
  (the paper reports around 100 % there).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pandas as pd

from mirrorpark_env.config import PARKING_TYPES
from mirrorpark_env.vehicle import VEHICLES, VehicleParams, vehicle_named

TYPES = PARKING_TYPES
CELL = ("parking_type", "slot_length", "slot_width", "theta0_deg", "y0")  # road width pooled (the paper's ODD)
ODD_RATE = 0.95
FAR_Y0 = 1.6  # [m] the paper's "from 1.6 m or more from the slot"

# The paper's headline figures (abstract and section III.B).
PAPER = {
    "success_gain_pct": 40.6,
    "odd_gain_pct": 86.1,
    "switch_change_pct": -47.6,
    "parking_time_change_pct": -18.0,
    # the paper states no paired (both-park) figures: "switch_change_paired_pct", ... are absent
    "mean_switches": 3.3,
    "mean_parking_time_s": 28.2,
    "mean_plan_time_ms": 74.0,
}


def comfortable(df: pd.DataFrame, vehicle: VehicleParams | None = None) -> pd.Series:
    """Rows whose slot is comfortable: parallel SL >= 1.25 x car length, reverse and angle
    SW >= car width + 0.4 m, for ``vehicle`` if given, else each row's car (layout rows name
    theirs in ``vehicle``; a custom car's rows count as not comfortable), else Table II's."""
    v = vehicle or VehicleParams.table_ii()
    length, width = pd.Series(v.length, index=df.index), pd.Series(v.width, index=df.index)
    if vehicle is None and "vehicle" in df:
        cars = {n: vehicle_named(n) for n in VEHICLES}
        named = df["vehicle"].where(df["vehicle"].notna(), "paper")
        length = named.map(lambda n: cars[n].length if n in cars else math.inf).astype(float)
        width = named.map(lambda n: cars[n].width if n in cars else math.inf).astype(float)
    parallel = df["parking_type"] == "parallel"
    return (parallel & (df["slot_length"] >= 1.25 * length - 1e-9)) | (
        ~parallel & (df["slot_width"] >= width + 0.4 - 1e-9)
    )


def far_out(df: pd.DataFrame) -> pd.Series:
    """Rows that start at least 1.6 m from the slot (y0), where the paper reports about 100 %."""
    return df["y0"] >= FAR_Y0 - 1e-9


def _rate(s: pd.Series) -> float | None:
    return float(s.mean()) if len(s) else None


def _plan_times(df: pd.DataFrame) -> np.ndarray:
    if "plan_times_ms" not in df:
        return np.empty(0)
    vals = [t for ts in df["plan_times_ms"].dropna() for t in (ts if ts is not None else [])]
    return np.asarray(vals, float)


def summary(df: pd.DataFrame, planner: str | None = None) -> dict[str, Any]:
    """The evaluation's JSON summary for one planner (types absent from the run are None)."""
    if planner is not None:
        df = df[df["planner"] == planner]
    planners = sorted(df["planner"].unique()) if len(df) else []
    success = df["success"].fillna(False).astype(bool) if len(df) else pd.Series(dtype=bool)
    rates = {t: _rate(success[df["parking_type"] == t]) for t in TYPES} if len(df) else dict.fromkeys(TYPES)
    rates["all"] = _rate(success)
    feasible = df["feasible"].fillna(True).astype(bool) if "feasible" in df else pd.Series(True, index=df.index)
    rates_feasible = {t: _rate(success[feasible & (df["parking_type"] == t)]) for t in TYPES} if len(df) else {}
    rates_feasible["all"] = _rate(success[feasible]) if len(df) else None
    ok = df[success] if len(df) else df
    times = _plan_times(df)
    wall = df["episode_wall_s"].dropna() if "episode_wall_s" in df else pd.Series(dtype=float)
    setup = df["setup_ms"].dropna() if "setup_ms" in df else pd.Series(dtype=float)
    return {
        "planner": planner if planner is not None else (planners[0] if len(planners) == 1 else planners),
        "cases": int(len(df)),
        "success_rate": rates,
        "success_rate_feasible": rates_feasible,  # over cases whose slot admits an ISO pose
        "success_rate_comfortable": _rate(success[comfortable(df)]) if len(df) else None,
        "success_rate_y0_1.6_feasible": _rate(success[feasible & far_out(df)]) if len(df) else None,
        "mean_switches": float(ok["switches"].mean()) if len(ok) else None,
        "mean_parking_time_s": float(ok["parking_time_s"].mean()) if len(ok) else None,
        "plan_time_ms": {
            "median": float(np.median(times)) if len(times) else None,
            "p95": float(np.percentile(times, 95)) if len(times) else None,
            "mean": float(times.mean()) if len(times) else None,
        },
        "setup_ms": {"median": float(setup.median()) if len(setup) else None},  # per episode, at reset
        "episode_wall_s": {"median": float(wall.median()) if len(wall) else None},
        "errors": int((df.get("planner_status") == "error").sum()) if len(df) else 0,
        # Calls where a wall-clock safety net (not the work budget) ended the search.
        "safety_net_calls": int(df["safety_net_calls"].fillna(0).sum()) if "safety_net_calls" in df else None,
    }


def odd_cells(df: pd.DataFrame, threshold: float = ODD_RATE) -> pd.DataFrame:
    """Per planner and cell (road widths pooled): runs, success fraction, in the ODD or not.

    Cell values are rounded to 1e-6 so that one level read back from Parquet is one cell."""
    key = df[list(CELL[1:])].round(6)
    g = df.assign(success=df["success"].fillna(False).astype(float), **key).groupby(["planner", *CELL])
    cells = g["success"].agg(runs="size", rate="mean").reset_index()
    cells["in_odd"] = cells["rate"] >= threshold - 1e-12
    return cells


def odd_size(df: pd.DataFrame) -> dict[str, dict[str, int]]:
    """ODD size per planner: cells in the ODD, per parking type and in all."""
    cells = odd_cells(df)
    out = {}
    for planner, c in cells.groupby("planner"):
        sizes = {t: int(c.loc[c["parking_type"] == t, "in_odd"].sum()) for t in TYPES}
        sizes["all"] = int(c["in_odd"].sum())
        out[planner] = sizes
    return out


def change_pct(ours: float | None, baseline: float | None) -> float | None:
    if ours is None or baseline is None or baseline == 0 or math.isnan(baseline):
        return None
    return 100.0 * (ours - baseline) / baseline


def _both_parked(df: pd.DataFrame, planner: str, baseline: str) -> dict[str, tuple[float, float]]:
    """Mean switches and parking time of ``planner`` and ``baseline`` over the cases both
    park: the paired comparison, free of each planner's own mix of hard successes."""
    ok = df[df["success"].astype(bool)]
    both = set(ok.loc[ok["planner"] == planner, "case_id"]) & set(ok.loc[ok["planner"] == baseline, "case_id"])
    d = ok[ok["case_id"].isin(both)]
    out = {}
    for col in ("switches", "parking_time_s"):
        means = d.groupby("planner")[col].mean()
        out[col] = (float(means.get(planner, math.nan)), float(means.get(baseline, math.nan)))
    return out


def headline(df: pd.DataFrame, planner: str, baseline: str | None) -> list[dict[str, Any]]:
    """The paper's headline comparisons beside ours (relative changes against ``baseline``).

    Comparisons use the cases both planners ran, so the figures are paired.
    """
    s = summary(df, planner)
    rows = []
    if baseline is not None:
        common = set(df.loc[df["planner"] == planner, "case_id"]) & set(df.loc[df["planner"] == baseline, "case_id"])
        d = df[df["case_id"].isin(common)]
        a, b = summary(d, planner), summary(d, baseline)
        odd = odd_size(d)
        rows += [
            ("success rate", "success_gain_pct", change_pct(a["success_rate"]["all"], b["success_rate"]["all"])),
            ("ODD size", "odd_gain_pct", change_pct(odd.get(planner, {}).get("all"), odd.get(baseline, {}).get("all"))),
            ("direction switches", "switch_change_pct", change_pct(a["mean_switches"], b["mean_switches"])),
            ("parking time", "parking_time_change_pct", change_pct(a["mean_parking_time_s"], b["mean_parking_time_s"])),
        ]
        both = _both_parked(d, planner, baseline)
        rows += [
            ("direction switches, cases both park", "switch_change_paired_pct", change_pct(*both["switches"])),
            ("parking time, cases both park", "parking_time_change_paired_pct", change_pct(*both["parking_time_s"])),
        ]
    else:
        rows += [
            (name, key, None)
            for name, key in (
                ("success rate", "success_gain_pct"),
                ("ODD size", "odd_gain_pct"),
                ("direction switches", "switch_change_pct"),
                ("parking time", "parking_time_change_pct"),
            )
        ]
    rows += [
        ("mean switches (successes)", "mean_switches", s["mean_switches"]),
        ("mean parking time [s] (successes)", "mean_parking_time_s", s["mean_parking_time_s"]),
        ("mean planning time [ms]", "mean_plan_time_ms", s["plan_time_ms"]["mean"]),
    ]
    return [
        {"measure": name, "paper": PAPER.get(key), "ours": val, "relative": key.endswith("pct")}
        for name, key, val in rows
    ]
