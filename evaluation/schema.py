"""Every column of a result row, declared once: its type, unit, export rounding, whether it is
exported, and whether a machine decides it.

``episode.run_case`` writes rows of these columns (tests/test_schema.py fails on any other);
the store checks journal rows by their types, ``export_table`` keeps the exported ones at
their precision, ``mirrorpark diff`` compares those, and the report reads them. To add a
column: write it in ``run_case`` and declare it here.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import pandas as pd

# The types a journal row's value may have, by kind (None stands for NaN or no value).
_TYPES: dict[str, tuple[type, ...]] = {"str": (str,), "bool": (bool,), "int": (int,), "float": (int, float)}


@dataclass(frozen=True)
class Column:
    """One result column. ``kind``: str, bool, int or float, or a list of them (``list[float]``,
    ``list[int]``). ``decimals``: exports round a float (or each float of a list) to this;
    None keeps it as run. ``machine``: measured on this machine, not decided by the code (two
    runs of the same code differ in it; ``diff`` does not compare it)."""

    name: str
    kind: str
    unit: str = ""
    decimals: int | None = None
    exported: bool = True
    machine: bool = False
    doc: str = ""

    @property
    def types(self) -> tuple[type, ...] | None:
        """The Python types a stored value may have (None: not checked, a list)."""
        return _TYPES.get(self.kind)


MARGINS = ("M_f", "M_r", "M_e", "M_fl", "M_fr", "M_rl", "M_rr")  # the ISO margins, by the paper's names

COLUMNS: tuple[Column, ...] = (
    # The case (``episode.case_fields``, ``episode.layout_fields``).
    Column("planner", "str", doc="the planner's name"),
    Column("case_id", "str", doc="the grid case's id, or the layout's name"),
    Column("layout", "str", exported=False, doc="the layout's name (layout rows only)"),
    Column(
        "layout_key",
        "str",
        exported=False,
        doc="a hash of the layout's content and car (layout rows only): its rows' key",
    ),
    Column(
        "vehicle", "str", exported=False, doc="the car a layout ran with: paper, tpcap or custom (layout rows only)"
    ),
    Column("perturb", "str", exported=False, doc="the perturbation the episode ran under (perturbed rows only)"),
    Column("parking_type", "str", doc="parallel, reverse, angle (none: a layout without a slot)"),
    Column("road_width", "float", "m"),
    Column("slot_length", "float", "m"),
    Column("slot_width", "float", "m"),
    Column("theta0_deg", "float", "deg", doc="the start's heading (> 0 turns the nose away from the slot)"),
    Column("y0", "float", "m", doc="the rear axle's distance from the slot line at the start"),
    Column("y1", "float", "m", 3, doc="the rear axle's distance from the road's far boundary at the start"),
    Column("start_x_offset", "float", "m", 3, doc="the start along the road, from the slot's far end"),
    Column("feasible", "bool", doc="the slot admits an ISO pose at all"),
    # The outcome (the environment's verdicts).
    Column("success", "bool", doc="parked by the ISO criteria"),
    Column("failed_criterion", "str", doc="the first criterion that failed"),
    Column("failure_cause", "str", doc="why the episode failed (``causes.py``)"),
    Column("failure_amount", "float", "m", 4, doc="by how much (the cause's own measure)"),
    Column("collision", "bool"),
    Column("heading_error_deg", "float", "deg", 3),
    Column("switches", "int", doc="direction switches"),
    Column("parking_time_s", "float", "s", 2, doc="simulated time to the end of the episode"),
    Column("path_length_m", "float", "m", 3),
    Column("steps", "int", exported=False, doc="control steps (0.1 s)"),
    Column("inside_slot", "bool", doc="the outline ends inside the slot"),
    Column("min_clearance_m", "float", "m", 4, doc="the smallest gap to an obstacle along the episode"),
    Column("speed_at_min_clearance", "float", "m/s", 3),
    Column("min_clearance_away_m", "float", "m", 4, doc="... away from the start"),
    Column("speed_at_min_clearance_away", "float", "m/s", 3),
    *(Column(m, "float", "m", 4, doc="ISO margin at the end") for m in MARGINS),
    # The planner's effort: work (any machine repeats it) and time (this machine's).
    Column("planning_calls", "int"),
    Column("plan_times_ms", "list[float]", "ms", 1, machine=True, doc="each call's wall time"),
    Column("plan_time_median_ms", "float", "ms", exported=False, machine=True),
    Column("plan_time_max_ms", "float", "ms", exported=False, machine=True),
    Column("plan_iterations", "list[int]", doc="each call's SCP rounds or search expansions"),
    Column("plan_qp_solves", "list[int]", doc="each call's QP solves"),
    Column("plan_nodes", "list[int]", doc="each call's branch-and-bound or search nodes"),
    Column("safety_net_calls", "int", doc="calls that hit a wall-clock safety net"),
    Column("setup_ms", "float", "ms", 1, machine=True, doc="the policy's reset (slot-dependent parts)"),
    Column("planner_status", "str", doc="the policy's last word (ok, gave_up, no_goal, error, ...)"),
    Column("episode_wall_s", "float", "s", 2, machine=True),
    Column("environment", "str", machine=True, doc="the machine and packages (``environment.jsonl``)"),
    # Errors and what a layout's figure draws: kept in the run's folder, not exported.
    Column("error", "str", doc="the exception of a case that errored"),
    Column("traceback", "str", exported=False),
    # The driven trajectory (layout rows; grid rows of ``evaluate --trajectories``): the state
    # after the reset and after every step, and each step's commands (``episode.trajectory_fields``).
    Column("path_t", "list[float]", "s", exported=False, doc="the time of each state"),
    Column("path_x", "list[float]", "m", exported=False, doc="the rear axle, in the scene's frame"),
    Column("path_y", "list[float]", "m", exported=False),
    Column("path_theta", "list[float]", "rad", exported=False, doc="the heading"),
    Column("path_v", "list[float]", "m/s", exported=False, doc="the speed (negative in reverse)"),
    Column("path_accel", "list[float]", "m/s^2", exported=False, doc="the actual acceleration (after its lag)"),
    Column("path_steer", "list[float]", "rad", exported=False, doc="the actual front-wheel angle (after its lag)"),
    Column("path_accel_cmd", "list[float]", "m/s^2", exported=False, doc="the step's commanded acceleration"),
    Column("path_steer_cmd", "list[float]", "rad", exported=False, doc="the step's commanded front-wheel angle"),
    Column("path_origin", "list[float]", "m", exported=False, doc="a layout file's frame origin in the scene's"),
)

BY_NAME: dict[str, Column] = {c.name: c for c in COLUMNS}
EXPORT_COLUMNS: tuple[str, ...] = tuple(c.name for c in COLUMNS if c.exported)
MACHINE_COLUMNS: tuple[str, ...] = tuple(c.name for c in COLUMNS if c.machine)


def column_label(name: str) -> str:
    """A column as the report and its figures name it: its words and its unit
    (``parking_time_s`` -> "parking time [s]"); a column the schema does not declare is a KeyError."""
    col = BY_NAME[name]
    words = name if name in MARGINS else name.removesuffix(f"_{col.unit}").replace("_", " ")
    return f"{words} [{col.unit}]" if col.unit else words


def with_every_column(df: pd.DataFrame) -> pd.DataFrame:
    """``df`` with every declared column, those it lacks empty: a run whose every case
    errored has no outcome columns, and readers need not ask for each."""
    missing = [c.name for c in COLUMNS if c.name not in df.columns]
    return df.assign(**dict.fromkeys(missing, None)) if missing else df


def unknown_columns(row: dict[str, Any]) -> list[str]:
    """The row's columns that the schema does not declare."""
    return sorted(k for k in row if k not in BY_NAME)


