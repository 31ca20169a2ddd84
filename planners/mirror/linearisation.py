"""The linear models one candidate's rounds are solved on, behind one interface (``Rounds``).

- ``Jacobians`` (sequential convex programming, every strategy but the paper's): each
  round linearises the planning model exactly about the reference rollout, after
  Algorithm I has added the reference's colliding steps. A round's rollout replaces the
  reference only where it lowers the merit; otherwise the trust region tightens.
- ``PaperModel`` (``mirror-paper``): Eqs. (22)-(32), linear about one angle with a speed
  per step in the v terms. Every round is taken; the rounds end once the rollout is clear
  and the model's speeds and angle have settled.

A ``Rounds`` object lives for one candidate solve (``scp.SCP.solve``); ``factory(config)``
gives the function that makes one, so that a strategy names its linearisation once.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable
from typing import Any

import numpy as np

from .checks import converged_to
from .config import PaperConfig
from .frames import FLIP, XI_TH, XI_V, planned_controls, to_planned
from .plans import Candidate


class Rounds(ABC):
    """One candidate's rounds: the first reference, each round's model, and whether to go on.

    ``core`` is the planner's ``PlannerCore`` (its model, checks, shape seeds and config)."""

    trust: bool  # whether the QP carries SCP's trust region about the reference
    trust_scale: float = 1.0

    def __init__(self, core: Any, xi0: np.ndarray, cand: Candidate, theta_t: float, goal: np.ndarray):
        self.core, self.xi0, self.cand, self.theta_t, self.goal = core, xi0, cand, theta_t, goal

    @abstractmethod
    def first(self, seed: np.ndarray | None, line) -> tuple[np.ndarray, np.ndarray] | None:
        """(real rollout at half steps, planned commands) to score as the first reference, or None."""

    @abstractmethod
    def model(self, ref, theta_set: dict, start) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(A, B, c) of this round, per step, in the planned frame."""

    @abstractmethod
    def after(self, ref, new, hits: list, usable: bool, st: dict) -> tuple[Any, bool]:
        """(the next reference, stop) once a round's rollout ``new`` is scored."""


class Jacobians(Rounds):
    """SCP: exact Jacobians about each accepted rollout, inside a trust region."""

    trust = True

    def first(self, seed, line):
        # Seed: a moving reference of the manoeuvre's shape. (The paper's form, Eqs. 22-27,
        # moves the car at its nominal speed even where the real speed is zero; linearising
        # about that standstill would freeze the heading.) The seed is a plan too.
        core = self.core
        real = seed if seed is not None else core.shape_seeds.seed(self.xi0, self.cand, line)
        cfg = core.cfg
        return real, planned_controls(real, self.cand, core.p, cfg.dt, cfg.model_substeps)

    def model(self, ref, theta_set, start):
        """Algorithm I on the reference (its colliding steps join ``theta_set``), then the
        exact Jacobians about it."""
        core, cand = self.core, self.cand
        for i, k in core.checks.collisions(ref.real, 0.0, start, ref.pen):
            theta_set[(i, k)] = None
        lin_at = to_planned(ref.real, cand, core.cfg.model_substeps)
        if cand.switch is not None:  # step s starts from the flipped lag states
            lin_at[cand.switch] = FLIP @ lin_at[cand.switch]
        return core.model.jacobian_linearisation(lin_at, ref.u)

    def after(self, ref, new, hits, usable, st):
        cfg = self.core.cfg
        if new.merit < ref.merit - 1e-6:
            converged = converged_to(new.real, ref.real, cfg)
            self.trust_scale = max(self.trust_scale / 2.0, 0.25)
            if usable and (converged or self.core.checks.settled(new.real, self.goal, self.theta_t)):
                st["converged"] = True  # not stopped by the round cap (the aimed strategy refines on)
                return new, True
            return new, False
        self.trust_scale *= 4.0
        return ref, self.trust_scale > cfg.max_trust_scale


class PaperModel(Rounds):
    """Eqs. (22)-(32) about a linearising angle, with a speed per step in the v terms. Both
    start as 1 m/s in the plan's gear about the mean of the start and goal headings (or, with
    ``paper_first="seed"``, from the seed's rollout); ``paper_speed`` / ``paper_angle`` =
    "previous" take them from each round's rollout (the paper leaves the speed open and
    draws the angle, Fig. 13, "close to the average yaw angle of the parking path")."""

    trust = False

    def __init__(self, core, xi0, cand, theta_t, goal, config: PaperConfig):
        super().__init__(core, xi0, cand, theta_t, goal)
        self.pc = config
        self.angle = 0.5 * (xi0[XI_TH] + theta_t)
        self.v = np.full(core.N, 1.0 * cand.direction)
        self.lin = core.model.paper_linearisation(core.N, self.angle, self.v)

    def first(self, seed, line):
        if self.pc.paper_first == "seed" and seed is not None:
            self.update(seed)  # the seed's rollout as round zero
        return None

    def model(self, ref, theta_set, start):
        return self.lin

    def after(self, ref, new, hits, usable, st):
        settled = self.update(new.real)
        return (ref, True) if not hits and settled else (new, False)

    def update(self, real: np.ndarray) -> bool:
        """Re-linearise about a rollout (half steps, real frame); True: nothing moved beyond
        the config's tolerances (or nothing is taken from rollouts)."""
        pc, core, d = self.pc, self.core, self.cand.direction
        if pc.paper_speed == "nominal" and pc.paper_angle == "ends":
            return True
        planned = to_planned(real, self.cand, core.cfg.model_substeps)
        settled = True
        if pc.paper_speed == "previous":  # Eq. (31)'s v_i: the speeds just driven
            v = d * np.maximum(d * planned[: core.N, XI_V], pc.paper_speed_floor)
            settled = float(np.max(np.abs(v - self.v))) <= pc.paper_speed_tolerance
            self.v = v
        if pc.paper_angle == "previous":  # the average yaw of the path just driven
            angle = float(np.mean(planned[:, XI_TH]))
            settled = settled and abs(angle - self.angle) <= pc.paper_angle_tolerance
            self.angle = angle
        if not settled:
            self.lin = core.model.paper_linearisation(core.N, self.angle, self.v)
        return settled


RoundsFactory = Callable[..., Rounds]


def jacobians() -> RoundsFactory:
    """SCP's rounds."""
    return Jacobians


def paper_model(config: PaperConfig) -> RoundsFactory:
    """The paper model's rounds under ``config``'s choices."""
    return lambda core, xi0, cand, theta_t, goal: PaperModel(core, xi0, cand, theta_t, goal, config)
