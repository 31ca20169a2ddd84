"""The mirrored-target planner as a policy: execute, and replan as in the paper's Fig. 11.

Each plan holds one direction switch. Its commands are executed as planned before the
switch and negated after it (Eq. 42; the planner already returns them in that form).
A new plan starts from where the car stands when the last one has run out without the
target being met, or early when the measured state drifts from the plan's prediction.
A failed solve stops the car (or lets it finish its verified plan) and retries a few steps
later; it never raises. The planner is deterministic, so the policy gives up rather than
ask it again from a standing state where its answer got the car nowhere.
"""

from __future__ import annotations

import math
import time
from typing import Any

import numpy as np

from mirrorpark_env.angles import wrap_angle
from mirrorpark_env.criteria import iso_pose_exists
from mirrorpark_env.scenario import ScenarioGeometry
from mirrorpark_env.vehicle import VehicleState, to_action

from ..base import PlanStats, Policy
from ..common.brake import clearest_stop
from ..common.innovation import Innovation
from ..common.tracker import emergency_accel, hold_accel
from .config import MirrorPlannerConfig, MirrorPolicyConfig
from .planner import MirrorPlanner
from .plans import Plan

IDLE_SPEED = 0.05  # [m/s] the car stands (the ISO check's stop speed)
IDLE_TRAVEL = 0.05  # [m] a plan whose rest moves the car less than this has done its work


