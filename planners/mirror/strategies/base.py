"""What a strategy is: the part of a mirror planner that decides which candidates a call
solves on the shared parts (``core.py``) and which plan it returns, as an ``Outcome``. The
planner (``planner.py``) owns the call: it resets the clock and the budget, times the call
and records its statistics."""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np

from mirrorpark_env.vehicle import VehicleState

from ..checks import Start
from ..core import PlannerCore
from ..linearisation import RoundsFactory, jacobians
from ..plans import Candidate, Plan, Tally


@dataclass(frozen=True, eq=False)
class Outcome:
    """A call's answer: its plan (None: none), status ("ok", "partial", "infeasible", ...),
    the work it took, the plan's cost (NaN: none), ``progress``: what the policy watches to
    tell a call that brings the car nearer (lower is nearer), whether a wall-clock safety net
    was hit, and ``detail``: what the strategy tried, for reports and tests."""

    plan: Plan | None
    status: str
    tally: Tally
    cost: float = math.nan
    progress: float = math.inf
    safety_net: bool = False
    detail: dict[str, Any] = field(default_factory=dict)


class Strategy(ABC):
    """A planning call's choices over the slot's parts, under the strategy's own ``config``.

    The constructors take the parts a strategy uses from ``core``; no strategy keeps the
    core itself."""

    takes_candidates: ClassVar[bool] = False  # whether ``plan`` accepts given candidates

    def __init__(self, core: PlannerCore, config) -> None:
        self.cfg = config
        self.g, self.cc, self.lines = core.geometry, core.cfg, core.lines
        self.checks, self.seeds, self.scp = core.checks, core.seeds, core.scp
        self.clock, self.budget = core.clock, core.budget

    @classmethod
    def rounds(cls, config) -> RoundsFactory:
        """The linearisation its candidates are solved on (SCP's Jacobians unless overridden)."""
        return jacobians()

    def prepare(self) -> None:  # noqa: B027 - most strategies have nothing to build per slot
        """Build what depends on the slot alone, once per episode (the policy calls it at reset)."""

    @abstractmethod
    def plan(
        self, state: VehicleState, xi0: np.ndarray, start: Start, candidates: list[Candidate] | None = None
    ) -> Outcome:
        """The call's outcome from ``state`` (``xi0``: as an array; ``start``: its clearance;
        ``candidates``: given ones, where ``takes_candidates``)."""
