"""Drawing a scenario with highway-env's road, lane and vehicle graphics.

highway-env draws world +Y downwards; the scene is handed to it in a display frame with
Y flipped (``y_disp = -y``, ``heading_disp = -theta``) so that pictures show the road
above the slot, as in the paper's figures. Rendering only: nothing here feeds back into
the simulation.
"""

from __future__ import annotations

import os
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from .config import RenderConfig
    from .scenario import ScenarioGeometry


def prepare_headless(render_mode: str | None) -> None:
    """Make ``rgb_array`` work without a screen: SDL's offscreen driver (``dummy`` draws black)."""
    if render_mode == "rgb_array" and os.environ.get("SDL_VIDEODRIVER", "dummy") == "dummy":
        os.environ["SDL_VIDEODRIVER"] = "offscreen"
    os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")


def build_road(geometry: ScenarioGeometry, np_random=None):
    """A highway-env ``Road`` with the driving strip and the slot's painted lines."""
    from highway_env.road.lane import LineType, StraightLane
    from highway_env.road.road import Road, RoadNetwork

    x_lo, x_hi, _, _ = geometry.bounds  # the rear axle's box: the road reaches a car length beyond
    x_lo, x_hi = x_lo - geometry.vehicle.length, x_hi + geometry.vehicle.length
    rw = geometry.road_width
    net = RoadNetwork()
    c, n = LineType.CONTINUOUS_LINE, LineType.NONE
    grid = geometry.scenario is not None
    if grid:  # a layout names no road: its obstacles are drawn as they are
        net.add_lane("road", "end", StraightLane([x_lo, -rw / 2], [x_hi, -rw / 2], width=rw, line_types=(c, c)))
    slot = geometry.slot
    names = [name for name, _ in geometry.slot_edges]
    for i in range(4 if slot is not None else 0):  # the slot's sides painted, as one narrow lane each
        a, b = slot[i], slot[(i + 1) % 4]
        if grid and names[i] == "entrance" and geometry.parking_type.value != "angle":
            continue  # lies on the road's own edge line
        net.add_lane(f"slot{i}", f"slot{i}e", StraightLane([a[0], -a[1]], [b[0], -b[1]], width=0.15, line_types=(c, n)))
    return Road(network=net, np_random=np_random, record_history=False)


class Scene:
    """The highway-env objects that stand for the car and the target in the picture."""

    def __init__(self, geometry: ScenarioGeometry, np_random=None):
        from highway_env.vehicle.graphics import VehicleGraphics
        from highway_env.vehicle.kinematics import Vehicle
        from highway_env.vehicle.objects import Landmark

        self.geometry = geometry
        p = geometry.vehicle
        self.road = build_road(geometry, np_random)
        tx, ty, tth = geometry.target
        off = p.center_offset
        goal = Landmark(self.road, [tx + off * np.cos(tth), -(ty + off * np.sin(tth))], heading=-tth)
        goal.LENGTH, goal.WIDTH = p.length, p.width
        self.road.objects.append(goal)
        s = geometry.start
        self.ego = Vehicle(self.road, [s.x, -s.y], heading=-s.theta, speed=0.0)
        self.ego.LENGTH, self.ego.WIDTH = p.length, p.width
        self.ego.color = VehicleGraphics.EGO_COLOR
        self.road.vehicles.append(self.ego)
        self.path: list[tuple[float, float]] = []

    def update(self, x: float, y: float, theta: float, v: float) -> None:
        off = self.geometry.vehicle.center_offset
        cx, cy = x + off * np.cos(theta), y + off * np.sin(theta)
        self.ego.position = np.array([cx, -cy])
        self.ego.heading = -theta
        self.ego.speed = v
        self.path.append((x, -y))


