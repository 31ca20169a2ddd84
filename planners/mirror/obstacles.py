"""The disjunctive obstacle rows of Eq. (40), linearised about a reference rollout.

Each feature point of the car (the paper's six: corners and the middles of the long sides)
must stay behind one face of an obstacle, and each obstacle vertex that could pierce the
car behind one face of the car. A row per alternative; the alternatives of one point or
vertex form a ``Disjunction`` (at least one holds), solved by branch and bound. Rows are
written on the real body: before the switch on p + R(theta) c, after it on
2 S - p + R(theta) c (``frames.real_pose_coeffs``), linear in the variables for a fixed s.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from mirrorpark_env.scenario import ScenarioGeometry

from .frames import XI_TH, XI_X, XI_Y, real_pose_coeffs
from .layout import ix, switch_index
from .plans import Candidate
from .solvers import INACTIVE, Disjunction


@dataclass
class Rows:
    """Inequality rows h_l <= G z <= h_u as triplets, with the disjunctions among them."""

    g_rows: list[int] = field(default_factory=list)
    g_cols: list[int] = field(default_factory=list)
    g_vals: list[float] = field(default_factory=list)
    h_l: list[float] = field(default_factory=list)
    h_u: list[float] = field(default_factory=list)
    active: list[float] = field(default_factory=list)  # each row's lower bound when it is enforced
    disj: list[Disjunction] = field(default_factory=list)
    preferred: list[int] = field(default_factory=list)  # per disjunction, the row the reference satisfies best

    def add_row(self, i: int, iS: int, coef_p, coef_th: float, sign: float, twice: float) -> int:
        """A row on the real pose at step ``i`` (real p = sign * p_i + twice * S); its index."""
        r = len(self.h_u)  # h_u grows per row at once, h_l only when the group is registered
        self.g_rows.extend([r, r, r])
        self.g_cols.extend([ix(i, XI_X), ix(i, XI_Y), ix(i, XI_TH)])
        self.g_vals.extend([sign * coef_p[0], sign * coef_p[1], coef_th])
        if twice:
            self.g_rows.extend([r, r])
            self.g_cols.extend([iS, iS + 1])
            self.g_vals.extend([twice * coef_p[0], twice * coef_p[1]])
        self.h_u.append(np.inf)
        return r

    def register(self, alts: list[tuple[int, float]], best: int) -> None:
        """Close the rows just added as one constraint (a single face) or a disjunction."""
        if len(alts) == 1:  # a single face: an ordinary constraint
            _, lo = alts[0]
            self.h_l.append(lo)
            self.active.append(lo)
            return
        for _, lo in alts:
            self.h_l.append(INACTIVE)
            self.active.append(lo)
        self.disj.append(Disjunction(tuple(r for r, _ in alts)))
        self.preferred.append(alts[best][0])


class ObstacleRows:
    """Builds Eq. (40)'s rows for one scenario: its useful faces and vertices are found once."""

    def __init__(self, geometry: ScenarioGeometry, margin: float, horizon: int, substeps: int):
        p = geometry.vehicle
        self.params = p
        self.margin = margin
        self.substeps = substeps
        self.iS = switch_index(horizon)
        self.faces, self.vertices = useful_features(geometry)
        hw = 0.5 * p.width
        mid = 0.5 * (p.front_length - p.rear_overhang)
        # The paper's six feature points: corners and the middles of the long sides.
        self.points = np.array(
            [
                [p.front_length, hw],
                [p.front_length, -hw],
                [-p.rear_overhang, -hw],
                [-p.rear_overhang, hw],
                [mid, hw],
                [mid, -hw],
            ]
        )
        # Car faces as (body normal, offset): front, rear, left, right.
        self.car_faces = (
            (np.array([1.0, 0.0]), p.front_length),
            (np.array([-1.0, 0.0]), p.rear_overhang),
            (np.array([0.0, 1.0]), hw),
            (np.array([0.0, -1.0]), hw),
        )

    def add(self, rows: Rows, cand: Candidate, ref_real: np.ndarray, theta_set) -> None:
        """Rows at the (step, obstacle) pairs in ``theta_set``, linearised about ``ref_real``."""
        ref = ref_real[:: self.substeps]  # real states at the control steps
        for i, k in sorted(theta_set):
            sign, twice = real_pose_coeffs(i, cand)
            th = ref[i, XI_TH]
            ct, st_ = math.cos(th), math.sin(th)
            self._points_outside(rows, i, k, ref[i, :2], th, ct, st_, sign, twice)
            self._vertices_outside(rows, i, k, ref[i, :2], th, ct, st_, sign, twice)

    def _points_outside(self, rows, i, k, Pbar, th, ct, st_, sign, twice) -> None:
        """Each feature point behind one face of obstacle ``k``."""
        faces = self.faces[k]
        for cx, cy in self.points:
            rc = np.array([ct * cx - st_ * cy, st_ * cx + ct * cy])  # R(th) c
            drc = np.array([-st_ * cx - ct * cy, ct * cx - st_ * cy])  # dR/dth c
            q_ref = Pbar + rc
            slack = [float(nrm @ q_ref) - off for nrm, off in faces]
            if not faces or max(slack) > 1.0:
                continue  # far outside: this point cannot reach the obstacle here
            alts = []
            for nrm, off in faces:
                coef_th = float(nrm @ drc)
                lower = off + self.margin - float(nrm @ (rc - th * drc))
                alts.append((rows.add_row(i, self.iS, nrm, coef_th, sign, twice), lower))
            rows.register(alts, int(np.argmax(slack)))

    def _vertices_outside(self, rows, i, k, Pbar, th, ct, st_, sign, twice) -> None:
        """Each nearby vertex of obstacle ``k`` behind one face of the car."""
        centre = Pbar + self.params.center_offset * np.array([ct, st_])
        for q in self.vertices[k]:
            if np.hypot(*(q - centre)) > 0.5 * self.params.length + 1.5:
                continue
            alts, slack = [], []
            for nb, off in self.car_faces:
                nw = np.array([ct * nb[0] - st_ * nb[1], st_ * nb[0] + ct * nb[1]])
                dnw = np.array([-st_ * nb[0] - ct * nb[1], ct * nb[0] - st_ * nb[1]])
                # nw(th).(q - P) >= off + margin, linearised about (th, Pbar)
                k_th = float(dnw @ (q - Pbar))
                lower = off + self.margin - float(nw @ q) + k_th * th
                alts.append((rows.add_row(i, self.iS, -nw, k_th, sign, twice), lower))
                slack.append(float(nw @ (q - Pbar)) - off)
            rows.register(alts, int(np.argmax(slack)))


