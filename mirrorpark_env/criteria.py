"""ISO 16787 / ISO 20900 success criteria as the paper states them (Figs. 17, 18).

Margins are signed distances in metres from the car's outline to the slot's sides,
positive inside the slot (figures of the paper are lost; the reading below is ours and
is documented in docs/verdicts.md):

- parallel: ``M_f`` / ``M_r``: gap between the car's outline and the slot's front / rear
  end; ``M_e``: gap between the outline and the slot line (the outer, road-side edge).
  Success needs all three > 0.
- reverse and angle: ``M_fl``, ``M_fr``, ``M_rl``, ``M_rr``: gap between each corner
  (front-left, ...) and the slot side line on that side of the car; ``M_e``: gap between
  the outline and the slot's entrance (how far the car is in). Success needs all five
  >= ``min_margin_perpendicular`` (0.1 m).

All types also need: |heading error| <= 3 deg, parking time < 180 s, no collision, the
whole outline inside the slot, and the car stopped.

A layout without a slot has no sides to measure: its one margin ``M_pos`` is
``target_position_tol`` less the rear axle's distance from the target's, and success needs
it >= 0 with the same heading, time, collision and standstill checks.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .angles import wrap_angle
from .config import CriteriaConfig
from .scenario import ParkingType, ScenarioGeometry
from .vehicle import CORNER_NAMES, VehicleParams

# Order in which a failing criterion is reported (the first that fails).
CRITERIA = ("collision", "time", "heading", "inside_slot", "margins", "stopped")


@dataclass(frozen=True)
class Verdict:
    """The outcome of the success check at one instant."""

    success: bool
    failed: str | None  # first failing criterion of CRITERIA, None on success
    margins: dict[str, float]
    heading_error: float  # [rad]
    inside_slot: bool
    stopped: bool
    collision: bool


class SuccessCriteria:
    """Precomputed success check for one scenario geometry."""

    def __init__(self, geometry: ScenarioGeometry, cfg: CriteriaConfig | None = None):
        cfg = cfg or CriteriaConfig()
        self.cfg = cfg
        self.geometry = geometry
        self.vehicle = geometry.vehicle
        self.heading_tol = math.radians(cfg.heading_tol_deg)
        self.target_heading = geometry.target[2]
        self.no_slot = geometry.slot is None
        if self.no_slot:
            self.margin_names, self._min_margin, self._strict = ("M_pos",), 0.0, False
            self._pos_tol = cfg.target_position_tol
            return
        names = [n for n, _ in geometry.slot_edges]
        self._edge_index = {n: i for i, n in enumerate(names)}
        self._normals = np.array([hp.normal for _, hp in geometry.slot_edges])  # (4, 2)
        self._offsets = np.array([hp.offset for _, hp in geometry.slot_edges])  # (4,)
        self.parallel = geometry.parking_type is ParkingType.PARALLEL
        corner = {n: i for i, n in enumerate(CORNER_NAMES)}
        e = self._edge_index
        if self.parallel:
            self.margin_names = ("M_f", "M_r", "M_e")
            self._min_margin = 0.0
            self._strict = True
            self._spec = ((None, e["front"]), (None, e["rear"]), (None, e["entrance"]))
        else:
            self.margin_names = ("M_fl", "M_fr", "M_rl", "M_rr", "M_e")
            self._min_margin = cfg.min_margin_perpendicular
            self._strict = False
            self._spec = (
                (corner["front_left"], e["left"]),
                (corner["front_right"], e["right"]),
                (corner["rear_left"], e["left"]),
                (corner["rear_right"], e["right"]),
                (None, e["entrance"]),
            )
        self._body = [tuple(b) for b in self.vehicle.body_corners().tolist()]
        self._edges = [(hp.normal[0], hp.normal[1], hp.offset) for _, hp in geometry.slot_edges]

    def as_arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
        """What ``verdict``'s margins are computed from, for compiled checks: the body corners
        (4, 2), the slot's edges as (normal x, normal y, offset) rows, the margins as (corner
        or -1 for the lowest over the corners, edge) rows, and the position tolerance of a
        scene without a slot (its only margin; the arrays are then empty)."""
        if self.no_slot:
            return np.zeros((4, 2)), np.zeros((1, 3)), np.zeros((1, 2), np.int64), self._pos_tol
        spec = np.array([(-1 if c is None else c, e) for c, e in self._spec], np.int64)
        return np.array(self._body, float), np.array(self._edges, float), spec, 0.0

    @property
    def min_margin(self) -> float:
        """The smallest margin success allows (parallel: strictly more than this)."""
        return self._min_margin

    def edge_distances(self, corners: np.ndarray) -> np.ndarray:
        """Signed distance of each corner to each slot edge, (4 corners, 4 edges)."""
        return corners @ self._normals.T - self._offsets

    def margins(self, x: float, y: float, theta: float) -> dict[str, float]:
        if self.no_slot:
            return {"M_pos": self._pos_tol - math.hypot(x - self.geometry.target[0], y - self.geometry.target[1])}
        return self._margins_from(self._edge_distances_at(x, y, theta))

    def _edge_distances_at(self, x: float, y: float, theta: float) -> list[list[float]]:
        """d[corner][edge] in plain floats: for 4 x 4 values Python beats numpy."""
        c, s = math.cos(theta), math.sin(theta)
        out = []
        for bx, by in self._body:
            px, py = x + c * bx - s * by, y + s * bx + c * by
            out.append([nx * px + ny * py - off for nx, ny, off in self._edges])
        return out

    def _margins_from(self, d) -> dict[str, float]:
        return {
            name: float(d[ci][ei]) if ci is not None else float(min(row[ei] for row in d))
            for name, (ci, ei) in zip(self.margin_names, self._spec)
        }

    def verdict(
        self,
        x: float,
        y: float,
        theta: float,
        v: float,
        elapsed: float,
        collided: bool,
    ) -> Verdict:
        herr = wrap_angle(theta - self.target_heading)
        if self.no_slot:
            margins = self.margins(x, y, theta)
            inside = margins["M_pos"] >= 0.0  # no slot: "inside" is within the position tolerance
        else:
            d = self._edge_distances_at(x, y, theta)
            margins = self._margins_from(d)
            inside = min(min(row) for row in d) >= -1e-12
        stopped = abs(v) < self.cfg.stop_speed
        lowest = min(margins.values())
        margins_ok = lowest > self._min_margin if self._strict else lowest >= self._min_margin - 1e-12
        checks = (
            ("collision", not collided),
            ("time", elapsed < self.cfg.time_limit_s),
            ("heading", abs(herr) <= self.heading_tol + 1e-12),
            ("inside_slot", inside),
            ("margins", margins_ok),
            ("stopped", stopped),
        )
        failed = next((name for name, ok in checks if not ok), None)
        return Verdict(failed is None, failed, margins, herr, inside, stopped, collided)


def iso_pose_exists(parking_type, slot_length, slot_width, vehicle: VehicleParams, cfg: CriteriaConfig | None = None):
    """Whether any pose in a slot passes the ISO check, for arrays of slot sizes.

    Exact: the margins are distances from the outline to the slot's sides, and turning the
    car by any heading error widens its outline along both of the slot's axes (by
    L sin(phi) + W cos(phi) >= W and L cos(phi) + W sin(phi) >= L for |phi| <= 3 deg), so
    the best pose is aligned with the slot, centred across it, and along it centred
    (parallel: front and rear margins) or against the back (reverse, angle: the entrance
    margin is then SL - L):

    - parallel: M_f, M_r > 0 and M_e > 0 (the kerb side >= 0): SL > L and SW > W;
    - reverse, angle: four side margins >= m and the entrance margin >= m (m = 0.1 m):
      SW >= W + 2 m and SL >= L + m.
    """
    slack = iso_pose_slack(parking_type, slot_length, slot_width, vehicle, cfg)
    tol = 1e-9  # parallel margins must be > 0, the others >= m
    return np.where(np.asarray(parking_type) == ParkingType.PARALLEL.value, slack > tol, slack >= -tol)


def iso_pose_slack(parking_type, slot_length, slot_width, vehicle: VehicleParams, cfg: CriteriaConfig | None = None):
    """How much room to spare the best pose in a slot has [m], for arrays of slot sizes:
    the largest amount by which every ISO margin can exceed its limit at once (negative:
    no ISO pose; zero: exactly one, which no real car hits).

    From the same best poses as ``iso_pose_exists``: parallel min((SL - L) / 2, SW - W)
    (front and rear margins split the spare length; the kerb side may be 0, so the entrance
    margin takes all the spare width); reverse and angle min((SW - W) / 2 - m, SL - L - m).
    """
    cfg = cfg or CriteriaConfig()
    ptype = np.asarray(parking_type)
    sl, sw = np.asarray(slot_length, float), np.asarray(slot_width, float)
    L, W, m = vehicle.length, vehicle.width, cfg.min_margin_perpendicular
    parallel = np.minimum((sl - L) / 2, sw - W)
    perpendicular = np.minimum((sw - W) / 2 - m, sl - L - m)
    return np.where(ptype == ParkingType.PARALLEL.value, parallel, perpendicular)
