"""Demo of the mirrored-target planner: one episode per parking type, drawn like the
paper's Fig. 19 (the first plan toward the mirrored target, the path the car drove, the
mirror line, the car's footprints) and animated as a GIF.

The episode is the evaluation's own closed loop (``run_episode``); the figure only reads
what the environment reported each step and the plans the policy made.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import gymnasium as gym
import numpy as np
from matplotlib.animation import FuncAnimation, PillowWriter
from matplotlib.patches import Polygon

import mirrorpark_env  # noqa: F401  (registers MirrorPark-v0)
from mirrorpark_env import Scenario
from mirrorpark_env.scenario import ScenarioGeometry
from mirrorpark_env.vehicle import footprint
from planners.base import run_episode
from planners.mirror.mirror_line import mirrored_target
from planners.mirror.plans import Plan
from planners.mirror.policy import MirrorPolicy

from .figures import pyplot

# One case per type in which a plan of the default planner holds its switch (many plans
# switch only at their ends, where the mirror has nothing to show): Fig. 19-like manoeuvres.
DEMO_CASES = {
    "parallel": Scenario.from_case_id("parallel_rw3.50_sl6.82_sw2.50_th+0_y1.50"),
    "reverse": Scenario.from_case_id("reverse_rw7.00_sl4.82_sw2.72_th+0_y5.50"),
    "angle": Scenario.from_case_id("angle_rw4.50_sl4.82_sw1.92_th+10_y1.80"),
}


@dataclass(frozen=True)
class DemoEpisode:
    """What the demo drew for one parking type."""

    parking_type: str
    case_id: str
    success: bool
    switches: int
    parking_time_s: float
    plans: int
    figure: Path
    animation: Path


def mirror_demo(
    out: Path, types: tuple[str, ...] = tuple(DEMO_CASES), fps: int = 8, every: int = 5
) -> list[DemoEpisode]:
    """Plan and drive one demo case per type in ``types``; write ``mirror_<type>.png`` and
    ``mirror_<type>.gif`` (a frame every ``every`` control steps, ``fps`` frames/s)."""
    unknown = [t for t in types if t not in DEMO_CASES]
    if unknown:
        raise ValueError(f"types: must be among {tuple(DEMO_CASES)}, got {unknown}")
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    env = gym.make("MirrorPark-v0")
    done = []
    for t in types:
        policy = MirrorPolicy()
        trace: list[dict] = []
        info, _ = run_episode(env, policy, DEMO_CASES[t], trace=trace)
        g: ScenarioGeometry = trace[0]["geometry"]
        states = np.array([[s.x, s.y, s.theta] for s in (i["vehicle_state"] for i in trace)])
        times = [i["parking_time"] for i in trace]
        fig_path = _figure(g, states, policy.plans, info, out / f"mirror_{t}.png")
        gif_path = _animation(g, states, times, out / f"mirror_{t}.gif", fps, every)
        done.append(
            DemoEpisode(
                t,
                DEMO_CASES[t].case_id,
                bool(info["is_success"]),
                int(info["direction_switches"]),
                float(info["parking_time"]),
                len(policy.plans),
                fig_path,
                gif_path,
            )
        )
    env.close()
    return done


def _scene(ax, g: ScenarioGeometry, focus: np.ndarray | None = None) -> None:
    """Obstacles, slot and target footprint; axes around ``focus`` points (x, y) plus 2 m,
    within the scene."""

    for poly in g.obstacles.polygons:
        ax.add_patch(Polygon(poly, closed=True, facecolor="0.8", edgecolor="0.5", lw=0.8))
    ax.add_patch(Polygon(g.slot, closed=True, fill=False, edgecolor="0.4", ls=":", lw=1))
    ax.add_patch(
        Polygon(footprint(g.vehicle, *g.target), closed=True, fill=False, edgecolor="tab:green", lw=1.5, label="target")
    )
    x0, x1, y0, y1 = g.bounds
    if focus is not None:
        lo, hi = focus.min(axis=0) - 2.0, focus.max(axis=0) + 2.0
        x0, x1, y0, y1 = max(x0, lo[0]), min(x1, hi[0]), max(y0, lo[1]), min(y1, hi[1])
    ax.set_xlim(x0, x1)
    ax.set_ylim(y0, y1)
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")


def _focus(g: ScenarioGeometry, states: np.ndarray) -> np.ndarray:
    """Points the view must hold: the driven path, the slot and the target's footprint."""
    return np.concatenate([states[:, :2], np.asarray(g.slot), footprint(g.vehicle, *g.target)])


