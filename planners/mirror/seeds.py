"""First references for SCP: where each plan's linearisation starts.

- ``TrackedSeed``: the planning model driven along a path (the geometric guide of
  ``guide.py``, or the cost to go's way on) by the shared path tracker, up to the path's
  first switch: a candidate (gear, switch step), a rollout and the goal of the plan.
- ``ShapeSeeds``: without a path, rollouts of the manoeuvre's classic shape for every
  candidate (both gears, two switch steps, no switch) and a few heading excursions,
  ranked by merit (a multi-start: 18 seeds roll out in about 0.2 ms compiled, an SCP takes tens).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from mirrorpark_env.angles import unwrap_near
from mirrorpark_env.scenario import ParkingType, ScenarioGeometry
from mirrorpark_env.vehicle import TruthModel, VehicleState

from ..common.path import Path
from ..common.tracker import PathTracker, TrackerConfig
from ..common.tracker_kernel import TrackedRollout
from .config import CoreConfig
from .frames import XI_TH, XI_Y
from .guide import Guide
from .mirror_line import MirrorLine
from .plans import Candidate
from .seed_kernel import SeedRollouts, seed_references

TURN = math.inf  # seed mode: steer toward the target heading in both segments


class TrackedSeed:
    """Tracks a path on the planning model (``coarse``: the truth model at half steps)."""

    def __init__(self, geometry: ScenarioGeometry, cfg: CoreConfig, coarse: TruthModel):
        self.p, self.N = geometry.vehicle, cfg.horizon
        self.target = np.array(geometry.target, float)
        self.tracker_cfg = TrackerConfig(cruise_speed=cfg.seed_speed, accel=cfg.seed_accel, decel=cfg.seed_accel)
        self._rollout = TrackedRollout(coarse)

    def seed(
        self, xi0: np.ndarray, guide: Guide, speed: float | None = None
    ) -> tuple[Candidate, np.ndarray, np.ndarray]:
        """(candidate, real rollout at half steps, goal pose) from tracking the guide's first
        two gear segments at cruise ``speed`` (default: the config's; accelerations scaled
        alike), cut so that the car stands by N."""
        poses = guide.path.poses
        end = guide.first_switch()
        for _ in range(3):
            path = Path.from_poses(poses[: end + 1])
            real, segs, reached = self.track(xi0, path, speed)
            if segs[-1] < 0 or reached[-1] >= end:  # stood at the portion's end within N
                break
            back = max(0, self.N - 20)  # cut where the car was 2 s before the horizon
            end = max(reached[back], 2)
        gear = path.direction[1]
        seg = np.asarray(segs)
        s = int(np.argmax(seg >= 1)) if (seg >= 1).any() else None
        if s is not None and (s < 2 or s > self.N - 2):
            s = None
        goal = self.target.copy() if end >= len(poses) - 1 else poses[end].copy()
        goal[2] = unwrap_near(goal[2], xi0[XI_TH])
        return Candidate(int(gear), s), real, goal

    def track(self, xi0: np.ndarray, path: Path, speed: float | None = None) -> tuple[np.ndarray, list[int], list[int]]:
        """Roll the planning model out under the path tracker for N steps: the half-step real
        states, the tracker's segment per control step (-1 once done), the pose index reached."""
        cfg = self.tracker_cfg
        if speed is not None:  # a slower or faster seed: the cusp at another step
            scale = speed / cfg.cruise_speed
            cfg = TrackerConfig(
                **{**cfg.model_dump(), "cruise_speed": speed, "accel": cfg.accel * scale, "decel": cfg.decel * scale}
            )
        real, segs, reached = self._rollout(PathTracker(path, self.p, cfg), xi0, self.N)  # compiled
        return real, segs.tolist(), reached.tolist()


