"""One A* search of a hybrid A* call, held between slices of the compiled loop.

A call runs two searches, backward out of the slot and forward into it (``search.py``).
Each keeps its nodes, open list and cells here between calls of ``kernel.run``, so that the
two can take turns (``HybridAStarConfig.interleave``) or run one after the other.
"""

from __future__ import annotations

import math
import time

import numpy as np

from . import kernel
from .heuristic import CostToGoHeuristic

SLICE = 500  # expansions between looks at the wall-clock safety net


class OneSearch:
    """An A* search from ``origin`` toward ``goal`` that may make at most ``cap`` expansions.

    Forward, a node in the ISO goal set also ends it, and after ``plain_expansions`` the
    cost to go takes over (built then, if not yet); backward, the gear costs are swapped,
    since the path will be driven the other way, and shots go to ``goal`` (the start) alone.
    """

    def __init__(self, planner, origin, goal, backward: bool, cap: int) -> None:
        self.p, self.origin, self.goal, self.backward = planner, origin, goal, backward
        cfg = planner.cfg
        self.sharpen_at = -1 if backward or cfg.heuristic != "cost_to_go" else cfg.plain_expansions
        forward_cost, reverse_cost = (cfg.reverse_cost, 1.0) if backward else (1.0, cfg.reverse_cost)
        n = 1 + cap * len(planner._primitives[1])  # each expansion adds one node a primitive at most
        self.fl, self.it = np.empty((n, 5)), np.empty((n, 5), np.int64)
        self.hf, self.ht, self.hn = np.empty(n), np.empty(n, np.int64), np.empty(n, np.int64)
        self.ctr = np.array([1, 0, 0, 0], np.int64)
        self.best_g, self.closed = kernel.new_maps()
        gap = float(planner._gaps(np.array([origin]))[0])
        key = kernel.cell_key(*origin, gap, planner._keyp)
        self.fl[0], self.it[0] = (*origin, 0.0, 0.0), (-1, 0, -1, 0, key)
        self.best_g[key] = 0.0
        self.heur = planner._heur_args(goal, None)
        kernel.push(self.hf, self.ht, self.hn, self.ctr, kernel.estimate(*origin, 0, *self.heur), 0, 0)
        costs = [forward_cost, reverse_cost, cfg.steer_cost, cfg.steer_change_cost, cfg.switch_cost]
        self.costs = np.array(costs + [planner.sample_spacing, planner.min_samples])
        goals, self.shotp, self.gapargs, self.req, self.window = planner._shot_args()
        self.goals = np.array([goal[:3]], float) if backward else goals
        self.goalp, self.body, self.edges, self.spec = planner._goal_args()
        self.status: str | None = None  # set once it has ended: "ok", "budget", "no_path", "wall_clock"
        self.poses: np.ndarray | None = None
        self.cost = math.nan

    @property
    def expansions(self) -> int:
        return int(self.ctr[kernel.N_EXP])

    @property
    def nodes(self) -> int:
        return int(self.ctr[kernel.N_NODES])

    def advance(self, limit: int, deadline: float, final: bool) -> None:
        """Expand until this search's expansions reach ``limit`` or it ends (``status`` set:
        a path, the open list empty, the wall-clock safety net, or with ``final`` the limit)."""
        cfg = self.p.cfg
        while True:
            stops = np.array([limit, self.expansions + SLICE, self.sharpen_at, cfg.analytic_every], np.int64)
            code, i, tail = kernel.run(
                self.fl, self.it, self.hf, self.ht, self.hn, self.ctr, self.best_g, self.closed, stops,
                self.backward, self.p._primitives, self.costs, self.p._keyp, self.gapargs, self.req,
                self.window, *self.heur, self.goalp, self.body, self.edges, self.spec, self.goals, self.shotp,
            )  # fmt: skip
            if code == kernel.SLICE:
                if time.perf_counter() <= deadline:
                    continue
                self.status = "wall_clock"
            elif code == kernel.SHARPEN:
                self._sharpen()
                continue
            elif code in (kernel.FOUND, kernel.SHOT):
                self.status, self.cost = "ok", float(self.fl[i, kernel.G])
                self.poses = self._trace(i, tail if code == kernel.SHOT else None)
            elif code == kernel.NO_PATH:
                self.status = "no_path"
            elif final:
                self.status = "budget"
            return

    def _sharpen(self) -> None:
        """The cost to go takes over: built (or taken from the slot's cache) and the open
        nodes re-ranked by it."""
        p = self.p
        p.car_heuristic = CostToGoHeuristic(p.geometry, p.lattice, self.origin, p.cfg.lattice_stop)
        self.heur = p._heur_args(self.goal, p.car_heuristic)
        kernel.rerank(self.hf, self.ht, self.hn, self.ctr, self.fl, self.it, *self.heur)
        self.sharpen_at = -1

    def samples(self, i: int) -> np.ndarray:
        """Node ``i``'s poses from its parent (excluded) to it (included), as the kernel made them."""
        fl, it = self.fl, self.it
        x, y, th = fl[it[i, kernel.PARENT], :3]
        c, s = math.cos(th), math.sin(th)
        o = self.p._primitives[0][it[i, kernel.PRIM], : it[i, kernel.KEPT]]
        return np.stack((x + c * o[:, 0] - s * o[:, 1], y + s * o[:, 0] + c * o[:, 1], th + o[:, 2]), axis=-1)

    def _trace(self, i: int, tail: np.ndarray | None) -> np.ndarray:
        parts = [] if tail is None else [tail[1:]]
        while i > 0:
            parts.append(self.samples(i))
            i = int(self.it[i, kernel.PARENT])
        parts.append(self.fl[:1, :3])
        return np.concatenate(parts[::-1])
