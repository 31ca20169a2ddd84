"""Checks and scores of a plan's rollout: exact footprint clearance, the truth model's
verdict, the merit that SCP accepts steps by (``cost.true_cost`` plus the exact penalty on
penetration), and the safe stop."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from mirrorpark_env.angles import unwrap_near
from mirrorpark_env.scenario import ScenarioGeometry
from mirrorpark_env.vehicle import TruthModel

from ..common.brake import BrakeRollout
from ..common.clearance import gap_kernel, gaps, required_gap
from ..common.tracker import hold_accel
from .config import CoreConfig
from .cost import Terminal, merit, terminal_for, true_cost
from .frames import XI_A, XI_D, XI_V, real_commands
from .mirror_line import MirrorLine
from .plans import Candidate, Plan

BRAKE_STEPS = 30  # control steps of the brake checked after a plan (3 s: then under 1 mm/s)


@dataclass(frozen=True)
class Start:
    """Where a planning call starts: rear axle (x, y) and its gap to the nearest obstacle."""

    x: float
    y: float
    gap: float


class Checks:
    """Clearance, truth and cost of rollouts in one scenario."""

    def __init__(self, geometry: ScenarioGeometry, cfg: CoreConfig):
        self.g, self.cfg = geometry, cfg
        self.p = geometry.vehicle
        self.N = cfg.horizon
        self.truth = TruthModel(self.p, cfg.dt, 0.01)
        self.brake = BrakeRollout(self.truth)  # compiled: common/brake.py
        self.terminal = terminal_for(geometry, cfg)  # the target's terminal cost (None: one weight)

    def terminal_toward(self, goal) -> Terminal | None:
        """The end's position cost toward ``goal``: the target's (``cost.terminal_for``) where
        ``goal`` is the target, else one weight (None)."""
        return self.terminal if self.terminal is not None and same_pose(goal, self.g.target) else None

    def start(self, xi0: np.ndarray) -> Start:
        return Start(float(xi0[0]), float(xi0[1]), float(gaps(self.g.checker, xi0[None, :3])[0]))

    # ------------------------------------------------------------- clearance
    def penetration(self, real_half: np.ndarray) -> np.ndarray:
        """Footprint penetration of every half step into every obstacle, (2N + 1, K): the
        checker's values bit for bit, from its compiled kernel."""
        return gap_kernel(self.g.checker).penetration(real_half)

    def clearance(self, poses: np.ndarray, margin: float, start: Start) -> np.ndarray | float:
        """Clearance each pose must keep: ``margin``, relieved near a start that is closer
        than that (``common.clearance``: the car may leave a tight spot, not tighten it)."""
        return required_gap(poses, (start.x, start.y), start.gap, margin)

    def collisions(
        self, real_half: np.ndarray, margin: float, start: Start, pen: np.ndarray | None = None
    ) -> list[tuple[int, int]]:
        """(step, obstacle) pairs to constrain: steps next to any half step closer than
        ``margin`` (``pen``: the rollout's ``penetration``, if already computed)."""
        pen = self.penetration(real_half) if pen is None else pen
        need = self.clearance(real_half, margin, start) if margin > 0 else 0.0
        hit = pen > -1e-9 - np.reshape(need, (-1, 1))
        out = set()
        m = self.cfg.model_substeps
        for h, k in zip(*np.nonzero(hit)):
            for j in {h // m, -(-h // m)}:  # the control steps around half step h
                if 1 <= j <= self.N:
                    out.add((int(j), int(k)))
        return sorted(out)

    def clear_and_stopped(
        self, poses: list[np.ndarray], end: np.ndarray, start: Start, clearance: float = 0.005
    ) -> bool:
        q = np.concatenate(poses)
        pen = -gaps(self.g.checker, q)  # the largest penetration per pose
        clear = bool(np.all(pen < -self.clearance(q, clearance, start)))
        return bool(clear and abs(end[XI_V]) < 0.05)

    def truth_safe(self, xi0: np.ndarray, u_real: np.ndarray, start: Start, clearance: float = 0.005) -> bool:
        """On the environment's own model (0.01 s sub-steps) the plan keeps clear and ends
        standing, and so does the policy's brake after its last command: a plan may end at
        zero speed with the acceleration still high (a hard stop), and if no next plan
        comes, the lag carries the car on until the brake has caught it."""
        sub = self.truth.rollout(xi0, u_real)
        tail = self.brake_tail(sub[-1, :6])
        return self.clear_and_stopped([sub[:, :3], tail], sub[-1, :6], start, clearance)

    def brake_tail(self, state: np.ndarray, steps: int = BRAKE_STEPS) -> np.ndarray:
        """Sub-step poses (steps * n, 3) under the policy's brake from ``state``: the hold law
        on the acceleration (``tracker.hold_accel``), the steering held where it is."""
        return self.brake.tail(state, steps)

    # ------------------------------------------------------------------ cost
    def true_cost(self, real: np.ndarray, goal: np.ndarray, theta_t: float) -> tuple[float, float, float]:
        """(cost, position error, heading error) of real states at the control steps (``cost.true_cost``)."""
        return true_cost(self.cfg, real, goal, theta_t, self.terminal_toward(goal))

    def merit(self, real_half: np.ndarray, goal: np.ndarray, theta_t: float, pen: np.ndarray | None = None) -> float:
        """True cost of a rollout plus the exact penalty on its footprint's penetration
        (``pen``: its ``penetration``, if already computed)."""
        cost, _, _ = self.true_cost(real_half[:: self.cfg.model_substeps], goal, theta_t)
        return merit(self.cfg, cost, (self.penetration(real_half) if pen is None else pen).max(axis=1))

    def settled(self, real_half: np.ndarray, goal: np.ndarray, theta_t: float) -> bool:
        """The rollout ends standing this close to its goal: another SCP round would only polish it."""
        _, pos_err, th_err = self.true_cost(real_half[:: self.cfg.model_substeps], goal, theta_t)
        return pos_err < self.cfg.settle_position and th_err < self.cfg.settle_heading

    # ------------------------------------------------------------- safe stop
    def safe_prefix(
        self,
        xi0: np.ndarray,
        cand: Candidate,
        u_planned: np.ndarray,
        hits: list[tuple[int, int]],
        goal: np.ndarray,
        theta_t: float,
        start: Start,
        line: MirrorLine,
    ) -> Plan | None:
        """The colliding plan's start, braking to a stop before its first contact.

        Verified on the environment's own model with the same clearance as full plans;
        used when no candidate yields a clear plan that makes progress.
        """
        p = self.p
        u_real = real_commands(u_planned, cand)
        first = min(i for i, _ in hits)
        for cut in (first - 3, first - 8, first - 15):
            if cut < 3:
                break
            s, states, poses, cmds = xi0, [xi0], [], []
            for i in range(self.N):
                if i < cut:
                    a, d = u_real[i]
                else:  # brake to a stop, wheels held
                    a = hold_accel(p, s[XI_V], s[XI_A])
                    d = s[XI_D]
                sub = self.truth.step(s, a, d)
                poses.append(sub[:, :3])
                s = sub[-1, :6]
                states.append(s)
                cmds.append((a, d))
            poses.append(self.brake_tail(s))  # and the policy's brake after it, as truth_safe
            if self.clear_and_stopped(poses, s, start):
                real = np.array(states)
                cost, pos_err, th_err = self.true_cost(real, goal, theta_t)
                sw = cand.switch if cand.switch is not None and cand.switch < cut else None
                S = tuple(real[sw, :2]) if sw else None
                g = (float(goal[0]), float(goal[1]), float(theta_t))
                plan_cand = Candidate(cand.direction, sw)
                return Plan(np.array(cmds), real, plan_cand, S, line, real, cost, (pos_err, th_err), True, goal=g)
        return None


def converged_to(real: np.ndarray, ref: np.ndarray, cfg: CoreConfig) -> bool:
    """An SCP round's rollout lies within the convergence tolerances of its reference."""
    dp = np.hypot(real[:, 0] - ref[:, 0], real[:, 1] - ref[:, 1]).max()
    dth = np.abs(real[:, 2] - ref[:, 2]).max()
    return dp < cfg.converge_position and dth < cfg.converge_heading


def same_pose(goal, target) -> bool:
    """Within 1e-6 in position and heading (headings compared modulo 2 pi)."""
    return (
        math.hypot(goal[0] - target[0], goal[1] - target[1]) < 1e-6
        and abs(unwrap_near(target[2], goal[2]) - goal[2]) < 1e-6
    )
