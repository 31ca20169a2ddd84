"""The mirrored-target planner: one plan = one direction switch (paper II.C-E).

Variables: planned states xi_0..xi_N, controls u_0..u_{N-1}, the switch point S. The planned
motion is monodirectional; at the switch step s the car stands (v_s = 0) and from then on
executes negated commands (Eq. 42), so its real pose is the planned pose reflected
through S: real = (2 S - p, theta) (Theorem 2, ``frames.py``). Exactly so with the
actuator lags too: at s the planned lag states are the real ones negated, which the
dynamics row of step s encodes (``FLIP``). Consequences, all linear for fixed s (``qp.py``):

- the mirrored target is 2 S - p_target; the cost pulls the planned poses to it, which is
  the real pose error after the switch (and terminal error at N; ``cost.py``);
- in the natural order S lies in Theorem 1's band (parallel), beyond Eqs. 5-6 (others);
- obstacle constraints are written on the real body: before s on p + R(theta) c, after s
  on 2 S - p + R(theta) c (the flipped body against obstacles reflected through S).

A planner is the slot's parts (``core.py``: those every strategy shares, with ``scp.py``
solving one candidate by Algorithm I inside a linearisation loop) and a strategy
(``strategies/``, chosen by the config's preset, ``presets.py``): which candidates a call
solves and which plan it returns. The planner owns the call: it resets the call's clock
and budget, times it and records its statistics.
"""

from __future__ import annotations

import time
from dataclasses import replace

import numpy as np

from mirrorpark_env.scenario import ScenarioGeometry
from mirrorpark_env.vehicle import VehicleState

from ..base import PlanStats
from .config import MirrorPlannerConfig
from .core import build_core
from .mirror_line import MirrorLine
from .plans import Candidate, Plan
from .presets import strategy_for


class MirrorPlanner:
    """Plans toward the mirrored target from a measured vehicle state."""

    def __init__(self, geometry: ScenarioGeometry, config: MirrorPlannerConfig | None = None):
        self.cfg = config or MirrorPlannerConfig()
        kind = strategy_for(self.cfg.strategy)
        self.core = build_core(geometry, self.cfg.core, kind.rounds(self.cfg.strategy))
        self.strategy = kind(self.core, self.cfg.strategy)
        self.last_stats: PlanStats | None = None  # the latest call's, a failed one's too

    @property
    def line(self) -> MirrorLine:
        """The slot's mirror line (Theorem 1 for parallel slots, Eqs. 5-6 otherwise)."""
        return self.core.lines.slot

    def prepare(self) -> None:
        """Build what depends on the slot alone, once per episode (the policy does it at
        reset, as a car does once it has measured the slot)."""
        self.strategy.prepare()

    def plan(self, state: VehicleState, candidates: list[Candidate] | None = None) -> Plan | None:
        """Best collision-free plan from ``state``, or None; statistics of the call, a failed
        one included, in ``last_stats``. ``candidates``: solve these (the multi-start
        strategies only) instead of the strategy's own."""
        if candidates is not None and not self.strategy.takes_candidates:
            raise ValueError(f"candidates: only the multi-start strategies take them, not {self.cfg.strategy.kind!r}")
        t0 = time.perf_counter()
        core = self.core
        core.clock.reset()
        core.budget.reset()
        xi0 = state.as_array()
        out = self.strategy.plan(state, xi0, core.checks.start(xi0), candidates)
        detail = {
            **out.detail,
            "progress": out.progress,
            "safety_net": out.safety_net,
            "stages_ms": core.clock.ms(),
            "budget_spent": core.budget.spent,
        }
        t = out.tally
        stats = PlanStats(time.perf_counter() - t0, out.status, t.iterations, t.qp_solves, t.nodes, out.cost, detail)
        self.last_stats = stats
        return replace(out.plan, stats=stats) if out.plan is not None else None

    def rollout(self, xi0: np.ndarray, u_planned: np.ndarray, cand: Candidate) -> np.ndarray:
        """Real states at the control steps when executing planned commands (Eq. 42 after the switch)."""
        return self.core.rollouts.steps(xi0, u_planned, cand)
