"""What one planning call produces: the candidate manoeuvre, the plan in the real frame and
the work it took."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..base import PlanStats
from .mirror_line import MirrorLine


@dataclass(frozen=True)
class Tally:
    """Work done: SCP rounds, QP solves and branch-and-bound nodes (a call sums its solves')."""

    iterations: int = 0
    qp_solves: int = 0
    nodes: int = 0

    def __add__(self, other: Tally) -> Tally:
        return Tally(self.iterations + other.iterations, self.qp_solves + other.qp_solves, self.nodes + other.nodes)


@dataclass(frozen=True)
class Candidate:
    """A manoeuvre to optimise: the first gear and the switch step."""

    direction: int  # +1: forward first, -1: reverse first
    switch: int | None  # switch step s, None for a plan without a switch


@dataclass(frozen=True, eq=False)
class Plan:
    """A plan in the real frame, ready to execute."""

    commands: np.ndarray  # (N, 2) real a_cmd, delta_cmd (negated after the switch)
    states: np.ndarray  # (N + 1, 6) predicted real states at the control steps
    candidate: Candidate
    switch_point: tuple[float, float] | None
    mirror: MirrorLine
    planned_states: np.ndarray  # (N + 1, 6) the monodirectional, mirror-frame states
    cost: float
    terminal_error: tuple[float, float]  # [m], [rad] predicted real error at step N
    collision_free: bool
    stats: PlanStats | None = field(default=None)
    goal: tuple[float, float, float] | None = None  # the real pose it was planned toward (mirrored through S)
