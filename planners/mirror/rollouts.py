"""The planning model's rollouts: a plan's commands executed from a state, the switch's
negated commands included (Eq. 42), on the truth model at the planner's half steps."""

from __future__ import annotations

import numpy as np

from mirrorpark_env.vehicle import TruthModel, VehicleParams

from .frames import real_commands
from .plans import Candidate


class Rollouts:
    """Real states of planned commands at ``substeps`` per control step of ``dt``."""

    def __init__(self, params: VehicleParams, dt: float, substeps: int):
        self.substeps = substeps
        self.truth = TruthModel(params, dt, dt / substeps)

    def half(self, xi0: np.ndarray, u_planned: np.ndarray, cand: Candidate) -> np.ndarray:
        """Real states at every half step: (substeps N + 1, 6); every ``substeps``-th row is a control step."""
        return self.commands(xi0, real_commands(u_planned, cand))

    def steps(self, xi0: np.ndarray, u_planned: np.ndarray, cand: Candidate) -> np.ndarray:
        """Real states at the control steps when executing planned commands (Eq. 42 after the switch)."""
        return self.half(xi0, u_planned, cand)[:: self.substeps]

    def commands(self, xi0: np.ndarray, u_real: np.ndarray) -> np.ndarray:
        """Real states at every half step under real commands (a plan's ``commands``)."""
        return np.concatenate([xi0[None], self.truth.rollout(xi0, u_real)[:, :6]])