class MirrorPolicy(Policy):
    name = "mirror"

    def __init__(self, config: MirrorPlannerConfig | None = None, policy: MirrorPolicyConfig | None = None) -> None:
        super().__init__()
        self.config = config or MirrorPlannerConfig()
        self.policy_config = pc = policy or MirrorPolicyConfig()
        self.drift_position = pc.drift_position
        self.drift_heading = math.radians(pc.drift_heading_deg)
        self.retry_every = pc.retry_every
        self.max_failures = pc.max_failures  # consecutive failed solves before giving up
        self.max_plans = pc.max_plans  # plans per episode before giving up
        self.patience = pc.patience  # plans without lowering the cost of standing still
        self.planner: MirrorPlanner | None = None
        self.geometry: ScenarioGeometry | None = None
        self.plan: Plan | None = None
        self.k = 0
        self._step = 0  # control steps so far
        self._retry_at = 0  # the step from which a failed call may be retried

    def reset(self, geometry: ScenarioGeometry) -> None:
        """Prepare for ``geometry``. A slot that admits no ISO-compliant pose at all (too narrow
        or too short for the car and the margins, ``criteria.iso_pose_exists``) is refused at
        once, as a car refuses a gap it has measured: status ``no_goal``, the car stays."""
        t0 = time.perf_counter()
        self.planner = MirrorPlanner(geometry, self.config)
        self.geometry = g = geometry
        self._stand_first: float | None = None  # brake to a stand on this steering first (a changed scene)
        fits = bool(iso_pose_exists(g.parking_type.value, g.slot_length, g.slot_width, g.vehicle))
        if fits:
            self.planner.prepare()
        self.setup_time_s = time.perf_counter() - t0
        self.params = geometry.vehicle
        self.plan = None
        self.k = 0
        self._step = 0  # control steps so far
        self._retry_at = 0  # the step from which a failed call may be retried
        self.stats = [] if fits else [PlanStats(0.0, "no_goal", detail={"reason": "no ISO pose in this slot"})]
        self.plans: list[Plan] = []
        self.gave_up = not fits
        self._innovation = Innovation(geometry.vehicle, self.config.core.dt)
        self.planner_config = self.config  # the planner's settings now: its margins grow (``_widen``)
        self._margin_level = 0  # margin steps added to the clearances (``_widen``)
        self._failures = 0
        self._failed_at: np.ndarray | None = None  # standing state of the last failed call
        self._stood: list[np.ndarray | None] = []  # the last two calls' standing states
        self._best = math.inf  # the lowest progress measure so far (the strategy's, ``Outcome.progress``)
        self._since_best = 0
        self._stuck = 0  # partial plans in a row that only turn the wheels of a standing car

    def act(self, obs: dict[str, np.ndarray], info: dict[str, Any]) -> np.ndarray:
        if self.planner is None:
            raise RuntimeError("MirrorPolicy: call reset(geometry) first")
        s = self._innovation.observe(info["vehicle_state"])  # the measurement itself, unless it is noisy
        self._widen()
        action = self._decide(s, info)
        self._innovation.sent(action)
        return action

    def _widen(self) -> None:
        """Keep the clearances above what the innovation says the car's pose may be off by:
        ``margin_gain`` x its RMS, in steps of ``margin_step`` up to ``margin_max``, added to
        the planned and checked clearances. A wider margin takes a new planner for the next
        plan; the plan in hand, checked with the narrower one, runs on (dropping it at speed
        left the car braking blind, into a slot's side). Without a perturbation the
        innovation is exactly zero: the margins stay as configured."""
        if self.gave_up:  # no plan is asked for again (a slot without an ISO pose included)
            return
        pc = self.policy_config
        extra = min(pc.margin_max, pc.margin_gain * self._innovation.position_rms)
        level = math.floor(extra / pc.margin_step + 1e-9)
        if level <= self._margin_level:
            return
        self._margin_level = level
        settings = self.config.core  # the core's settings (not the core)
        m = level * pc.margin_step
        wider = {"obstacle_margin": settings.obstacle_margin + m, "check_margin": settings.check_margin + m}
        self.planner_config = cfg = self.config.model_copy(update={"core": settings.model_copy(update=wider)})
        self.planner = MirrorPlanner(self.geometry, cfg)
        self.planner.prepare()

    def _decide(self, s: VehicleState, info: dict[str, Any]) -> np.ndarray:
        self._step += 1
        changed = self.changed_scene(info, self.geometry)
        if changed is not None:
            self._new_scene(changed, s)
        if self._stand_first is not None:  # a changed scene: brake to a stand on the clearest steering
            if abs(s.v) >= IDLE_SPEED:
                return to_action(self.params, emergency_accel(self.params, s.v, s.a), self._stand_first)
            self._stand_first = None
        if not self.gave_up and (
            self.plan is None or self.k >= len(self.plan.commands) or self._drifted(s) or self._idle(s)
        ):
            self._replan(s)
        if self.plan is None or self.k >= len(self.plan.commands):
            return self._brake(s)
        a, d = self.plan.commands[self.k]
        self.k += 1
        return to_action(self.params, float(a), float(d))

    def _new_scene(self, geometry: ScenarioGeometry, s: VehicleState) -> None:
        """The scene changed (a late obstacle): the plan in hand did not know it. Brake to a
        stand on the steering that keeps clearest of the new scene, then plan in it, with the
        search for progress begun afresh."""
        self.planner = MirrorPlanner(geometry, self.planner_config)
        self.planner.prepare()
        self.geometry = geometry
        self.plan = None
        self._stand_first = clearest_stop(geometry, s.as_array())
        self._failures, self._failed_at, self._stood = 0, None, []
        self._best, self._since_best, self._stuck = math.inf, 0, 0

    def _idle(self, s: VehicleState) -> bool:
        """The car stands and the rest of the plan would move it less than ``IDLE_TRAVEL``:
        the plan has done its work (a leg after the switch that only creeps, a goal reached
        early), and waiting out the horizon would only add parking time."""
        if abs(s.v) >= IDLE_SPEED or self.k == 0:
            return False
        return self._travel(self.plan, self.k) < IDLE_TRAVEL

    def _travel(self, plan: Plan, k: int = 0) -> float:
        """How far ``plan`` moves the car from its step ``k`` on [m]."""
        return float(np.abs(plan.states[k:, 3]).sum()) * self.config.core.dt

    def _drifted(self, s: VehicleState) -> bool:
        ref = self.plan.states[self.k]
        return (
            math.hypot(s.x - ref[0], s.y - ref[1]) > self.drift_position or abs(s.theta - ref[2]) > self.drift_heading
        )

    def _replan(self, s: VehicleState) -> None:
        ongoing = self.plan is not None and self.k < len(self.plan.commands)
        if self._step < self._retry_at:
            if not ongoing:
                self.plan = None
            return
        # The planner is deterministic: from the standing state of the last two calls (pose,
        # steering, speed and lagged acceleration), a third returns what the second did, which
        # got the car nowhere (measured: 6 identical partial plans of 935 QPs each from a
        # standing car, until ``patience`` ended it). Plans that only turn the wheels are
        # progress: the steering is part of the state.
        here = s.as_array() if abs(s.v) < IDLE_SPEED else None
        stood = here is not None and len(self._stood) == 2
        if stood and all(p is not None and _same_state(here, p) for p in self._stood):
            self.gave_up = True  # the verified plan, if any is left, is finished (below)
            if not ongoing:
                self.plan = None
            return
        self._stood = [*self._stood[-1:], here]
        plan = self.planner.plan(s)
        if plan is None:
            self.stats.append(self.planner.last_stats)
            # Retry after ``retry_every`` steps, keeping to the verified plan, if any is left,
            # rather than brake blindly while moving (measured: a failed call while a plan
            # ran was repeated at every step its idling lasted: 39 calls of ~500 QPs in one episode).
            self._retry_at = self._step + self.retry_every + 1
            self._failures += 1
            # Failing twice from one standing state, it will fail again (measured: 8
            # identical failed calls per stuck episode).
            again = here is not None and self._failed_at is not None and _same_state(here, self._failed_at)
            self._failed_at = here
            self.gave_up = self._failures >= self.max_failures or again
            if not ongoing:
                self.plan = None
            return
        self._failures = 0
        self._failed_at = None
        self.stats.append(plan.stats)
        # Progress: the strategy's measure (the guide's cost to go, or the cost of standing still).
        measure = plan.stats.detail.get("progress", math.inf)
        if measure < 0.99 * self._best:
            self._best, self._since_best = measure, 0
        else:
            self._since_best += 1
        # A partial plan that moves a standing car less than ``IDLE_TRAVEL`` is a safe stop
        # where it stands: no way on was found, and it only turns the wheels. Once may help
        # (the steering is part of the state); after two with no other plan between them
        # (failed calls aside), the calls that followed returned the same until ``patience``
        # (measured: 6 such calls of up to 790 QPs each in 8 of 500 standard episodes, 170 s
        # of the 627 s of planning of all 500).
        still = here is not None and plan.stats.status == "partial" and self._travel(plan) < IDLE_TRAVEL
        self._stuck = self._stuck + 1 if still else 0
        if len(self.stats) >= self.max_plans or self._since_best >= self.patience or self._stuck >= 2:
            self.gave_up = True  # no progress: stop safely rather than shuffle for 180 s
            # The car finishes its verified plan, if any is left, which ends standing with its
            # brake checked. Braking where it is, wheels held, leaves the checked path: with
            # the lag, even a car at v = 0 may still be accelerating (measured: a give-up at a
            # plan's reversal, a = -1.0 m/s^2, rolled 2.7 cm back into a neighbour).
            if self.plan is not None and self.k >= len(self.plan.commands):
                self.plan = None
            return
        self.plans.append(plan)
        self.plan = plan
        self.k = 0

    def _brake(self, s: VehicleState) -> np.ndarray:
        return to_action(self.params, hold_accel(self.params, s.v, s.a), s.delta)

    @property
    def status(self) -> str:
        if self.gave_up:
            return "no_goal" if self.stats and self.stats[-1].status == "no_goal" else "gave_up"
        return super().status


def _same_state(a: np.ndarray, b: np.ndarray) -> bool:
    """States (x, y, theta, v, a, delta) within 1 cm, 0.01 rad, 0.01 m/s, 0.05 m/s^2 and 0.01 rad."""
    return bool(
        math.hypot(a[0] - b[0], a[1] - b[1]) < 0.01
        and abs(wrap_angle(a[2] - b[2])) < 0.01
        and abs(a[3] - b[3]) < 0.01
        and abs(a[4] - b[4]) < 0.05
        and abs(a[5] - b[5]) < 0.01
    )