def wrong_types(row: dict[str, Any]) -> list[str]:
    """The row's columns whose values do not have their declared types (None stands for any)."""
    out = []
    for k, v in row.items():
        col = BY_NAME.get(k)
        if v is None or col is None or col.types is None:
            continue
        if not isinstance(v, col.types) or (bool not in col.types and isinstance(v, bool)):
            out.append(k)
    return out


def type_error(row: dict[str, Any]) -> str | None:
    """Why a decoded journal row's values do not have their columns' types, or None."""
    bad = wrong_types(row)
    return f"{bad[0]!r} has the wrong type ({type(row[bad[0]]).__name__})" if bad else None


def exported_values(df: pd.DataFrame) -> pd.DataFrame:
    """``df`` (index reset) with its numbers rounded as ``export_table`` stores them, each
    column to its ``decimals``. With zstd at level 19 a row then takes about 70 bytes: a
    full-grid table is about 5 MB."""
    out = df.reset_index(drop=True).copy()
    for c in out.columns:
        col = BY_NAME.get(c)
        if col is None or col.decimals is None:
            continue
        if col.kind.startswith("list"):
            out[c] = [None if t is None else [round(float(v), col.decimals) for v in t] for t in out[c]]
        elif out[c].dtype.kind == "f":
            out[c] = out[c].round(col.decimals)
    return out
