"""The parts of a mirror planner that every strategy shares, assembled once per slot.

The planning model and its rollouts, the QP of a round (``qp.py``) with its solvers, the
mirror line, the checks, the shape seeds and the candidate solver (``scp.py``). A strategy
(``strategies/``) decides which candidates a call solves and which plan it returns; it
records the call's statistics through ``finish``.
"""

from __future__ import annotations

import math
import time
from dataclasses import replace

import numpy as np

from mirrorpark_env.angles import unwrap_near
from mirrorpark_env.scenario import ScenarioGeometry
from mirrorpark_env.vehicle import TruthModel

from ..base import PlanStats
from .checks import Checks
from .config import CoreConfig
from .frames import real_commands
from .linearisation import RoundsFactory
from .mirror_line import MirrorLine, mirror_line
from .model import PlanningModel
from .obstacles import ObstacleRows
from .plans import Candidate, Plan
from .qp import MirrorQP
from .scp import SCP
from .seeds import ShapeSeeds
from .solvers import BranchAndBound, PiqpQP
from .stages import StageClock


class CallBudget:
    """QP solves left to the current call (``CoreConfig.call_qp_budget``; None: no limit)."""

    def __init__(self, limit: int | None):
        self.limit = limit
        self.left: float = math.inf

    def reset(self) -> None:
        self.left = math.inf if self.limit is None else self.limit

    def spend(self, solves: int) -> None:
        self.left -= solves

    @property
    def spent(self) -> bool:
        return self.left <= 0


class PlannerCore:
    """A slot's planning parts under ``cfg``, with candidates solved by ``rounds``' linearisation."""

    def __init__(self, geometry: ScenarioGeometry, cfg: CoreConfig, rounds: RoundsFactory):
        self.g, self.p, self.cfg = geometry, geometry.vehicle, cfg
        self.N = cfg.horizon
        self.model = PlanningModel(self.p, cfg.dt, cfg.model_substeps)
        self.coarse = TruthModel(self.p, cfg.dt, cfg.dt / cfg.model_substeps)  # the planning model's rollouts
        e = cfg.qp_tolerance
        self.qp_backend = PiqpQP(e, 0.1 * e, kkt_solver=cfg.kkt_solver, eps_gap=(e, 0.1 * e))
        self.miqp = BranchAndBound(self.qp_backend, cfg.node_limit, cfg.time_limit_s)
        self.line = mirror_line(geometry, margin=cfg.mirror_margin)
        self.qp = MirrorQP(self.p, cfg, ObstacleRows(geometry, cfg.obstacle_margin, cfg.horizon, cfg.model_substeps))
        self.checks = Checks(geometry, cfg)
        self.shape_seeds = ShapeSeeds(geometry, cfg, self.coarse)
        self.scp = SCP(self, rounds)
        self.last_stats: PlanStats | None = None  # the latest call's, a failed one's too
        self.clock = StageClock()  # the current call's time per stage (``stages.py``)
        self.budget = CallBudget(cfg.call_qp_budget)  # the current call's QP solves left

    def line_from(self, theta: float) -> MirrorLine:
        """The mirror line for a plan from heading ``theta``: Theorem 1's (parallel), else
        Eqs. (5), (6) bound by the heading change still to go."""
        if self.line.fixed:
            return self.line
        psi = min(abs(unwrap_near(self.g.target[2], theta) - theta), math.pi / 2)
        return mirror_line(self.g, psi=psi, margin=self.cfg.mirror_margin)

    def rollout_half(self, xi0: np.ndarray, u_planned: np.ndarray, cand: Candidate) -> np.ndarray:
        """Real states at every half step: (2N + 1, 6); even rows are the control steps."""
        sub = self.coarse.rollout(xi0, real_commands(u_planned, cand))[:, :6]
        return np.concatenate([xi0[None], sub])

    def rollout(self, xi0: np.ndarray, u_planned: np.ndarray, cand: Candidate) -> np.ndarray:
        """Real states at the control steps when executing planned commands (Eq. 42 after the switch)."""
        return self.rollout_half(xi0, u_planned, cand)[:: self.cfg.model_substeps]

    def finish(self, t0: float, status: str, totals: dict, cost: float, detail: dict, best: Plan | None) -> Plan | None:
        """Record a call's statistics (``last_stats``, with the time per stage in
        ``detail["stages_ms"]``) and return its plan carrying them."""
        detail = {**detail, "stages_ms": self.clock.ms(), "budget_spent": self.budget.spent}
        stats = PlanStats(
            time.perf_counter() - t0, status, totals["iterations"], totals["qp_solves"], totals["nodes"], cost, detail
        )
        self.last_stats = stats
        return replace(best, stats=stats) if best is not None else None
