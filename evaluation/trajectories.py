"""Driven trajectories out of a run (``mirrorpark export RUN --trajectories DIR``).

A row holds its trajectory where the run kept it (``evaluate --trajectories``; layout runs
always): the state after the reset and after every 0.1 s step, and each step's commands
(``episode.trajectory_fields``). Written one file per episode, ``<case>-<planner>.csv``
(or ``.parquet``), with the columns of ``COLUMNS``: time, rear-axle pose, speed, actual
steering and acceleration, the gear (+1 forward, -1 reverse, 0 standing: the sign of the
speed beyond 1 mm/s), and the step's commands (NaN on the last state). Layout rows also go
in TPCAP's form, ``tpcap/<layout>-<planner>.csv``: ``t, x, y, theta`` of the rear axle in
the layout file's own frame. Replaying the commands through the truth model from the first
state gives the stored states (``tests/test_trajectories.py``).
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pandas as pd

# (file column, row field) of a trajectory file.
COLUMNS = (
    ("t", "path_t"),
    ("x", "path_x"),
    ("y", "path_y"),
    ("heading", "path_theta"),
    ("v", "path_v"),
    ("steer", "path_steer"),
    ("accel", "path_accel"),
    ("gear", None),
    ("accel_cmd", "path_accel_cmd"),
    ("steer_cmd", "path_steer_cmd"),
)
STANDING = 1e-3  # m/s: slower than this, the gear is 0


def has_trajectory(row: pd.Series) -> bool:
    """Whether the row kept every field of a full trajectory."""
    return all(isinstance(row.get(f), (list, np.ndarray)) and len(row[f]) for _, f in COLUMNS if f is not None)


def trajectory_table(row: pd.Series) -> pd.DataFrame:
    """The row's trajectory as a table of ``COLUMNS`` (the scene's frame)."""
    table = pd.DataFrame({name: np.asarray(row[f], float) for name, f in COLUMNS if f is not None})
    v = table["v"].to_numpy()
    table.insert(7, "gear", np.where(v > STANDING, 1, np.where(v < -STANDING, -1, 0)))
    return table


def tpcap_table(row: pd.Series, origin: tuple[float, float]) -> pd.DataFrame:
    """The row's driven poses in TPCAP's form: ``t, x, y, theta`` of the rear axle, in the
    frame whose origin lies at ``origin`` of the scene's (a layout file's own frame)."""
    return pd.DataFrame(
        {
            "t": np.asarray(row["path_t"], float),
            "x": np.asarray(row["path_x"], float) + float(origin[0]),
            "y": np.asarray(row["path_y"], float) + float(origin[1]),
            "theta": np.asarray(row["path_theta"], float),
        }
    )


def _stem(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9._+-]+", "_", text).strip("._") or "case"


def write_trajectories(df: pd.DataFrame, out: str | Path, fmt: str = "csv") -> tuple[list[Path], int]:
    """One file per row that kept its trajectory (and TPCAP's form for layout rows); the
    paths written and how many rows had none."""
    if fmt not in ("csv", "parquet"):
        raise ValueError(f"--format: csv or parquet, got {fmt!r}")
    out = Path(out)
    written, missing = [], 0
    for _, row in df.iterrows():
        if not has_trajectory(row):
            missing += 1
            continue
        stem = f"{_stem(str(row['case_id']))}-{_stem(str(row['planner']))}"
        table = trajectory_table(row)
        out.mkdir(parents=True, exist_ok=True)
        path = out / f"{stem}.{fmt}"
        if fmt == "csv":
            table.to_csv(path, index=False, float_format="%.9g")
        else:
            table.to_parquet(path, index=False)
        written.append(path)
        origin = row.get("path_origin")
        if isinstance(row.get("layout"), str) and isinstance(origin, (list, np.ndarray)) and len(origin) == 2:
            (out / "tpcap").mkdir(exist_ok=True)
            tpcap_table(row, origin).to_csv(out / "tpcap" / f"{stem}.csv", index=False, float_format="%.6f")
            written.append(out / "tpcap" / f"{stem}.csv")
    return written, missing
