"""Why an episode failed: one cause per row, for the report's failure table.

First match wins:

- ``error``: the case raised (a bug, or a case that cannot be built);
- ``collision``: the footprint overlapped an obstacle;
- ``out_of_scene``: the car left the scene along the road;
- ``no_iso_pose``: the slot admits no ISO-compliant final pose at all
  (``criteria.iso_pose_exists``), so no planner can succeed;
- ``parked_outside_margin:<which>``: the car ended standing inside the slot but outside a
  criterion: ``heading`` or the smallest margin's name (``M_e``, ``M_fl``, ...); the row's
  ``failure_amount`` says by how much (degrees past the heading tolerance, metres short);
- ``timeout``: the 180 s ran out;
- ``gave_up``: the planner stopped trying (no path, budget spent, no progress).
"""

from __future__ import annotations

import math
from typing import Any

CAUSES = ("error", "collision", "out_of_scene", "no_iso_pose", "parked_outside_margin", "timeout", "gave_up")


def cause_of(failure_cause: str) -> str:
    """The cause itself, one of ``CAUSES``, without the criterion ``parked_outside_margin``
    names after a colon."""
    return failure_cause.split(":", 1)[0]


def failure_cause(
    *,
    success: bool,
    error: bool,
    collision: bool,
    out_of_scene: bool,
    feasible: bool,
    inside_slot: bool,
    stopped: bool,
    heading_error_deg: float,
    margins: dict[str, float],
    parking_time_s: float,
    heading_tol_deg: float = 3.0,
    min_margin: float = 0.1,
    time_limit_s: float = 180.0,
) -> tuple[str | None, float]:
    """(cause, amount) of a failed episode; (None, nan) for a success. ``min_margin`` is the
    perpendicular types' margin (parallel margins need only be > 0)."""
    if success:
        return None, math.nan
    for cause, hit in (("error", error), ("collision", collision), ("out_of_scene", out_of_scene)):
        if hit:
            return cause, math.nan
    if not feasible:
        return "no_iso_pose", math.nan
    if inside_slot and stopped:
        excess = abs(heading_error_deg) - heading_tol_deg
        if excess > 1e-9:
            return "parked_outside_margin:heading", excess
        need = min_margin if "M_fl" in margins else 0.0
        name, value = min(margins.items(), key=lambda kv: kv[1])
        if value < need or (need == 0.0 and value <= 0.0):
            return f"parked_outside_margin:{name}", need - value
    if parking_time_s >= time_limit_s - 1e-9:
        return "timeout", math.nan
    return "gave_up", math.nan


def episode_cause(info: dict[str, Any] | None, feasible: bool) -> tuple[str | None, float]:
    """``failure_cause`` of an episode from its last info (None: the case raised)."""
    if info is None:
        return "error", math.nan
    return failure_cause(
        success=bool(info["is_success"]),
        error=False,
        collision=bool(info["collision"]),
        out_of_scene=bool(info["out_of_scene"]),
        feasible=feasible,
        inside_slot=bool(info["inside_slot"]),
        stopped=bool(info["stopped"]),
        heading_error_deg=float(info["heading_error_deg"]),
        margins=dict(info["margins"]),
        parking_time_s=float(info["parking_time"]),
    )
