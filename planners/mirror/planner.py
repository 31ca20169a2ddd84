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

A planner is a core (``core.py``: the parts every strategy shares, and ``scp.py``: one
candidate solved by Algorithm I inside a linearisation loop) and a strategy
(``strategies/``): which candidates a call solves and which plan it returns.
"""

from __future__ import annotations

import time

from mirrorpark_env.scenario import ScenarioGeometry
from mirrorpark_env.vehicle import VehicleState

from ..base import PlanStats
from .config import MirrorPlannerConfig
from .core import PlannerCore
from .mirror_line import MirrorLine
from .plans import Candidate, Plan
from .strategies.aimed import AimedCandidates, ColdStart
from .strategies.base import Strategy
from .strategies.guided import Guided
from .strategies.multistart import MultiStart
from .strategies.paper import PaperMultiStart

# Each strategy config's ``kind`` and the strategy it configures.
STRATEGIES: dict[str, type[Strategy]] = {
    "aimed": AimedCandidates,
    "cold": ColdStart,
    "guided": Guided,
    "multistart": MultiStart,
    "paper": PaperMultiStart,
}


class MirrorPlanner:
    """Plans toward the mirrored target from a measured vehicle state."""

    def __init__(self, geometry: ScenarioGeometry, config: MirrorPlannerConfig | None = None):
        self.cfg = config or MirrorPlannerConfig()
        kind = STRATEGIES[self.cfg.strategy.kind]
        self.core = PlannerCore(geometry, self.cfg.core, kind.rounds(self.cfg.strategy))
        self.strategy = kind(self.core, self.cfg.strategy)

    @property
    def line(self) -> MirrorLine:
        """The slot's mirror line (Theorem 1 for parallel slots, Eqs. 5-6 otherwise)."""
        return self.core.line

    @property
    def last_stats(self) -> PlanStats | None:
        """The latest call's statistics, a failed one's too."""
        return self.core.last_stats

    @last_stats.setter
    def last_stats(self, stats: PlanStats | None) -> None:
        self.core.last_stats = stats

    def prepare(self) -> None:
        """Build what depends on the slot alone, once per episode (the policy does it at
        reset, as a car does once it has measured the slot)."""
        self.strategy.prepare()

    def plan(self, state: VehicleState, candidates: list[Candidate] | None = None) -> Plan | None:
        """Best collision-free plan from ``state``, or None; statistics of the call, a failed
        one included, in ``last_stats``. ``candidates``: solve these (the multi-start
        strategies only) instead of the strategy's own."""
        t0 = time.perf_counter()
        self.core.clock.reset()
        self.core.budget.reset()
        xi0 = state.as_array()
        start = self.core.checks.start(xi0)
        if candidates is None:
            return self.strategy.plan(state, xi0, start, t0)
        if not isinstance(self.strategy, MultiStart):
            raise ValueError(f"candidates: only the multi-start strategies take them, not {self.cfg.strategy.kind!r}")
        return self.strategy.plan_candidates(state, xi0, start, t0, candidates)

    def rollout(self, xi0, u_planned, cand: Candidate):
        """Real states at the control steps when executing planned commands (Eq. 42 after the switch)."""
        return self.core.rollout(xi0, u_planned, cand)
