"""Two runs over the same cases, compared: did a code change keep every row, and if not,
which cases did it gain or lose, and at what cost?

The question every planner change raises. Rows are matched by case; both sides are
compared at the precision ``export_table`` stores (so an exported table and a run's own
folder compare alike), on every column but those that depend on the machine
(``schema.MACHINE_COLUMNS``): a change that only makes the planner faster leaves every row
"the same". Times are summed and set side by side, but they say something only where
both runs shared one machine at one time (paired).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np
import pandas as pd

from .causes import cause_of
from .metrics import _plan_times, _rate
from .report import _pct
from .schema import EXPORT_COLUMNS, MACHINE_COLUMNS, exported_values


@dataclass(frozen=True)
class RunDiff:
    """What changed from ``before`` to ``after`` over their common cases."""

    before: str  # each side's planner name
    after: str
    cases: int  # in both
    only_before: int
    only_after: int
    same_rows: int  # every compared column equal
    changed_columns: dict[str, int]  # column -> cases where it differs
    success_before: float
    success_after: float
    gained: tuple[str, ...]  # parked after, not before
    lost: tuple[str, ...]
    collisions_before: int
    collisions_after: int
    both_parked: int
    switches_before: float | None  # means where both park
    switches_after: float | None
    parking_time_before: float | None
    parking_time_after: float | None
    calls_before: int
    calls_after: int
    planning_s_before: float  # summed call times: comparable only when paired
    planning_s_after: float
    causes_lost: dict[str, int] = field(default_factory=dict)  # the lost cases' failure causes after
    by: str | None = None  # the column ``groups`` splits the cases by
    groups: dict[str, dict[str, float | int]] = field(default_factory=dict)  # value -> cases, success, gained, lost

    def to_json(self) -> dict[str, Any]:
        d = asdict(self)
        d["gained"], d["lost"] = list(self.gained), list(self.lost)
        return d


NEEDED = ("success", "collision", "failure_cause", "switches", "parking_time_s", "planning_calls")


def _one_planner(df: pd.DataFrame, side: str) -> str:
    """The side's planner, after checking it is one planner's rows, each case once, with
    the columns the comparison reads."""
    missing = [c for c in NEEDED if c not in df.columns]
    if missing:
        raise ValueError(f"{side}: the results lack the column(s) {', '.join(missing)}")
    names = sorted(df["planner"].dropna().unique())
    if len(names) != 1:
        raise ValueError(f"{side}: expected the rows of one planner, got {len(names)} ({', '.join(names) or 'none'})")
    dup = df["case_id"].duplicated()
    if dup.any():
        raise ValueError(f"{side}: case {df['case_id'][dup].iloc[0]!r} appears more than once")
    return names[0]


def _equal(a: Any, b: Any) -> bool:
    """Cell equality: missing equals missing (None, NaN, pd.NA), lists or arrays element by
    element."""
    seq = (list, tuple, np.ndarray)
    if isinstance(a, seq) or isinstance(b, seq):
        if not (isinstance(a, seq) and isinstance(b, seq)):
            return False
        a, b = np.asarray(a, dtype=object), np.asarray(b, dtype=object)
        return a.shape == b.shape and all(_equal(x, y) for x, y in zip(a.ravel(), b.ravel()))
    missing_a, missing_b = bool(pd.isna(a)), bool(pd.isna(b))
    if missing_a or missing_b:
        return missing_a and missing_b
    return bool(a == b)


BY_COLUMNS = ("parking_type", "road_width", "slot_length", "slot_width", "theta0_deg", "y0", "feasible")


def compare(before: pd.DataFrame, after: pd.DataFrame, by: str | None = None) -> RunDiff:
    """``RunDiff`` of two result tables (``read_results``), one planner each; ``by``: also
    per value of that case column (one of ``BY_COLUMNS``)."""
    if by is not None and by not in BY_COLUMNS:
        raise ValueError(f"by: must be one of {', '.join(BY_COLUMNS)}, got {by!r}")
    name_b, name_a = _one_planner(before, "before"), _one_planner(after, "after")
    cols = [c for c in EXPORT_COLUMNS if c in before.columns and c in after.columns]
    b = exported_values(before[cols].sort_values("case_id")).set_index("case_id")
    a = exported_values(after[cols].sort_values("case_id")).set_index("case_id")
    common = b.index.intersection(a.index)
    if not len(common):
        raise ValueError("before and after share no case: compare runs over the same cases")
    b, a = b.loc[common], a.loc[common]
    compared = [c for c in b.columns if c not in MACHINE_COLUMNS and c != "planner"]
    changed: dict[str, int] = {}
    same = np.ones(len(common), bool)
    for c in compared:
        eq = np.array([_equal(x, y) for x, y in zip(b[c].tolist(), a[c].tolist())], bool)
        if not eq.all():
            changed[c] = int((~eq).sum())
        same &= eq
    ok_b, ok_a = b["success"].astype(bool), a["success"].astype(bool)
    both = ok_b & ok_a
    lost = common[ok_b & ~ok_a]
    causes = a.loc[lost, "failure_cause"].fillna("none").map(cause_of).value_counts()
    groups: dict[str, dict[str, float | int]] = {}
    if by is not None:
        if by not in b.columns:
            raise ValueError(f"by: the results hold no column {by!r}")
        for value, idx in b.groupby(by, sort=True).groups.items():
            gb, ga = ok_b.loc[idx], ok_a.loc[idx]
            groups[str(value)] = {
                "cases": len(idx),
                "success_before": float(gb.mean()),
                "success_after": float(ga.mean()),
                "gained": int((ga & ~gb).sum()),
                "lost": int((gb & ~ga).sum()),
            }
    return RunDiff(
        before=name_b,
        after=name_a,
        cases=len(common),
        only_before=int(len(before) - len(common)),
        only_after=int(len(after) - len(common)),
        same_rows=int(same.sum()),
        changed_columns=dict(sorted(changed.items(), key=lambda kv: -kv[1])),
        success_before=float(ok_b.mean()),
        success_after=float(ok_a.mean()),
        gained=tuple(common[ok_a & ~ok_b]),
        lost=tuple(lost),
        collisions_before=int(b["collision"].astype(bool).sum()),
        collisions_after=int(a["collision"].astype(bool).sum()),
        both_parked=int(both.sum()),
        switches_before=_rate(b.loc[both, "switches"]),
        switches_after=_rate(a.loc[both, "switches"]),
        parking_time_before=_rate(b.loc[both, "parking_time_s"]),
        parking_time_after=_rate(a.loc[both, "parking_time_s"]),
        calls_before=int(b["planning_calls"].sum()),
        calls_after=int(a["planning_calls"].sum()),
        planning_s_before=float(_plan_times(b).sum()) / 1e3,
        planning_s_after=float(_plan_times(a).sum()) / 1e3,
        causes_lost={str(k): int(v) for k, v in causes.items()},
        by=by,
        groups=groups,
    )


def _both(x: float | None, y: float | None, fmt: str) -> str:
    if x is None or y is None:
        return "-"
    return f"{x:{fmt}} -> {y:{fmt}}"


def format_diff(d: RunDiff, list_cases: int = 10) -> str:
    """``d`` as Markdown: the verdict first, then outcomes, cost and the cases that moved."""
    n = d.cases
    lines = [f"# `{d.after}` against `{d.before}` on {n:,} common cases", ""]
    if d.only_before or d.only_after:
        lines += [f"Not compared: {d.only_before:,} cases only before, {d.only_after:,} only after.", ""]
    if d.same_rows == n:
        lines += ["**Every row the same** (all columns but the machine's times).", ""]
    else:
        cols = ", ".join(f"`{c}` {k:,}" for c, k in d.changed_columns.items())
        lines += [f"**{n - d.same_rows:,} of {n:,} rows differ**; by column (cases): {cols}.", ""]
    lines += [
        "| | before | after |",
        "|---|---|---|",
        f"| success | {_pct(d.success_before)} | {_pct(d.success_after)} |",
        f"| collisions | {d.collisions_before} | {d.collisions_after} |",
        f"| planning calls | {d.calls_before:,} | {d.calls_after:,} |",
        f"| planning time (s; paired runs only) | {d.planning_s_before:.1f} | {d.planning_s_after:.1f} |",
        "",
        f"Gained {len(d.gained)}, lost {len(d.lost)}"
        + (f" (now: {', '.join(f'{k} {v}' for k, v in d.causes_lost.items())})" if d.lost else "")
        + f". Where both park ({d.both_parked:,}): switches {_both(d.switches_before, d.switches_after, '.2f')}, "
        f"parking time {_both(d.parking_time_before, d.parking_time_after, '.1f')} s.",
    ]
    if d.groups:
        lines += ["", f"| {d.by} | cases | before | after | gained | lost |", "|---|---|---|---|---|---|"]
        for value, g in d.groups.items():
            lines.append(
                f"| {value} | {g['cases']:,} | {_pct(g['success_before'])} | {_pct(g['success_after'])} "
                f"| {g['gained']} | {g['lost']} |"
            )
    for title, ids in (("Gained", d.gained), ("Lost", d.lost)):
        if ids and list_cases > 0:
            more = f" (first {list_cases} of {len(ids)})" if len(ids) > list_cases else ""
            lines += ["", f"{title}{more}:", *(f"- `{c}`" for c in ids[:list_cases])]
    return "\n".join(lines) + "\n"
