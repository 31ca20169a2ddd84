"""The parts of a mirror planner that every strategy shares, assembled once per slot.

The mirror lines, the planning model and its rollouts, the QP of a round (``qp.py``) with
its solvers, the checks, the shape seeds, the candidate solver (``scp.py``) and the call's
bookkeeping (``stages.py``: its clock and work budget). A strategy (``strategies/``)
receives the parts it uses when it is built and decides which candidates a call solves;
the planner (``planner.py``) owns the call.
"""

from __future__ import annotations

from dataclasses import dataclass

from mirrorpark_env.scenario import ScenarioGeometry

from .checks import Checks
from .config import CoreConfig
from .linearisation import RoundParts, RoundsFactory
from .mirror_line import SlotLines
from .model import PlanningModel
from .obstacles import ObstacleRows
from .qp import MirrorQP
from .rollouts import Rollouts
from .scp import SCP
from .seeds import ShapeSeeds
from .solvers import BranchAndBound, PiqpQP
from .stages import CallBudget, StageClock


@dataclass(frozen=True, eq=False)
class PlannerCore:
    """A slot's planning parts under ``cfg`` (built by ``build_core``)."""

    geometry: ScenarioGeometry
    cfg: CoreConfig
    lines: SlotLines
    model: PlanningModel
    rollouts: Rollouts
    qp: MirrorQP
    qp_solver: PiqpQP
    miqp: BranchAndBound
    checks: Checks
    seeds: ShapeSeeds
    scp: SCP
    clock: StageClock  # the current call's time per stage
    budget: CallBudget  # the current call's QP solves left


def build_core(geometry: ScenarioGeometry, cfg: CoreConfig, rounds: RoundsFactory) -> PlannerCore:
    """The parts for ``geometry`` under ``cfg``, candidates solved by ``rounds``' linearisation."""
    p = geometry.vehicle
    rollouts = Rollouts(p, cfg.dt, cfg.model_substeps)
    e = cfg.qp_tolerance
    qp_solver = PiqpQP(e, 0.1 * e, kkt_solver=cfg.kkt_solver, eps_gap=(e, 0.1 * e))
    miqp = BranchAndBound(qp_solver, cfg.node_limit, cfg.time_limit_s)
    lines = SlotLines(geometry, cfg.mirror_margin)
    checks = Checks(geometry, cfg)
    seeds = ShapeSeeds(geometry, cfg, rollouts.truth)
    model = PlanningModel(p, cfg.dt, cfg.model_substeps)
    parts = RoundParts(cfg, model, checks, seeds)
    qp = MirrorQP(p, cfg, ObstacleRows(geometry, cfg.obstacle_margin, cfg.horizon, cfg.model_substeps))
    clock, budget = StageClock(), CallBudget(cfg.call_qp_budget)
    scp = SCP(
        geometry=geometry,
        lines=lines,
        parts=parts,
        rollouts=rollouts,
        qp=qp,
        qp_solver=qp_solver,
        miqp=miqp,
        budget=budget,
        clock=clock,
        rounds=rounds,
    )
    return PlannerCore(geometry, cfg, lines, model, rollouts, qp, qp_solver, miqp, checks, seeds, scp, clock, budget)
