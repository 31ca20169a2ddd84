"""``MirrorPark-v0``: parallel, reverse and angle parking as a goal-conditioned Gymnasium env.

The class docstring of ``MirrorParkEnv`` is the environment's specification.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from .config import EnvConfig, default_env, merge
from .criteria import SuccessCriteria
from .geometry import COLLISION_TOL, ConvexSet
from .grid import TYPES, grid_for
from .layout import Layout
from .lidar import Lidar
from .perturb import Perturbation
from .rendering import Renderer
from .scenario import Scenario, ScenarioGeometry, grid_layout
from .vehicle import TruthModel, VehicleParams, VehicleState, from_action

POS_SCALE = 10.0  # [m] scale of positions in observations and goals
_HYPOT = np.frompyfunc(math.hypot, 2, 1)  # compute_reward: the scalar path's arithmetic, vectorised
_ATAN2 = np.frompyfunc(math.atan2, 2, 1)
V_EPS = 0.01  # [m/s] speeds below this count as standing when counting direction switches
AWAY = 1.0  # [m] a rear axle this far from its start has left the start's kerb behind


class MirrorParkEnv(gym.Env):
    """Parallel, reverse and angle parking with the paper's car and ISO verdicts.

    ## Description
    A scene of Table III (road width, slot size, start heading and distance) is built
    with the slot on the -Y side of a road along +X. The car starts just past the slot;
    the task is the target pose inside it, judged by the ISO criteria
    (``criteria.SuccessCriteria``). The truth model is a rear-axle kinematic bicycle with
    first-order lags on acceleration and steering (``vehicle.TruthModel``); collisions are
    exact footprint-polygon tests on every 0.01 s sub-step.

    ## Action Space
    ``Box(-1, 1, (2,))``: ``[accel, steer]``. Acceleration maps piecewise-linearly onto
    [a_min, a_max] = [-5, 3] m/s^2 with 0 -> 0; steering linearly onto +-0.6 rad
    (``vehicle.to_action`` / ``from_action``). A NaN or infinite action raises ``ValueError``.

    ## Observation Space
    ``Dict`` (usable with stable-baselines3's HER):
    - ``observation`` (13,): x/10, y/10, cos(theta), sin(theta), v/v_max, a/|a_min|,
      delta/max_steer, RW/10, SL/10, SW/10, one-hot parking type. With the type, the
      three sizes fix all obstacles: the vector describes the scene completely.
    - ``achieved_goal`` / ``desired_goal`` (4,): x/10, y/10, cos(theta), sin(theta) of
      the rear axle now / at the target.

    ## Rewards
    ``-(d_pos + w_h * |d_theta|) / distance_scale + success_bonus * reached +
    collision_penalty * collision`` per step (``compute_reward``, vectorised for HER),
    where ``reached`` is the goal pose within 0.15 m and 3 deg. The episode's verdict is
    ``info["is_success"]``, the ISO check.

    With ``lidar.rays`` > 0 the dict also holds ``lidar`` (rays,): ranges from the body
    centre to the obstacles, divided by ``lidar.max_range`` (``lidar.Lidar``), so that an
    agent can act in a layout it has not seen. In a layout the sizes are the slot's (0
    without a slot) and the road width the layout's (0 where it names none).

    ## Starting State
    Standing (v = a = delta = 0) at the scene's start pose: a random Table III case of
    the configured parking types, ``options={"scenario": Scenario | case id}``, or any
    layout: ``options={"layout": Layout | path}`` (``layout_io.load_layout``; a grid case
    is built through the same ``Layout.build``).

    ## Episode End
    Terminated on ISO success (in a layout without a slot: the target pose within
    ``criteria.target_position_tol`` and the heading tolerance), collision or leaving the
    scene (the rear axle outside the geometry's ``bounds``); truncated after
    ``max_episode_steps`` = 1800 steps (180 s at the default 0.1 s step, the ISO time
    limit; declared in the registration: pass ``max_episode_steps`` to ``gym.make`` with
    another ``dt``).

    ## Arguments
    ``gym.make("MirrorPark-v0", config={...}, render_mode=None | "rgb_array" | "human")``;
    ``config`` overrides ``configs/env.yaml`` and ``configs/vehicle.yaml`` (``EnvConfig``);
    a bad value is rejected naming the field and its allowed range.

    ## Info
    Planners get the scene's geometry once, in the reset info (``info["geometry"]``), and
    the measured vehicle state every step (``info["vehicle_state"]``); they never read
    the simulator. Also: ``is_success``, ``collision``, ``failed_criterion``, ``margins``,
    ``heading_error``, ``direction_switches``, ``parking_time``, ``path_length``, and
    ``min_clearance`` / ``speed_at_min_clearance`` (the closest the car has come to any
    obstacle so far, a separating-axis gap over every sub-step, and its speed there), and
    the same once the rear axle is more than 1 m from its start (``*_away``: grid starts
    may touch a kerb, and driving off along it is not a close pass).
    """

    metadata = {"render_modes": ["human", "rgb_array"], "render_fps": 10}

    def __init__(self, config: dict[str, Any] | EnvConfig | None = None, render_mode: str | None = None):
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(
                f"render_mode: must be one of {self.metadata['render_modes']} or None, got {render_mode!r}"
            )
        self.cfg: EnvConfig = (
            config if isinstance(config, EnvConfig) else merge(default_env(), config, "MirrorPark-v0 config")
        )
        self.default_params = self.params = VehicleParams.from_config(self.cfg.vehicle)
        self.model = TruthModel(self.params, self.cfg.dt, self.cfg.substep)
        self.render_mode = render_mode
        self._renderer = Renderer(self.cfg.render, render_mode, self.cfg.dt) if render_mode is not None else None
        self.time = 0.0
        self.steps = 0
        self.done = False

        self.action_space = spaces.Box(-1.0, 1.0, shape=(2,), dtype=np.float32)
        goal = spaces.Box(-np.inf, np.inf, shape=(4,), dtype=np.float32)
        obs_spaces = {
            "observation": spaces.Box(-np.inf, np.inf, shape=(13,), dtype=np.float32),
            "achieved_goal": goal,
            "desired_goal": goal,
        }
        if self.cfg.lidar.rays:
            obs_spaces["lidar"] = spaces.Box(0.0, 1.0, shape=(self.cfg.lidar.rays,), dtype=np.float32)
        self.observation_space = spaces.Dict(obs_spaces)
        self._lidar = None
        self.geometry: ScenarioGeometry | None = None
        self._pool: np.ndarray | None = None
        self._heading_tol = math.radians(self.cfg.reward.goal_heading_tol_deg)

    # ------------------------------------------------------------------ episode
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        if options is not None and not isinstance(options, dict):
            raise ValueError(
                "reset options: expected a dict such as {'scenario': CASE_ID} or {'layout': PATH}, "
                f"got {type(options).__name__}"
            )
        options = options or {}
        unknown = set(options) - {"scenario", "layout", "lot"}
        if unknown:
            raise ValueError(f"reset options: unknown {sorted(unknown)}; allowed: ['layout', 'lot', 'scenario']")
        if sum(options.get(k) is not None for k in ("scenario", "layout", "lot")) > 1:
            raise ValueError("reset options: give one of 'scenario', 'layout' and 'lot'")
        layout = self._layout_from(options)
        params = layout.vehicle or self.default_params  # a scene's own car, else the config's
        told = layout.build(params)  # the scene the planners are told of
        self.perturbation = self._perturbation(layout, params)
        truth = params if self.perturbation is None else self.perturbation.truth
        if params != self.params or truth != self.model.params:
            self.params, self.model = params, TruthModel(truth, self.cfg.dt, self.cfg.substep)
        g = told if truth == params else dataclasses.replace(told, vehicle=truth)
        self.geometry, self.told_geometry = g, told  # the truth's scene (verdicts), the planners'
        self.criteria = SuccessCriteria(g, self.cfg.criteria)
        s = g.start
        self.state = np.array([s.x, s.y, s.theta, 0.0, 0.0, 0.0])
        self.time = 0.0
        self._substeps = 0
        self.steps = 0
        self.done = False
        self.switches = 0
        self.path_length = 0.0
        self._last_dir = 0
        self.collided = bool(g.checker.collides(s.x, s.y, s.theta)[0])
        self._free = not len(g.obstacles.polygons)  # a scene without obstacles
        self.min_clearance = float(self._gaps(np.array([[s.x, s.y, s.theta]]))[0])
        self.speed_at_min_clearance = 0.0
        self.min_clearance_away, self.speed_at_min_clearance_away = math.inf, 0.0
        onehot = [1.0 if t is g.parking_type else 0.0 for t in TYPES]
        sizes = [0.0 if math.isnan(v) else v / POS_SCALE for v in (g.road_width, g.slot_length, g.slot_width)]
        self._static_obs = np.array([*sizes, *onehot])
        if self.cfg.lidar.rays:
            self._lidar = Lidar(g.obstacles, self.cfg.lidar.rays, self.cfg.lidar.max_range)
        tx, ty, tth = g.target
        self._desired = np.array([tx / POS_SCALE, ty / POS_SCALE, math.cos(tth), math.sin(tth)], dtype=np.float32)
        if self._renderer is not None:
            self._renderer.reset(g, s.x, s.y, s.theta)
        obs = self._obs()
        info = self._info(False)
        info.update(scenario=layout.scenario, case_id=layout.case_id, geometry=told, layout=layout)
        return obs, info

    def _perturbation(self, layout: Layout, told: VehicleParams) -> Perturbation | None:
        """This episode's perturbation (``perturb.py``), seeded by the case; None when off."""
        if self.cfg.perturb is None:
            return None
        if layout.scenario is not None:
            key = layout.case_id
        else:
            from .layout_io import content_key

            key = content_key(layout)
        return Perturbation(self.cfg.perturb, told, self.cfg.dt, key)

    def _layout_from(self, options: dict[str, Any]) -> Layout:
        if options.get("lot") is not None:
            return self._lot_from(options["lot"])
        spec = options.get("layout")
        if spec is None:
            sc = self._scenario_from(options.get("scenario"))
            return grid_layout(sc, self.default_params, self.cfg.scene_margin)
        if isinstance(spec, Layout):
            spec.check_placement()  # a file's layouts are checked at load; one built in code here (reset builds it)
            return spec
        if isinstance(spec, (str, Path)):
            from .layout_io import load_layout

            return load_layout(spec)
        raise ValueError(f"reset options: 'layout' must be a Layout or a file path, got {type(spec).__name__}")

    def _lot_from(self, spec) -> Layout:
        """A generated lot (``lots.generate_lot``) for the config's car: ``{"level": L, "seed":
        S}``, or a level alone (its seed drawn from the env's generator)."""
        from .lots import LEVELS, generate_lot

        if isinstance(spec, dict) and set(spec) <= {"level", "seed"} and "level" in spec:
            level, seed = spec["level"], spec.get("seed")
        elif not isinstance(spec, (dict, bool)) and spec in LEVELS:
            level, seed = spec, None
        else:
            raise ValueError(
                f"reset options: 'lot' must be a level in {LEVELS} or {{'level': L, 'seed': S}}, got {spec!r}"
            )
        if seed is None:
            seed = int(self.np_random.integers(2**31))
        return generate_lot(seed, level, self.default_params)

    def _scenario_from(self, spec: Scenario | str | None) -> Scenario:
        if isinstance(spec, Scenario):
            return spec
        if isinstance(spec, str):
            return Scenario.from_case_id(spec)
        if spec is not None:
            raise ValueError(f"reset options: 'scenario' must be a Scenario or a case id, got {type(spec).__name__}")
        grid = grid_for(self.default_params)  # only cases that can be generated for this car
        if self._pool is None:
            self._pool = np.concatenate([grid.indices(t) for t in self.cfg.parking_types])
            if not len(self._pool):
                raise ValueError(
                    f"vehicle: no Table III case of {', '.join(self.cfg.parking_types)} fits a car "
                    f"{self.default_params.length:.2f} m long and {self.default_params.width:.2f} m wide"
                )
        return grid.scenario(int(self._pool[self.np_random.integers(len(self._pool))]))

    def step(self, action):
        if self.geometry is None:
            raise RuntimeError("MirrorPark-v0: call reset() before step()")
        if self.done:
            raise RuntimeError("MirrorPark-v0: the episode has ended; call reset()")
        a_cmd, d_cmd = from_action(self.params, action)
        if self.perturbation is not None:  # the truth's actuators take what reaches them
            a_cmd, d_cmd = self.perturbation.commands.apply(a_cmd, d_cmd)
        traj = self.model.step(self.state, a_cmd, d_cmd)
        gap = self._gaps(traj)
        hit = gap < -COLLISION_TOL
        n_sub = len(traj)
        if hit.any():
            n_sub = int(np.argmax(hit)) + 1
            traj, gap = traj[:n_sub], gap[:n_sub]
            self.collided = True
        i = int(np.argmin(gap))
        if gap[i] < self.min_clearance:  # the closest the car has come to any obstacle
            self.min_clearance, self.speed_at_min_clearance = float(gap[i]), float(abs(traj[i, 3]))
        away = np.hypot(traj[:, 0] - self.geometry.start.x, traj[:, 1] - self.geometry.start.y) > AWAY
        if away.any():
            j = int(np.argmin(np.where(away, gap, np.inf)))
            if gap[j] < self.min_clearance_away:
                self.min_clearance_away, self.speed_at_min_clearance_away = float(gap[j]), float(abs(traj[j, 3]))
        self.path_length += float(traj[:, 6].sum())
        self._count_switches(traj[:, 3].tolist())
        self.state = traj[-1, :6]
        self._substeps += n_sub
        self.time = round(self._substeps * self.model.h, 9)  # no drift from summing 0.1 s
        self.steps += 1
        x, y, th = self.state[:3].tolist()
        box = self.geometry.bounds
        out = not (box[0] <= x <= box[1] and box[2] <= y <= box[3])
        late = (
            None
            if self.perturbation is None
            else self.perturbation.late_obstacle(self.time, self.state, self._last_dir)
        )
        if late is not None:
            self._add_obstacle(late)
        obs = self._obs()
        info = self._info(out)
        if late is not None:  # the scene changed: the planners are told once, as at reset
            info["geometry"] = self.told_geometry
        terminated = bool(info["is_success"] or self.collided or out)
        truncated = False  # the time limit is the registration's max_episode_steps (TimeLimit)
        self.done = terminated
        achieved = obs["achieved_goal"] if self.perturbation is None else self._goal(self.state)  # the truth's
        reward = float(self.compute_reward(achieved, obs["desired_goal"], info))
        if self._renderer is not None:
            self._renderer.update(x, y, th, self.state[3])
        return obs, reward, terminated, truncated, info

    def _add_obstacle(self, corners: np.ndarray) -> None:
        """A new obstacle part in the truth's scene and in the one the planners are told of."""
        obstacles = ConvexSet.from_polygons([*self.geometry.obstacles.polygons, corners])  # the two scenes share it
        self.geometry, self.told_geometry = (
            dataclasses.replace(g, obstacles=obstacles) for g in (self.geometry, self.told_geometry)
        )
        self._free = False
        if self._lidar is not None:
            self._lidar = Lidar(self.geometry.obstacles, self.cfg.lidar.rays, self.cfg.lidar.max_range)
        if self._renderer is not None:
            self._renderer.add_obstacle(corners)

    def _gaps(self, traj: np.ndarray) -> np.ndarray:
        """Each sub-step's gap to the nearest obstacle: the separating-axis gap, a lower bound
        on the Euclidean distance (< 0: overlap)."""
        if self._free:
            return np.full(len(traj), np.inf)
        return -self.geometry.checker.penetration(traj[:, 0], traj[:, 1], traj[:, 2]).max(axis=1)

    def _count_switches(self, speeds: list[float]) -> None:
        """A switch is a change of driving direction between two movements."""
        last = self._last_dir
        for v in speeds:
            if abs(v) > V_EPS:
                d = 1 if v > 0 else -1
                if last != 0 and d != last:
                    self.switches += 1
                last = d
        self._last_dir = last

    # ------------------------------------------------------------ observation
    def _measure(self) -> None:
        """The state the planners observe this step: the truth's, or with the noise drawn."""
        if self.perturbation is None:
            self.measured = VehicleState(*self.state.tolist())
        else:
            self.measured = self.perturbation.noise.measure(self.state)

    @staticmethod
    def _goal(state: np.ndarray) -> np.ndarray:
        """The achieved goal of a true state (``_obs``'s first four entries)."""
        x, y, th = (float(q) for q in state[:3])
        return np.array([x / POS_SCALE, y / POS_SCALE, math.cos(th), math.sin(th)], dtype=np.float32)

    def _obs(self) -> dict[str, np.ndarray]:
        self._measure()
        m = self.measured
        x, y, th, v, a, d = m.x, m.y, m.theta, m.v, m.a, m.delta
        p = self.params
        c, s = math.cos(th), math.sin(th)
        x, y = x / POS_SCALE, y / POS_SCALE
        obs = np.empty(13, dtype=np.float32)
        obs[:7] = (x, y, c, s, v / p.speed_max, a / abs(p.accel_min), d / p.max_steer_rad)
        obs[7:] = self._static_obs
        out = {
            "observation": obs,
            "achieved_goal": obs[:4].copy(),
            "desired_goal": self._desired.copy(),
        }
        if self._lidar is not None:
            out["lidar"] = self._lidar.read_body(  # the sensor sits on the true car
                self.state[0], self.state[1], float(self.state[2]), self.model.params.center_offset
            )
        return out

    def _info(self, out_of_scene: bool) -> dict[str, Any]:
        x, y, th, v, a, d = self.state.tolist()
        verdict = self.criteria.verdict(x, y, th, v, self.time, self.collided)
        failed = "out_of_scene" if out_of_scene and not verdict.success else verdict.failed
        return {
            "is_success": verdict.success,
            "collision": self.collided,
            "out_of_scene": out_of_scene,
            "failed_criterion": failed,
            "margins": verdict.margins,
            "heading_error": verdict.heading_error,
            "heading_error_deg": math.degrees(verdict.heading_error),
            "inside_slot": verdict.inside_slot,
            "stopped": verdict.stopped,
            "direction_switches": self.switches,
            "parking_time": self.time,
            "path_length": self.path_length,
            "min_clearance": self.min_clearance,  # [m] closest to any obstacle so far (separating-axis gap)
            "speed_at_min_clearance": self.speed_at_min_clearance,  # [m/s] |v| at that moment
            "min_clearance_away": self.min_clearance_away,  # [m] the same, over poses > 1 m from the start
            "speed_at_min_clearance_away": self.speed_at_min_clearance_away,
            "vehicle_state": self.measured,  # what the planners observe (``_obs`` measures it)
        } | ({} if self.perturbation is None else {"true_state": VehicleState(x, y, th, v, a, d)})

    # ------------------------------------------------------------------ reward
    def compute_reward(self, achieved_goal, desired_goal, info) -> np.ndarray | float:
        """Goal-conditioned reward; vectorised over leading axes (HER relabels goals)."""
        r = self.cfg.reward
        if isinstance(info, dict) and np.ndim(achieved_goal) == 1:  # one transition: scalar path
            ax, ay, ac, as_ = (float(q) for q in achieved_goal)
            dx, dy, dc, ds_ = (float(q) for q in desired_goal)
            dpos = math.hypot(ax - dx, ay - dy) * POS_SCALE
            dth = abs(math.atan2(as_ * dc - ac * ds_, ac * dc + as_ * ds_))
            reached = dpos <= r.goal_position_tol and dth <= self._heading_tol
            return (
                -(dpos + r.heading_weight * dth) / r.distance_scale
                + r.success_bonus * reached
                + r.collision_penalty * bool(info.get("collision", False))
            )
        ag = np.asarray(achieved_goal, dtype=float)
        dg = np.asarray(desired_goal, dtype=float)
        # math's hypot and atan2 element by element, as the scalar path: numpy's own differ
        # from them in the last bits, and a relabelled reward must equal the step's exactly
        # (stable-baselines3's check_env compares them; 5 of 150 seeded checks failed).
        dpos = np.asarray(_HYPOT(ag[..., 0] - dg[..., 0], ag[..., 1] - dg[..., 1]), dtype=float) * POS_SCALE
        cross = ag[..., 3] * dg[..., 2] - ag[..., 2] * dg[..., 3]
        dot = ag[..., 2] * dg[..., 2] + ag[..., 3] * dg[..., 3]
        dth = np.abs(np.asarray(_ATAN2(cross, dot), dtype=float))
        reward = -(dpos + r.heading_weight * dth) / r.distance_scale
        reached = (dpos <= r.goal_position_tol) & (dth <= self._heading_tol)
        reward = reward + r.success_bonus * reached + r.collision_penalty * _collisions(info, reward.shape)
        return reward if reward.ndim else float(reward)

    # --------------------------------------------------------------- rendering
    def render(self):
        if self.render_mode is None:
            gym.logger.warn('MirrorPark-v0: no render_mode; use gym.make("MirrorPark-v0", render_mode="rgb_array")')
            return None
        if self.geometry is None:
            raise RuntimeError("MirrorPark-v0: call reset() before render()")
        return self._renderer.render()

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()


def _collisions(info, shape) -> np.ndarray:
    if isinstance(info, dict):
        return np.full(shape, float(info.get("collision", False)))
    if info is None:
        return np.zeros(shape)
    flags = np.array([float(i.get("collision", False)) for i in np.ravel(info)])
    return flags.reshape(shape) if flags.size == int(np.prod(shape)) else np.zeros(shape)