def _plan_goal(plan: Plan, g: ScenarioGeometry) -> tuple[float, float, float]:
    """The real goal a plan was made for (the target, or a pose on the way), mirrored through its switch."""
    goal = plan.goal or g.target
    return tuple(float(v) for v in goal)


def _figure(g: ScenarioGeometry, states: np.ndarray, plans: list[Plan], info: dict, path: Path) -> Path:

    plt = pyplot()
    fig, ax = plt.subplots(figsize=(9, 6))
    focus = [_focus(g, states)]
    colours = plt.get_cmap("tab10").colors
    for k, plan in enumerate(plans):
        c = colours[k % len(colours)]
        ax.plot(
            plan.planned_states[:, 0],
            plan.planned_states[:, 1],
            "--",
            color=c,
            lw=1.4,
            label=f"plan {k + 1}, as planned (one direction)",
        )
        focus.append(plan.planned_states[:, :2])
        if plan.switch_point is not None:
            mirrored = mirrored_target(_plan_goal(plan, g), plan.switch_point)
            corners = footprint(g.vehicle, *mirrored)
            ax.add_patch(
                Polygon(
                    corners,
                    closed=True,
                    fill=False,
                    edgecolor=c,
                    ls="--",
                    lw=1.0,
                    label=f"plan {k + 1}: its goal mirrored through the switch point",
                )
            )
            ax.plot(*plan.switch_point, "o", color=c, ms=5)
            focus.append(corners)
    natural = -1 if g.parking_type.value == "parallel" else 1  # first gear of the paper's mirror line
    for k, plan in enumerate(plans):  # each such switch's mirror line: through S, along its goal's axis
        if plan.switch_point is None or plan.candidate.direction != natural:
            continue
        heading = _plan_goal(plan, g)[2]
        along = np.array([math.cos(heading), math.sin(heading)])
        ends = np.array(plan.switch_point) + np.outer([-60.0, 60.0], along)
        ax.plot(
            ends[:, 0], ends[:, 1], "-.", color=colours[k % len(colours)], lw=0.9, label=f"plan {k + 1}: mirror line"
        )
    _scene(ax, g, np.concatenate(focus))
    ax.plot(states[:, 0], states[:, 1], "-", color="k", lw=1.6, label="driven (rear axle)")
    for k in range(0, len(states), 10):  # a footprint every 10 control steps
        ax.add_patch(
            Polygon(footprint(g.vehicle, *states[k]), closed=True, fill=False, edgecolor="0.2", lw=0.5, alpha=0.4)
        )
    ax.add_patch(Polygon(footprint(g.vehicle, *states[-1]), closed=True, fill=False, edgecolor="k", lw=1.5))
    verdict = "parked" if info["is_success"] else "not parked"
    ax.set_title(
        f"{g.scenario.case_id}: {verdict}, {info['direction_switches']} switches, "
        f"{info['parking_time']:.1f} s, {len(plans)} plans (dots: switch points)",
        fontsize=9,
    )
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=7, framealpha=0.9)
    fig.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(fig)
    return path


def _animation(g: ScenarioGeometry, states: np.ndarray, times: list[float], path: Path, fps: int, every: int) -> Path:

    plt = pyplot()
    fig, ax = plt.subplots(figsize=(6.4, 4.0))
    _scene(ax, g, _focus(g, states))
    (trail,) = ax.plot([], [], "-", color="k", lw=1)
    car = Polygon(footprint(g.vehicle, *states[0]), closed=True, facecolor="tab:blue", alpha=0.6, edgecolor="k")
    ax.add_patch(car)
    frames = list(range(0, len(states), every))
    if frames[-1] != len(states) - 1:
        frames.append(len(states) - 1)

    def draw(k: int):
        trail.set_data(states[: k + 1, 0], states[: k + 1, 1])
        car.set_xy(footprint(g.vehicle, *states[k]))
        ax.set_title(f"{g.scenario.case_id}   t = {times[k]:.1f} s", fontsize=8)
        return trail, car

    fig.tight_layout()
    FuncAnimation(fig, draw, frames=frames, blit=False).save(path, writer=PillowWriter(fps=fps), dpi=70)
    plt.close(fig)
    return path
