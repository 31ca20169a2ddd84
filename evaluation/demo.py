"""Demo of the environment: one scenario per parking type and one scripted episode, as PNG.

The three scene types at their start, and a closed-loop episode where a hand-written
speed controller reverses a car straight down into a reverse slot and stops, which the
ISO check accepts. (The planner's demo is ``mirror_demo``; ``mirrorpark demo`` runs both.)
"""

from __future__ import annotations

from pathlib import Path

import gymnasium as gym
import numpy as np

import mirrorpark_env  # noqa: F401  (registers MirrorPark-v0)
from mirrorpark_env import Scenario, VehicleParams, to_action

from .figures import pyplot

SHOWCASE = {
    "parallel": Scenario.from_degrees("parallel", 4.0, 5.5, 2.5, 10, 2.0),
    "reverse": Scenario.from_degrees("reverse", 6.0, 4.82, 2.3, 0, 2.5),
    "angle": Scenario.from_degrees("angle", 4.0, 4.82, 2.3, -10, 2.0),
}
STRAIGHT_BACK = Scenario.from_degrees("reverse", 5.0, 4.82, 2.3, 90, 1.0, start_x_offset=-1.15)


def straight_back_episode(env: gym.Env, frames: list | None = None, every: int = 10) -> dict:
    """Reverse straight into ``STRAIGHT_BACK``'s slot with a P speed controller; return the last info."""
    p = VehicleParams.from_config(env.unwrapped.cfg.vehicle)
    _, info = env.reset(options={"scenario": STRAIGHT_BACK})
    y_target = info["geometry"].target[1]
    for k in range(400):
        s = info["vehicle_state"]
        v_ref = max(-1.0, min(1.0, 0.8 * (y_target - s.y)))
        _, _, term, trunc, info = env.step(to_action(p, 2.0 * (v_ref - s.v) - s.a, 0.0))
        if frames is not None and (k % every == 0 or term or trunc):
            frames.append(env.render())
        if term or trunc:
            break
    return info


def run_demo(out: Path) -> dict[str, Path]:
    plt = pyplot()

    out.mkdir(parents=True, exist_ok=True)
    env = gym.make("MirrorPark-v0", render_mode="rgb_array")
    written = {}
    for name, sc in SHOWCASE.items():
        env.reset(options={"scenario": sc})
        path = out / f"scene_{name}.png"
        plt.imsave(path, env.render())
        written[name] = path
    frames: list[np.ndarray] = []
    info = straight_back_episode(env, frames)
    strip = np.concatenate([f[60:360, 150:550] for f in frames[:: max(1, len(frames) // 4)]][:5], axis=1)
    path = out / "episode_straight_back.png"
    plt.imsave(path, strip)
    written["episode"] = path
    env.close()
    print(
        f"demo episode {STRAIGHT_BACK.case_id}: success={info['is_success']} "
        f"time={info['parking_time']:.1f} s switches={info['direction_switches']} "
        f"margins={ {k: round(v, 3) for k, v in info['margins'].items()} }"
    )
    return written