class Renderer:
    """Draws one environment's scene with highway-env's viewer; owned by the env (composition).

    highway-env's ``EnvViewer`` reads a few attributes of the object it draws (``config``,
    ``road``, ``action_type``, ``observation_type``, ``close``): this object provides them,
    so the env itself stays a plain ``gymnasium.Env``. ``"human"`` opens a window (any SDL
    video driver; with ``SDL_VIDEODRIVER=dummy`` it draws nothing), ``"rgb_array"`` draws
    offscreen.
    """

    action_type = None  # no keyboard control of the car
    observation_type = None  # nothing observation-specific to draw

    def __init__(self, render: RenderConfig, mode: str, dt: float):
        prepare_headless(mode)
        self.mode = mode
        # Keys read by highway-env's EnvViewer.
        self.config = {
            "screen_width": render.screen_width,
            "screen_height": render.screen_height,
            "scaling": render.scaling,
            "centering_position": [0.5, 0.5],
            "offscreen_rendering": mode != "human",
            "render_agent": True,
            "real_time_rendering": False,
            "simulation_frequency": round(1 / dt),
            "policy_frequency": round(1 / dt),
            "show_trajectories": False,
            "manual_control": False,
        }
        self.geometry: ScenarioGeometry | None = None
        self.late: list[np.ndarray] = []
        self.scene: Scene | None = None
        self.road = None
        self.viewer = None

    def reset(self, geometry: ScenarioGeometry, x: float, y: float, theta: float) -> None:
        self.geometry = geometry
        self.late: list[np.ndarray] = []  # obstacles that appeared during the episode
        self.scene = Scene(geometry)
        self.road = self.scene.road
        self.scene.update(x, y, theta, 0.0)
        if self.mode == "human":
            self.render()

    def add_obstacle(self, corners: np.ndarray) -> None:
        """Draw an obstacle that appeared during the episode (a late obstacle) from now on."""
        self.late.append(np.asarray(corners, dtype=float))

    def update(self, x: float, y: float, theta: float, v: float) -> None:
        self.scene.update(x, y, theta, v)
        if self.mode == "human":
            self.render()

    def render(self) -> np.ndarray | None:
        """The frame (``rgb_array``), or None after drawing it in the window (``human``)."""
        if self.viewer is None:
            self.viewer = make_viewer(self)
        self.viewer.display()
        if not self.viewer.offscreen:
            self.viewer.handle_events()
        return self.viewer.get_image() if self.mode == "rgb_array" else None

    def close(self) -> None:
        if self.viewer is not None:
            self.viewer.close()
            self.viewer = None


def make_viewer(renderer: Renderer):
    """highway-env's ``EnvViewer`` drawing the obstacles, the slot, the target and the car."""
    import pygame
    from highway_env.envs.common.graphics import EnvViewer
    from highway_env.road.graphics import LaneGraphics, RoadGraphics

    class MirrorParkViewer(EnvViewer):
        OBSTACLE = (70, 70, 78)
        OBSTACLE_EDGE = (35, 35, 40)
        PATH = (255, 255, 255)

        def window_position(self) -> np.ndarray:
            g = self.env.geometry
            if g.scenario is None:  # a layout: between the start and the target
                mid = 0.5 * (np.asarray(g.target[:2]) + np.array([g.start.x, g.start.y]))
                return np.array([mid[0], -mid[1]])
            x_mid = 0.5 * (g.slot[:, 0].min() + g.slot[:, 0].max()) + 3.0
            y_mid = 0.5 * (g.road_width + g.slot[:, 1].min())
            return np.array([x_mid, -y_mid])

        def display(self) -> None:
            if not self.enabled or self.env.scene is None:
                return
            surf = self.sim_surface
            scene = self.env.scene
            surf.move_display_window_to(self.window_position())
            surf.fill((118, 118, 118))
            g = self.env.geometry
            polys = g.obstacles.polygons if g.layout is None or g.scenario is not None else g.layout.obstacles
            for poly in [*polys, *self.env.late]:  # a layout's obstacles as given (not their convex parts)
                pts = [surf.pos2pix(px, -py) for px, py in poly]
                pygame.draw.polygon(surf, self.OBSTACLE, pts)
                pygame.draw.polygon(surf, self.OBSTACLE_EDGE, pts, 2)
            for _from, tos in scene.road.network.graph.items():
                for lanes in tos.values():
                    for lane in lanes:
                        LaneGraphics.display(lane, surf)
            RoadGraphics.display_road_objects(scene.road, surf, offscreen=self.offscreen)
            if len(scene.path) > 1:
                pygame.draw.lines(surf, self.PATH, False, [surf.vec2pix(p) for p in scene.path], 1)
            RoadGraphics.display_traffic(scene.road, surf, offscreen=self.offscreen)
            if not self.offscreen:
                self.screen.blit(surf, (0, 0))
                pygame.display.flip()

    return MirrorParkViewer(renderer)
