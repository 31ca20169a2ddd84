"""What a strategy is: the part of a mirror planner that decides which candidates a call
solves on the shared core (``core.py``) and which plan it returns."""

from __future__ import annotations

from abc import ABC, abstractmethod

import numpy as np

from mirrorpark_env.vehicle import VehicleState

from ..checks import Start
from ..core import PlannerCore
from ..linearisation import RoundsFactory, jacobians
from ..plans import Plan


class Strategy(ABC):
    """A planning call's choices over ``core``, under the strategy's own ``config``."""

    def __init__(self, core: PlannerCore, config) -> None:
        self.core, self.cfg = core, config

    @classmethod
    def rounds(cls, config) -> RoundsFactory:
        """The linearisation its candidates are solved on (SCP's Jacobians unless overridden)."""
        return jacobians()

    def prepare(self) -> None:  # noqa: B027 - most strategies have nothing to build per slot
        """Build what depends on the slot alone, once per episode (the policy calls it at reset)."""

    @abstractmethod
    def plan(self, state: VehicleState, xi0: np.ndarray, start: Start, t0: float) -> Plan | None:
        """The call's plan from ``state`` (``xi0``: as an array; ``start``: its clearance;
        ``t0``: when the call began), or None; its statistics via ``core.finish``."""