def useful_features(g: ScenarioGeometry):
    """Per obstacle: faces next to free space near the slot, and vertices that can pierce the car.

    A face (outward normal n, offset b: outside is n.q >= b) is useful when some point
    just outside it, within the window around the slot and road, is free of obstacles.
    """
    polys = g.obstacles.polygons
    slot = g.slot
    x_lo, x_hi = float(slot[:, 0].min()) - 8.0, float(slot[:, 0].max()) + 10.0
    y_lo, y_hi = float(slot[:, 1].min()) - 0.5, g.road_width + 0.5

    def free(q):
        if not (x_lo <= q[0] <= x_hi and y_lo <= q[1] <= y_hi):
            return False
        return not any(_inside(poly, q) for poly in polys)

    faces, vertices = [], []
    for poly in polys:
        f, useful_edge = [], []
        n_v = len(poly)
        for e in range(n_v):
            a, b = poly[e], poly[(e + 1) % n_v]
            d = b - a
            n = np.array([d[1], -d[0]]) / np.hypot(*d)  # outward for CCW
            pts = [a + t * d + 0.05 * n for t in np.linspace(0.02, 0.98, 41)]
            ok = any(free(q) for q in pts)
            useful_edge.append(ok)
            if ok:
                f.append((n, float(n @ a)))
        faces.append(f)
        vs = [
            poly[e]
            for e in range(n_v)
            if useful_edge[e] and useful_edge[e - 1] and x_lo <= poly[e][0] <= x_hi and y_lo <= poly[e][1] <= y_hi
        ]
        vertices.append(vs)
    return faces, vertices


def _inside(poly: np.ndarray, q) -> bool:
    d = np.roll(poly, -1, axis=0) - poly
    cross = d[:, 0] * (q[1] - poly[:, 1]) - d[:, 1] * (q[0] - poly[:, 0])
    return bool(np.all(cross > 1e-12))
