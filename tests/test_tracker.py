"""The path tracker's compiled closed loop against the Python loop it replaced."""

from __future__ import annotations

import numpy as np
import pytest

from mirrorpark_env.vehicle import TruthModel, VehicleParams
from planners.common import reeds_shepp
from planners.common.path import Path
from planners.common.tracker import PathTracker, TrackerConfig
from planners.common.tracker_kernel import TrackedRollout
from planners.mirror.config import CoreConfig


def _python_loop(tracker: PathTracker, model: TruthModel, xi0, steps: int):
    """``PathTracker.command_at`` then ``TruthModel.step``, ``steps`` times: the loop
    the mirror planner's guided seed ran before it was compiled."""
    state = tuple(float(v) for v in xi0[:6])
    out, segs, reached = [(*state, 0.0)], [0], [0]
    for _ in range(steps):
        sub = model.step(state, *tracker.command_at(*state))
        out.extend(sub)
        state = sub[-1][:6]
        segs.append(-1 if tracker.done else tracker.seg)
        reached.append(tracker.j)
    return np.array(out)[:, :6], segs, reached


def test_the_compiled_tracker_loop_repeats_the_python_loop_bit_for_bit():
    """Reeds-Shepp paths with cusps, driven from the start pose and from poses off it
    (standing, moving, steered), at several cruise speeds, long enough for some runs to
    finish the path and stand: the same sub-step states, segments and samples reached,
    to the last bit."""
    p = VehicleParams.table_ii()
    cfg = CoreConfig()
    model = TruthModel(p, cfg.dt, cfg.dt / cfg.model_substeps)  # the planner's planning model
    roll = TrackedRollout(model)
    rng = np.random.default_rng(5)
    finished = cusps = 0
    for _ in range(60):
        start = np.array([*rng.uniform(-2, 2, 2), rng.uniform(-np.pi, np.pi)])
        goal = np.array([*rng.uniform(-6, 6, 2), rng.uniform(-np.pi, np.pi)])
        poses = reeds_shepp.sample(start, goal, p.r_min, float(rng.choice([0.05, 0.1])))
        path = Path.from_poses(poses)
        speed = float(rng.uniform(0.5, 2.5))
        tc = TrackerConfig(cruise_speed=speed, accel=min(3.0, 1.5 * speed), decel=min(3.0, 1.5 * speed))
        xi0 = np.array([*start, 0.0, 0.0, 0.0])
        if rng.random() < 0.6:  # off the path, moving, steered
            xi0 += [*rng.normal(0, 0.1, 2), rng.normal(0, 0.05), rng.uniform(-0.8, 0.8), rng.uniform(-1, 1),
                    rng.uniform(-0.5, 0.5)]  # fmt: skip
        steps = int(rng.integers(1, 160))
        want = _python_loop(PathTracker(path, p, tc), model, xi0, steps)
        got = roll(PathTracker(path, p, tc), xi0, steps)
        assert np.array_equal(got[0], want[0])
        assert got[1].tolist() == want[1] and got[2].tolist() == want[2]
        finished += want[1][-1] == -1
        cusps += max(want[1]) > 0
    assert finished >= 5 and cusps >= 10  # the runs reach the stops, cusps and ends


def test_the_compiled_tracker_loop_wants_a_fresh_tracker():
    p = VehicleParams.table_ii()
    tracker = PathTracker(Path.from_poses(reeds_shepp.sample((0, 0, 0), (3, 1, 0.3), p.r_min, 0.1)), p)
    tracker.command_at(0.0, 0.0, 0.0, 0.0, 0.0, 0.3)
    tracker.phase = "drive"
    with pytest.raises(ValueError, match="tracker: must be fresh"):
        TrackedRollout(TruthModel(p, 0.1, 0.05))(tracker, np.zeros(6), 10)
