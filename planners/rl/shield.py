"""A safety filter around a learned policy (``rl-shield:PATH``): a separate, named row.

Each step the learner's action is tried on the truth model: one step of it, then the
brake (``tracker.hold_accel``, steering held) until the car stands still (its speed and
acceleration die away; a car that only nearly stands creeps on). If a footprint on the
way comes closer to an obstacle than ``MIN_GAP`` (or, where the car is already closer,
closer than it is now), the filter brakes instead; but where the car stands and the
learner offers a second choice in the other gear (``second_choice``: a geared model's
other gear, else the same command mirrored), that is taken if it is clear. Braking alone
left a learner that insists on a blocked gear standing until the time ran out (docs/rl.md).
It changes what the learner's row measures, so it is never folded into ``rl:PATH``: the
learner alone stays that row.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import numpy as np

from mirrorpark_env.scenario import ScenarioGeometry
from mirrorpark_env.vehicle import TruthModel, VehicleState, from_action, to_action

from ..base import PlanStats, Policy
from ..common.brake import BrakeRollout
from ..common.clearance import gaps
from ..common.safety import MIN_GAP  # the tracking policies' stopping check keeps the same gap
from ..common.tracker import hold_accel
from .gear import STAND_SPEED

BRAKE_STEPS = 40  # control steps of braking tried at most (4 s at 0.1 s)


class Shield:
    """The filter itself, for one scenario: an action, or the brake where it is not clear."""

    def __init__(self, geometry: ScenarioGeometry, dt: float = 0.1):
        self.g = geometry
        self.p = geometry.vehicle
        self.rollout = BrakeRollout(TruthModel(self.p, dt, 0.01))  # compiled: common/brake.py

    def decide(
        self, s: VehicleState, action: np.ndarray, second: Callable[[np.ndarray], np.ndarray] | None = None
    ) -> tuple[np.ndarray, str]:
        """(the action to execute, ``"clear"``, ``"other"`` or ``"brake"``): ``action`` where
        it is clear; else, where the car stands and ``action`` would start it, the learner's
        ``second(action)`` in the other gear where that is clear; else the brake."""
        if self.clear(s, *from_action(self.p, action)):
            return action, "clear"
        if second is not None and abs(s.v) <= STAND_SPEED and action[0] != 0:
            other = np.asarray(second(action), dtype=np.float32)
            if self.clear(s, *from_action(self.p, other)):
                return other, "other"
        return to_action(self.p, hold_accel(self.p, s.v, s.a), s.delta), "brake"

    def clear(self, s: VehicleState, a_cmd: float, d_cmd: float) -> bool:
        """Whether one step of these commands, then the brake to a stand, keeps the gap."""
        state = (s.x, s.y, s.theta, s.v, s.a, s.delta)
        here = float(gaps(self.g.checker, np.array([state[:3]]), all_axes=True)[0])
        need = min(MIN_GAP, here)
        poses = self.rollout(state, a_cmd, d_cmd, BRAKE_STEPS)
        return bool((gaps(self.g.checker, poses, all_axes=True) >= need - 1e-12).all())


class Shielded(Policy):
    """``inner``'s action where one step of it and then the brake stay clear; else, standing,
    its second choice in the other gear where that is clear; else the brake."""

    def __init__(self, inner: Policy, dt: float = 0.1):
        self.inner = inner  # its stats and give-up are the filter's (no state of its own)
        self.name = f"rl-shield:{inner.name.removeprefix('rl:')}"
        self.dt = dt
        self.overrides = 0
        self.gear_swaps = 0  # overrides that took the learner's other gear

    def reset(self, geometry: ScenarioGeometry) -> None:
        self.inner.reset(geometry)
        self.shield = Shield(geometry, self.dt)
        self.overrides = 0
        self.gear_swaps = 0

    def act(self, obs: dict[str, np.ndarray], info: dict[str, Any]) -> np.ndarray:
        t0 = time.perf_counter()
        wanted = self.inner.act(obs, info)
        changed = self.changed_scene(info, self.shield.g)
        if changed is not None:  # a late obstacle: the filter keeps clear of it too
            self.shield = Shield(changed, self.dt)
        action, how = self.shield.decide(info["vehicle_state"], wanted, getattr(self.inner, "second_choice", None))
        clear = how == "clear"
        self.overrides += int(not clear)
        self.gear_swaps += int(how == "other")
        if self.inner.stats:  # the decision's time includes the filter's; its status says if it overrode
            last = self.inner.stats[-1]
            status = last.status if clear else "shielded"
            self.inner.stats[-1] = PlanStats(time.perf_counter() - t0, status, detail={"learner_status": last.status})
        return action

    @property
    def stats(self) -> list[PlanStats]:
        return self.inner.stats

    @property
    def gave_up(self) -> bool:
        return self.inner.gave_up

    @property
    def setup_time_s(self) -> float:
        return getattr(self.inner, "setup_time_s", 0.0)
