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
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from .checks import Checks, Start, converged_to
from .config import CoreConfig, PaperConfig
from .frames import FLIP, XI_TH, XI_V, planned_controls, to_planned
from .mirror_line import MirrorLine
from .model import PlanningModel
from .plans import Candidate
from .seeds import ShapeSeeds

if TYPE_CHECKING:  # for annotations only: scp.py builds the rounds
    from .scp import Reference


@dataclass(frozen=True, eq=False)
class RoundParts:
    """What rounds are built from: the core's settings, the planning model, the checks and
    the shape seeds (a first reference where no seed is given)."""

    cfg: CoreConfig
    model: PlanningModel
    checks: Checks
    seeds: ShapeSeeds


class Rounds(ABC):
    """One candidate's rounds: the first reference, each round's model, and whether to go on."""

    trust: bool  # whether the QP carries SCP's trust region about the reference
    trust_scale: float = 1.0

    def __init__(self, parts: RoundParts, xi0: np.ndarray, cand: Candidate, theta_t: float, goal: np.ndarray):
        self.cfg, self.planning, self.checks, self.seeds = parts.cfg, parts.model, parts.checks, parts.seeds
        self.p, self.N = parts.model.params, parts.cfg.horizon
        self.xi0, self.cand, self.theta_t, self.goal = xi0, cand, theta_t, goal

    @abstractmethod
    def first(self, seed: np.ndarray | None, line: MirrorLine) -> tuple[np.ndarray, np.ndarray] | None:
        """(real rollout at half steps, planned commands) to score as the first reference, or None."""

    @abstractmethod
    def model(self, ref: Reference | None, theta_set: dict, start: Start) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(A, B, c) of this round, per step, in the planned frame."""

    @abstractmethod
    def after(
        self, ref: Reference | None, new: Reference, hits: list, usable: bool
    ) -> tuple[Reference | None, bool, bool]:
        """(the next reference, stop, converged) once a round's rollout ``new`` is scored;
        converged: stopped because the rounds settled, not by a cap."""


class Jacobians(Rounds):
    """SCP: exact Jacobians about each accepted rollout, inside a trust region."""

    trust = True

    def first(self, seed, line):
        # Seed: a moving reference of the manoeuvre's shape. (The paper's form, Eqs. 22-27,
        # moves the car at its nominal speed even where the real speed is zero; linearising
        # about that standstill would freeze the heading.) The seed is a plan too.
        real = seed if seed is not None else self.seeds.seed(self.xi0, self.cand, line)
        cfg = self.cfg
        return real, planned_controls(real, self.cand, self.p, cfg.dt, cfg.model_substeps)

    def model(self, ref, theta_set, start):
        """Algorithm I on the reference (its colliding steps join ``theta_set``), then the
        exact Jacobians about it."""
        cand = self.cand
        for i, k in self.checks.collisions(ref.real, 0.0, start, ref.pen):
            theta_set[(i, k)] = None
        lin_at = to_planned(ref.real, cand, self.cfg.model_substeps)
        if cand.switch is not None:  # step s starts from the flipped lag states
            lin_at[cand.switch] = FLIP @ lin_at[cand.switch]
        return self.planning.jacobian_linearisation(lin_at, ref.u)

    def after(self, ref, new, hits, usable):
        cfg = self.cfg
        if new.merit < ref.merit - 1e-6:
            converged = converged_to(new.real, ref.real, cfg)
            self.trust_scale = max(self.trust_scale / 2.0, 0.25)
            if usable and (converged or self.checks.settled(new.real, self.goal, self.theta_t)):
                return new, True, True  # converged, not stopped by the round cap (the aimed strategy refines on)
            return new, False, False
        self.trust_scale *= 4.0
        return ref, self.trust_scale > cfg.max_trust_scale, False


class PaperModel(Rounds):
    """Eqs. (22)-(32) about a linearising angle, with a speed per step in the v terms. Both
    start as 1 m/s in the plan's gear about the mean of the start and goal headings (or, with
    ``paper_first="seed"``, from the seed's rollout); ``paper_speed`` / ``paper_angle`` =
    "previous" take them from each round's rollout (the paper leaves the speed open and
    draws the angle, Fig. 13, "close to the average yaw angle of the parking path")."""

    trust = False

    def __init__(self, parts: RoundParts, xi0, cand, theta_t, goal, config: PaperConfig):
        super().__init__(parts, xi0, cand, theta_t, goal)
        self.pc = config
        self.angle = 0.5 * (xi0[XI_TH] + theta_t)
        self.v = np.full(self.N, 1.0 * cand.direction)
        self.lin = self.planning.paper_linearisation(self.N, self.angle, self.v)

    def first(self, seed, line):
        if self.pc.paper_first == "seed" and seed is not None:
            self.update(seed)  # the seed's rollout as round zero
        return None

    def model(self, ref, theta_set, start):
        return self.lin

    def after(self, ref, new, hits, usable):
        settled = self.update(new.real)
        return (ref, True, False) if not hits and settled else (new, False, False)

    def update(self, real: np.ndarray) -> bool:
        """Re-linearise about a rollout (half steps, real frame); True: nothing moved beyond
        the config's tolerances (or nothing is taken from rollouts)."""
        pc, d = self.pc, self.cand.direction
        if pc.paper_speed == "nominal" and pc.paper_angle == "ends":
            return True
        planned = to_planned(real, self.cand, self.cfg.model_substeps)
        settled = True
        if pc.paper_speed == "previous":  # Eq. (31)'s v_i: the speeds just driven
            v = d * np.maximum(d * planned[: self.N, XI_V], pc.paper_speed_floor)
            settled = float(np.max(np.abs(v - self.v))) <= pc.paper_speed_tolerance
            self.v = v
        if pc.paper_angle == "previous":  # the average yaw of the path just driven
            angle = float(np.mean(planned[:, XI_TH]))
            settled = settled and abs(angle - self.angle) <= pc.paper_angle_tolerance
            self.angle = angle
        if not settled:
            self.lin = self.planning.paper_linearisation(self.N, self.angle, self.v)
        return settled


RoundsFactory = Callable[[RoundParts, np.ndarray, Candidate, float, np.ndarray], Rounds]


def jacobians() -> RoundsFactory:
    """SCP's rounds."""
    return Jacobians


def paper_model(config: PaperConfig) -> RoundsFactory:
    """The paper model's rounds under ``config``'s choices."""
    return lambda parts, xi0, cand, theta_t, goal: PaperModel(parts, xi0, cand, theta_t, goal, config)
