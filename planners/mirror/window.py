"""The target's ISO window across the slot, and the terminal weight across the slot it sets.

A plan's terminal cost pulls its end toward the target with one weight in every direction.
In a tight slot that pull is too weak across the slot: in a 1.92 m angle slot the ISO
window is 2.5 cm to each side of the target, and an end 3 cm off costs 400 x 0.03^2 =
0.36, less than the steering of a correcting move. The car then enters a little to one
side and corrects it a millimetre per plan, for dozens of direction switches
(docs/mirror_planner_notebook.md, "The end weighed across a tight slot"). Here the weight
across the slot grows as the window narrows, so that an end at the window's edge costs
what it costs in a slot of ``cfg.lateral_window`` each side; slots at least that wide
keep the one weight, and their plans are unchanged to the last bit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from mirrorpark_env.config import ParkingType
from mirrorpark_env.criteria import SuccessCriteria
from mirrorpark_env.scenario import ScenarioGeometry
from mirrorpark_env.vehicle import footprint

from .config import MirrorPlannerConfig

MIN_WINDOW = 1e-3  # [m] narrower than this, no pose passes in practice: nothing to sharpen


@dataclass(frozen=True)
class Terminal:
    """The end's position cost in the target's frame: along its heading at the config's
    ``w_terminal_position``; across it on the body's front and rear ends (where the ISO side
    margins are measured), each at half ``w_lateral``, so that a sideways offset with the
    heading exact costs ``w_lateral`` per m^2."""

    heading: float  # [rad] the target's heading (the slot's axis)
    w_lateral: float
    front: float  # [m] rear axle to the front of the body
    rear: float  # [m] rear axle to the back of the body


def end_cost(terminal: Terminal, w_along: float, dx: float, dy: float, dtheta: float) -> float:
    """The cost of a real end offset (dx, dy, dtheta) from the target, as the QP's rows
    weigh it (``qp.cost_pattern``)."""
    along, across = terminal_error(terminal, dx, dy)
    front, rear = across + terminal.front * dtheta, across - terminal.rear * dtheta
    return w_along * along**2 + 0.5 * terminal.w_lateral * (front**2 + rear**2)


def lateral_window(geometry: ScenarioGeometry) -> float | None:
    """[m] How far the car may move across the slot from the target, to the nearer side, and
    still pass the ISO margins (reverse, angle: the side margins >= their minimum;
    parallel: inside the entrance and the back). None without a slot."""
    if geometry.slot is None or not geometry.slot_edges:
        return None
    crit = SuccessCriteria(geometry)
    corners = footprint(geometry.vehicle, *geometry.target)
    d = crit.edge_distances(corners)  # (corner, edge)
    parallel = geometry.parking_type is ParkingType.PARALLEL
    names = ("entrance", "back") if parallel else ("left", "right")
    cols = [i for i, (n, _) in enumerate(geometry.slot_edges) if n in names]
    return float(d[:, cols].min()) - crit.min_margin


def terminal_for(geometry: ScenarioGeometry, cfg: MirrorPlannerConfig) -> Terminal | None:
    """The terminal cost toward ``geometry``'s target: None where one weight serves (no
    slot, a window of at least ``cfg.lateral_window``, or one too narrow to park in)."""
    w = lateral_window(geometry)
    if w is None or cfg.lateral_window <= 0 or not MIN_WINDOW <= w < cfg.lateral_window:
        return None
    scale = (cfg.lateral_window / w) ** 2
    v = geometry.vehicle
    return Terminal(float(geometry.target[2]), cfg.w_terminal_position * scale, v.front_length, v.rear_overhang)


def terminal_error(terminal: Terminal, dx: float, dy: float) -> tuple[float, float]:
    """(along, across) the target's heading of an end's offset (dx, dy) from the target."""
    c, s = math.cos(terminal.heading), math.sin(terminal.heading)
    return c * dx + s * dy, -s * dx + c * dy