class ShapeSeeds:
    """The multi-start seeds of a plan without a guide."""

    def __init__(self, geometry: ScenarioGeometry, cfg: CoreConfig, coarse: TruthModel):
        self.g, self.cfg, self.N = geometry, cfg, cfg.horizon
        self.rollouts = SeedRollouts(coarse)  # compiled: seed_kernel.py

    @property
    def first_direction(self) -> int:
        """Parallel parking reverses to the mirror line first; reverse and angle drive forward."""
        return -1 if self.g.parking_type is ParkingType.PARALLEL else 1

    def candidates(self, state: VehicleState, line: MirrorLine) -> list[Candidate]:
        """(direction, switch step) pairs to score: both directions (one while moving), two
        switch steps, and no switch."""
        first = self.first_direction
        if abs(state.v) > 0.1:
            dirs = [1 if state.v > 0 else -1]
        else:
            dirs = [first, -first]
        s_est = self._switch_estimate(state, line)
        steps = sorted({s_est, min(self.N - 15, max(12, int(1.6 * s_est)))})
        out = [Candidate(d, s) for d in dirs for s in steps]
        out += [Candidate(d, None) for d in dirs]  # no switch: straight on to the target
        return out

    def _switch_estimate(self, state: VehicleState, line: MirrorLine) -> int:
        off = line.offset((state.x, state.y))
        dist = abs(line.distance - off) + 0.5
        t = 2.0 * math.sqrt(dist / 1.0)  # accelerate then brake at about 1 m/s^2
        return int(min(max(round(t / self.cfg.dt), 8), self.N - 20))

    def ranked(
        self, xi0: np.ndarray, cands: list[Candidate], line: MirrorLine, merit: Callable[[np.ndarray], float]
    ) -> list[tuple[Candidate, np.ndarray]]:
        """Each candidate's best seed (by ``merit``), best candidates first."""
        pairs = [(c, sw) for c in cands for sw in ([None] if c.switch is None else [None, TURN, *self.cfg.seed_swings])]
        reals = self.seeds(xi0, pairs, line)
        scored = sorted(((merit(real), n) for n, real in enumerate(reals)), key=lambda t: t[0])
        out, seen = [], set()
        for _, n in scored:
            cand = pairs[n][0]
            if cand not in seen:
                seen.add(cand)
                out.append((cand, reals[n]))
        return out

    def seed(self, xi0: np.ndarray, cand: Candidate, line: MirrorLine, swing: float | None = None) -> np.ndarray:
        """A real rollout of the manoeuvre's classic shape, to linearise about first.

        Speed: a sine over each segment, sized to the distance the segment has to cover.
        Steering: a heading controller tracking the heading reference (``seed_references``).
        """
        return self.seeds(xi0, [(cand, swing)], line)[0]

    def seeds(
        self,
        xi0: np.ndarray,
        pairs: list[tuple[Candidate, float | None]],
        line: MirrorLine,
        target: tuple[float, float, float] | None = None,
    ) -> np.ndarray:
        """``seed`` of each (candidate, swing), rolled out together: (K, 2N + 1, 6).
        ``target``: the pose the shapes head for (default the slot's target pose)."""
        N, dt = self.N, self.cfg.dt
        tx, ty, tth = self.g.target if target is None else target
        tth = unwrap_near(tth, xi0[XI_TH])
        u_t = np.array([math.cos(tth), math.sin(tth)])
        S_guess = np.array([tx, ty]) + line.distance * np.array(line.normal)
        if not line.fixed:  # reverse, angle: out along the slot axis to the car's lane
            lam = (xi0[XI_Y] - S_guess[1]) / u_t[1] if abs(u_t[1]) > 1e-6 else 0.0
            S_guess = S_guess + max(lam, 0.0) * u_t
        p0 = xi0[:2]
        d2 = float(np.hypot(S_guess[0] - tx, S_guess[1] - ty)) + 0.3
        to_switch = float(np.hypot(*(S_guess - p0))) + 0.3  # first segment's distance with a switch
        to_target = float(np.hypot(tx - p0[0], ty - p0[1]))  # ... and without one
        # The references of every seed at every step: speed and heading (compiled).
        v_ref, th_ref = seed_references(
            np.array([c.direction for c, _ in pairs], np.int64),
            np.array([-1 if c.switch is None else c.switch for c, _ in pairs], np.int64),
            np.array([math.nan if sw is None else sw for _, sw in pairs], float),
            N,
            dt,
            to_switch,
            to_target,
            d2,
            float(tth),
            float(xi0[XI_TH]),
            float(line.psi),
            bool(line.fixed),
            self.g.parking_type is ParkingType.PARALLEL,
            int(self.first_direction),
        )
        # Each seed under a speed controller (3.0 (v_ref - v) - 0.5 a) and a heading one
        # (2.5 (th_ref - th), sign by gear), on the planning model.
        return self.rollouts(xi0, v_ref, th_ref)
