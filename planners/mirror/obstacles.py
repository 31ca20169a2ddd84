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
from .plans import Candidate
from .solvers import INACTIVE, Disjunction
from .variables import ix, switch_index


@dataclass
class Rows:
    """Inequality rows h_l <= G z <= h_u, their G as blocks of (row, column, value)
    triplets, with the disjunctions among them."""

    h_l: list[float] = field(default_factory=list)
    h_u: list[float] = field(default_factory=list)
    active: list[float] = field(default_factory=list)  # each row's lower bound when it is enforced
    disj: list[Disjunction] = field(default_factory=list)
    preferred: list[int] = field(default_factory=list)  # per disjunction, the row the reference satisfies best
    blocks: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = field(default_factory=list)

    def extend(self, g_rows: np.ndarray, g_cols: np.ndarray, g_vals: np.ndarray) -> None:
        """Add a block of triplets."""
        self.blocks.append((g_rows, g_cols, g_vals))

    def triplets(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(rows, cols, values) of every triplet, block after block."""
        empty = (np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0))
        return tuple(np.concatenate([p[j] for p in [empty, *self.blocks]]) for j in range(3))


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

        # The same, padded into arrays (a mask marks the real entries) for ``add``.
        n_f = max([len(f) for f in self.faces] + [1])
        n_v = max([len(v) for v in self.vertices] + [1])
        n_o = len(self.faces)
        self._f0, self._f1, self._foff = np.zeros((n_o, n_f)), np.zeros((n_o, n_f)), np.zeros((n_o, n_f))
        self._fvalid = np.zeros((n_o, n_f), bool)
        self._nfaces = np.array([len(f) for f in self.faces], np.int64)
        self._v0, self._v1 = np.zeros((n_o, n_v)), np.zeros((n_o, n_v))
        self._vvalid = np.zeros((n_o, n_v), bool)
        for k, (faces, verts) in enumerate(zip(self.faces, self.vertices)):
            for f, (nrm, off) in enumerate(faces):
                self._f0[k, f], self._f1[k, f], self._foff[k, f], self._fvalid[k, f] = nrm[0], nrm[1], off, True
            for v, q in enumerate(verts):
                self._v0[k, v], self._v1[k, v], self._vvalid[k, v] = q[0], q[1], True
        self._b0 = np.array([nb[0] for nb, _ in self.car_faces])
        self._b1 = np.array([nb[1] for nb, _ in self.car_faces])
        self._boff = np.array([off for _, off in self.car_faces], float)

    def add(self, rows: Rows, cand: Candidate, ref_real: np.ndarray, theta_set) -> None:
        """Rows at the (step, obstacle) pairs in ``theta_set``, linearised about ``ref_real``.

        Per pair, in sorted order: each feature point less than 1 m outside every face of
        the obstacle (one farther out cannot reach it here), behind one of them (a row per
        face: a disjunction, or a plain row where the obstacle has one useful face); then
        each obstacle vertex within reach of the car, behind one of the car's four faces.
        The preferred alternative of a disjunction is the one the reference satisfies best.
        Computed for all pairs at once; each value keeps the order of operations of the
        formula for one point and one face, so that the QPs (and every committed result)
        stay the same to the last bit."""
        pairs = sorted(theta_set)
        if not pairs:
            return
        ref = ref_real[:: self.substeps]  # real states at the control steps
        step = np.array([i for i, _ in pairs])
        obs = np.array([k for _, k in pairs])
        th = ref[step, XI_TH]
        ct = np.array([math.cos(t) for t in th.tolist()])[:, None, None]
        st = np.array([math.sin(t) for t in th.tolist()])[:, None, None]
        px, py = ref[step, XI_X][:, None, None], ref[step, XI_Y][:, None, None]
        th = th[:, None, None]
        sign, twice = np.array([real_pose_coeffs(i, cand) for i in step.tolist()]).T  # real p = sign p + twice S

        # Feature points (axis 1) behind faces (axis 2) of the pair's obstacle.
        f0, f1, off = self._f0[obs][:, None, :], self._f1[obs][:, None, :], self._foff[obs][:, None, :]
        cx, cy = self.points[None, :, 0, None], self.points[None, :, 1, None]
        rc0, rc1 = ct * cx - st * cy, st * cx + ct * cy  # R(th) c
        drc0, drc1 = -st * cx - ct * cy, ct * cx - st * cy  # dR/dth c
        valid = self._fvalid[obs][:, None, :]  # real faces, not padding
        slack_p = np.where(valid, f0 * (px + rc0) + f1 * (py + rc1) - off, -np.inf)
        near_p = valid & (slack_p.max(axis=2) <= 1.0)[:, :, None]
        coef_p = f0 * drc0 + f1 * drc1
        lower_p = off + self.margin - (f0 * (rc0 - th * drc0) + f1 * (rc1 - th * drc1))

        # Obstacle vertices (axis 1) behind the car's faces (axis 2).
        q0, q1 = self._v0[obs][:, :, None], self._v1[obs][:, :, None]
        co = self.params.center_offset
        dist = np.hypot(q0 - (px + co * ct), q1 - (py + co * st))
        near_v = self._vvalid[obs][:, :, None] & (dist <= 0.5 * self.params.length + 1.5)
        b0, b1, boff = self._b0, self._b1, self._boff
        nw0, nw1 = ct * b0 - st * b1, st * b0 + ct * b1
        dnw0, dnw1 = -st * b0 - ct * b1, ct * b0 - st * b1
        d0, d1 = q0 - px, q1 - py
        coef_v = dnw0 * d0 + dnw1 * d1
        lower_v = boff + self.margin - (nw0 * q0 + nw1 * q1) + coef_v * th
        slack_v = nw0 * d0 + nw1 * d1 - boff

        def flat(a_p, a_v):  # per pair: the points' rows, then the vertices'
            n = len(pairs)
            a_p, a_v = np.broadcast_to(a_p, slack_p.shape), np.broadcast_to(a_v, slack_v.shape)
            return np.concatenate([a_p.reshape(n, -1), a_v.reshape(n, -1)], axis=1).reshape(-1)

        keep = flat(near_p, near_v)
        n_alt = flat(self._nfaces[obs][:, None, None], 4)
        group = np.cumsum(flat(np.arange(slack_p.shape[2]) == 0, np.arange(4) == 0)) - 1
        pair = np.repeat(np.arange(len(pairs)), slack_p[0].size + slack_v[0].size)
        keep_i = np.flatnonzero(keep)
        k_group, k_pair, k_alts = group[keep_i], pair[keep_i], n_alt[keep_i]
        lower, slack = flat(lower_p, lower_v)[keep_i], flat(slack_p, slack_v)[keep_i]
        c0, c1 = flat(f0, -nw0)[keep_i], flat(f1, -nw1)[keep_i]
        c_th = flat(coef_p, coef_v)[keep_i]

        r0, n_rows = len(rows.h_u), len(keep_i)
        r = r0 + np.arange(n_rows)
        rows_sign, rows_twice = sign[k_pair], twice[k_pair]
        base = ix(step[k_pair], XI_X)
        rows.extend(
            np.repeat(r, 3),
            np.stack([base, base + (XI_Y - XI_X), base + (XI_TH - XI_X)], axis=1).reshape(-1),
            np.stack([rows_sign * c0, rows_sign * c1, c_th], axis=1).reshape(-1),
        )
        tw = np.flatnonzero(rows_twice != 0.0)
        if len(tw):
            rows.extend(
                np.repeat(r[tw], 2),
                np.tile([self.iS, self.iS + 1], len(tw)),
                np.stack([rows_twice[tw] * c0[tw], rows_twice[tw] * c1[tw]], axis=1).reshape(-1),
            )
        rows.h_u.extend([np.inf] * n_rows)
        single = k_alts == 1  # a single face: an ordinary constraint
        rows.h_l.extend(np.where(single, lower, INACTIVE).tolist())
        rows.active.extend(lower.tolist())
        if n_rows == 0:
            return
        starts = np.flatnonzero(np.r_[True, k_group[1:] != k_group[:-1]])
        sizes = np.diff(np.r_[starts, n_rows])
        # Each group's first row of most room (np.argmax's choice).
        top = np.flatnonzero(slack == np.repeat(np.maximum.reduceat(slack, starts), sizes))
        best = top[np.r_[True, k_group[top[1:]] != k_group[top[:-1]]]]
        for a, b, pref in zip(starts.tolist(), (starts + sizes).tolist(), best.tolist()):
            if b - a > 1:
                rows.disj.append(Disjunction(tuple(range(r0 + a, r0 + b))))
                rows.preferred.append(r0 + pref)


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
