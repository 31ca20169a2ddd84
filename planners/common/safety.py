"""A stopping check for path-tracking policies: brake while the car can still stop clear.

A tracker may drift from its path by up to its tolerances (15 cm, 5 deg) before the
policy replans, and 5 deg of heading swing the front of the car by 26 cm: more than the
clearance the path was planned with (hybrid A* on the full grid touched the road's far
edge twice this way, by 0.2 mm at 0.04 m/s). So at each step the tracker is rolled out in
closed loop on the truth model until the car next stands (at most a few seconds); if a
footprint on the way comes closer to an obstacle than ``min_gap``, the policy brakes now
and replans once it stands. Where the car is already closer than ``min_gap`` (a tight
start, or near its start), the rollout must keep half of that gap: tracking may use some
of what the planner kept, never all of it, so the check cannot pin the car where it
stands. Gaps here test all six separating axes for every pose (``kernels.FastGaps``).
"""

from __future__ import annotations

import copy

import numpy as np

from mirrorpark_env.scenario import ScenarioGeometry
from mirrorpark_env.vehicle import TruthModel, VehicleState

from .clearance import gaps, required_gap
from .tracker import PathTracker, hold_accel

MIN_GAP = 0.01  # [m] the closest a footprint may come on the way to a stand


class StoppingCheck:
    """``safe(state, tracker)``: does tracking stay clear until the car next stands (at most
    ``horizon`` seconds ahead)?"""

    def __init__(self, geometry: ScenarioGeometry, dt: float = 0.1, min_gap: float = MIN_GAP, horizon: float = 4.0):
        self.g = geometry
        self.p = geometry.vehicle
        self.model = TruthModel(self.p, dt, 0.01)
        self.min_gap = min_gap
        self.max_steps = max(1, round(horizon / dt))
        st = geometry.start
        self.start_xy = (st.x, st.y)
        self.start_gap = float(gaps(geometry.checker, np.array([[st.x, st.y, st.theta]]), all_axes=True)[0])

    def safe(self, s: VehicleState, tracker: PathTracker) -> bool:
        """Rolls a copy of ``tracker`` in closed loop on the truth model from ``s``; False if a
        footprint on the way comes closer to an obstacle than ``min_gap`` (or, from a pose
        or within ``START_RELIEF`` of a start already closer, than half that gap)."""
        p = self.p
        here = float(gaps(self.g.checker, np.array([[s.x, s.y, s.theta]]), all_axes=True)[0])
        need = min(self.min_gap, 0.5 * max(here, 0.0))
        tr = copy.copy(tracker)
        x, y, th, v, a, d = s.x, s.y, s.theta, s.v, s.a, s.delta
        poses = []
        moved = abs(v) >= 0.01
        for _ in range(self.max_steps):
            if tr.drifted:  # the policy will brake here, holding the steering: so does the rollout
                a_cmd, d_cmd = hold_accel(p, v, a), d
            else:
                a_cmd, d_cmd = tr.command_at(x, y, th, v, a, d)
            rows = self.model.step((x, y, th, v, a, d), a_cmd, d_cmd)
            poses += [r[:3] for r in rows]
            x, y, th, v, a, d = rows[-1][:6]
            if tr.done or (moved and abs(v) < 0.01):
                break  # standing: at the end of the path, at a cusp, or braked after a drift
            moved = moved or abs(v) >= 0.01
        poses = np.array(poses)
        # Within START_RELIEF of a start closer than min_gap, half the start's gap (the planners
        # keep that gap less START_SLACK there; common.clearance): the car may leave a tight start.
        half = 0.5 * max(self.start_gap, 0.0)
        need = np.minimum(need, required_gap(poses, self.start_xy, self.start_gap, self.min_gap, slack=half))
        return bool((gaps(self.g.checker, poses, all_axes=True) >= need - 1e-12).all())
