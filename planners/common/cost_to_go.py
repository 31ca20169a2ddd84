"""A cost to go over the slot's free space: the terminal cost of a plan with one switch.

A plan holds one direction switch; most manoeuvres need more. Pulled toward the target
alone, a plan settles at the clear pose nearest the target and stays there (measured,
docs/mirror_planner.md). What the optimisation needs beyond its horizon is what an MPC
designer puts there: a cost to go. This module computes one by dynamic programming on a
lattice of poses, once per slot: V(x, y, theta) is the cheapest way to the target in
driven metres (reversing dearer, each direction switch priced), over moves of full lock
either way or straight, in both gears, that keep a small gap to every obstacle. Near the
slot, where the moves a cell apart reach the mouth only roughly, exact paths into it are
V's sources besides the target: multi-point turns inside it, and entries of one gear
(straight, full-lock arc, straight).

It is a value, not a path: nothing here says where a plan goes. The planner compares its
own optimised plans by plan cost plus V at their ends, and pulls each plan's end down V.
"""

from __future__ import annotations

import math

import numpy as np

from mirrorpark_env.scenario import ScenarioGeometry

from .clearance import gap_kernel, gaps
from .cost_to_go_config import CostToGoConfig, driven_metres, move_cost, steering_cost, switch_price
from .cost_to_go_search import _ahead, _between, _entry_rows, _first_gear, _search, _straight
from .kernels import broad_phase
from .path import arc
from .slot_cache import SlotCache
from .turns import turn_chains


class CostToGo:
    """V over cells aligned on the target, each holding the exact pose it was reached at.

    The target and the poses of exact multi-point turns out of the slot are the sources: a
    tight slot is finer than any affordable lattice. From any cell, following its successors
    replays exact moves (and then an exact in-slot tail) to the target: V's way on is a
    drivable path, not a chain of snapped cells.
    """

    def __init__(
        self,
        geometry: ScenarioGeometry,
        config: CostToGoConfig | None = None,
        stop_near=None,
        stop_rule: tuple[float, float] = (1.0, 0.0),
        box: tuple[float, float, float, float] | None = None,
    ):
        """``stop_near``: a pose (x, y, theta); the search stops early once it has settled a
        cell within one of the pose's and the cost exceeds ``stop_rule[0]`` x that cell's
        cost + ``stop_rule[1]`` (``bound``): V is exact up to ``bound`` and at least
        ``bound`` beyond it. None: the whole box (``bound`` inf). ``box``: (x0, x1, y0, y1)
        the lattice covers (None: ``lattice_box``)."""
        self.g = geometry
        self.cfg = cfg = config or CostToGoConfig()
        res, nh = cfg.xy_resolution, cfg.headings
        self.dth = 2 * math.pi / nh
        self.radius = radius = geometry.vehicle.r_min / cfg.steer_fraction
        self.step = radius * self.dth  # a full-lock move turns one heading cell
        tx, ty, tth = (float(v) for v in geometry.target)
        self.origin = (tx, ty, tth)
        x0, x1, y0, y1 = box or lattice_box(geometry, cfg)
        self.i0 = math.floor((x0 - tx) / res)
        self.j0 = math.floor((y0 - ty) / res)
        self.nx = math.floor((x1 - tx) / res) - self.i0 + 1
        self.ny = math.floor((y1 - ty) / res) - self.j0 + 1
        self.nh = nh
        # Moves (gear, curvature): straight first, so that it wins ties.
        k = 1.0 / radius
        moves = [(gr, kk) for gr in (1.0, -1.0) for kk in (0.0, k, -k)]
        self.kappa = np.array([kk for _, kk in moves])
        self.gear = np.array([int(gr) for gr, _ in moves], np.int64)
        self.cost = np.array([move_cost(cfg.price, self.step, gr < 0, kk != 0.0) for gr, kk in moves])
        self.target_state = self._state(-self.i0, -self.j0, 0)
        self.tails: dict[int, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}  # state -> tail (``_sources``)
        self.entry_rows: dict[int, np.ndarray] = {}  # state -> its entry's path (``_entries``)
        sources, source_pose, source_v = self._sources()
        grid = np.array([res, self.dth, tx, ty, tth, self.i0, self.j0, self.nx, self.ny, nh], float)
        args = gap_kernel(geometry.checker).args
        args = (*args, *broad_phase(args[-1]))
        stop = self._near(stop_near) if stop_near is not None else np.zeros(0, np.int64)
        self.V, self.P, self.next, peak, self.bound = _search(
            self.kappa, self.gear, self.cost, self.step, grid, sources, source_pose, source_v,
            switch_price(cfg.price, 1), cfg.clearance, args, stop, np.array(stop_rule, float),
        )  # fmt: skip
        if peak > 2 * self.V.shape[0] + 2 * len(sources) + 16:  # never seen; a wrong V would be silent
            raise RuntimeError(f"CostToGo: the search's heap overflowed ({peak} entries)")
        self.heap_peak = int(peak)

    def _sources(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """V's sources: the target; the poses of exact multi-point turns out of the slot
        from the target (each arc driven until it would come within ``clearance``), at the
        cost of driving the turn back in; and the poses of exact single-gear entries
        (``_entries``); the cheapest in each cell. Each cell keeps its tail: poses to the
        target, the gear of each step and the cost to go from each (an entry's is drawn
        when first asked for)."""
        cfg = self.cfg
        best: dict[int, tuple[float, np.ndarray | None, np.ndarray | None, np.ndarray | None]] = {
            self.target_state: (0.0, np.array([self.origin]), None, None)
        }
        if cfg.in_slot_arcs:
            checker = self.g.checker

            def first_bad(poses: np.ndarray, n: int) -> int:
                bad = np.flatnonzero(gaps(checker, poses, all_axes=True) < cfg.clearance)
                return int(bad[0]) if len(bad) else len(poses)

            for chain, ends in turn_chains(self.origin, self.radius, cfg.tail_step, cfg.in_slot_arcs, first_bad):
                ds = np.hypot(*np.diff(chain[:, :2], axis=0).T)
                arc_of = np.searchsorted(np.asarray(ends), np.arange(1, len(chain)))  # arc of the step to pose j + 1
                out_gear = np.where(arc_of % 2 == 0, 1.0, -1.0) * _first_gear(chain)
                park = -out_gear  # the gear driven back in
                step = driven_metres(cfg.price, ds, park < 0)
                cum = np.concatenate([[0.0], np.cumsum(step)]) + switch_price(cfg.price, np.concatenate([[0], arc_of]))
                gears = np.concatenate([[park[0]], park])  # gears[m]: of the step from pose m back to m - 1
                i, j, h, inside = self.index(chain)
                for m in range(1, len(chain)):
                    st = self._state(i[m], j[m], h[m])
                    if inside[m] and cum[m] < best.get(st, (math.inf,))[0]:
                        best[st] = (float(cum[m]), chain[m::-1], gears[m:0:-1], cum[m::-1])
        entries = {}  # state -> (cost, path row): an entry replaces a turn only where it is cheaper
        if cfg.entry_length > 0:
            entries = {st: (c, row) for st, c, row in self._entries() if c < best.get(st, (math.inf,))[0]}
        states = np.array([st for st in best if st not in entries] + list(entries), np.int64)
        poses = np.zeros((len(states), 3))
        vals = np.zeros((len(states), 2))
        for n, st in enumerate(states.tolist()):
            if st in entries:
                c, row = entries[st]
                poses[n], first = row[:3], -row[3]  # driven back in, in the other gear
                self.entry_rows[st] = row  # its tail is drawn when first asked for (``_tail``)
            else:
                c, tail, gears, cum = best[st]
                poses[n] = tail[0]
                if gears is None:
                    continue  # the target
                first = gears[0]
                self.tails[st] = (tail, gears, cum)
            # arrived in the other gear than the first step's, the car first switches
            vals[n] = [c + switch_price(cfg.price, int(first > 0)), c + switch_price(cfg.price, int(first < 0))]
        return states, poses, vals

    def _entries(self) -> list[tuple[int, float, np.ndarray]]:
        """(state, cost to the target, path row of ``_entry_rows``) of the cheapest entry per cell."""
        cfg = self.cfg
        args = gap_kernel(self.g.checker).args
        r_min = self.g.vehicle.r_min
        ds, longest, gap = cfg.entry_step, cfg.entry_length, cfg.clearance
        rows = np.concatenate([_entry_rows(*self.origin, r_min / f, ds, longest, gap, args) for f in cfg.entry_steer])
        i, j, h, inside = self.index(rows[:, :3])
        length = rows[:, 4] + rows[:, 6] + rows[:, 7]  # of each entry's path
        park_rev = rows[:, 3] > 0  # driven out forward: parked in reverse
        steer = np.abs(rows[:, 5]) * self.radius  # of the lattice's full lock
        cost = driven_metres(cfg.price, length, park_rev) + steering_cost(cfg.price, steer, rows[:, 6])
        st = (i * self.ny + j) * self.nh + h
        keep = np.flatnonzero(inside & (length > 0))
        if len(keep) == 0:  # the target itself is not clear by ``clearance``: no entries
            return []
        order = keep[np.lexsort((cost[keep], st[keep]))]
        first = order[np.r_[True, st[order][1:] != st[order][:-1]]]
        return [(int(st[k]), float(cost[k]), rows[k]) for k in first]

    def _tail(self, st: int) -> tuple[np.ndarray, np.ndarray] | None:
        """(poses to the target, gear of the step to each) of source ``st`` (None: the target)."""
        tail = self.tails.get(st)
        if tail is not None:
            return tail[0], tail[1]
        row = self.entry_rows.get(st)
        if row is None:
            return None
        x, y, th, og, s1, kappa, a, s2 = (float(v) for v in row)
        tx, ty, tth = self.origin
        d = self.cfg.tail_step
        out = [np.array([[tx, ty, tth]])]
        if s1 > 0:
            out.append(arc(out[-1][-1], 0.0, og * np.linspace(0, s1, max(2, math.ceil(s1 / d) + 1))[1:]))
        if a > 0:
            out.append(arc(out[-1][-1], kappa, og * np.linspace(0, a, max(2, math.ceil(a / d) + 1))[1:]))
        if s2 > 0:
            out.append(arc(out[-1][-1], 0.0, og * np.linspace(0, s2, max(2, math.ceil(s2 / d) + 1))[1:]))
        poses = np.concatenate(out)[::-1].copy()
        poses[0] = row[:3]  # exact: the source's own pose
        return poses, np.full(len(poses) - 1, -og)

    # -- cells ------------------------------------------------------------------------
    def index(self, poses: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Cell (i, j, h) of each pose, and whether it lies in the grid (as ``_search``)."""
        poses = np.atleast_2d(np.asarray(poses, float))
        res = self.cfg.xy_resolution
        tx, ty, tth = self.origin
        i = np.floor((poses[:, 0] - tx) / res + 0.5).astype(np.int64) - self.i0
        j = np.floor((poses[:, 1] - ty) / res + 0.5).astype(np.int64) - self.j0
        h = np.floor((poses[:, 2] - tth) / self.dth + 0.5).astype(np.int64) % self.nh
        inside = (i >= 0) & (i < self.nx) & (j >= 0) & (j < self.ny)
        return np.clip(i, 0, self.nx - 1), np.clip(j, 0, self.ny - 1), h, inside

    def pose(self, i: int, j: int, h: int) -> np.ndarray:
        """The centre of cell (i, j, h)."""
        res = self.cfg.xy_resolution
        tx, ty, tth = self.origin
        return np.array([tx + (self.i0 + i) * res, ty + (self.j0 + j) * res, tth + h * self.dth])

    def _near(self, pose) -> np.ndarray:
        """The states (sorted) of the cells within one cell of ``pose``'s, each way."""
        i, j, h, inside = self.index(np.asarray(pose, float)[None, :3])
        if not inside[0]:
            return np.zeros(0, np.int64)
        out = {
            self._state(ii, jj, (int(h[0]) + dh) % self.nh)
            for ii in range(max(0, int(i[0]) - 1), min(self.nx, int(i[0]) + 2))
            for jj in range(max(0, int(j[0]) - 1), min(self.ny, int(j[0]) + 2))
            for dh in (-1, 0, 1)
        }
        return np.array(sorted(out), np.int64)

    def _state(self, i, j, h) -> int:
        return int((i * self.ny + j) * self.nh + h)

    def at(self, pose, gear: int | None = None) -> tuple[float, int]:
        """(V, state) at ``pose`` having arrived in ``gear`` (+1, -1; None: at rest, either):
        its own cell's, or where that is unreached, the lowest of its neighbours (one cell
        each way)."""
        i, j, h, inside = self.index(np.asarray(pose, float)[None, :3])
        if not inside[0]:
            return math.inf, -1
        cols = [0, 1] if gear is None else [1 if gear > 0 else 0]
        s0 = self._state(int(i[0]), int(j[0]), int(h[0]))
        v0 = min(self.V[s0, c] for c in cols)
        if math.isfinite(v0):
            return v0, s0
        best, arg = math.inf, -1
        for di in (0, -1, 1):
            for dj in (0, -1, 1):
                for dh in (0, -1, 1):
                    ii, jj = int(i[0]) + di, int(j[0]) + dj
                    if not (0 <= ii < self.nx and 0 <= jj < self.ny):
                        continue
                    s = self._state(ii, jj, (int(h[0]) + dh) % self.nh)
                    v = min(self.V[s, c] for c in cols)
                    if v < best:
                        best, arg = v, s
        return best, arg

    def lookahead(self, pose, gear: int | None = None) -> float:
        """V at ``pose`` (arrived in ``gear``; None: at rest) by one exact move from the pose
        itself, clear as V's own moves are, plus V where it lands: ``at`` reads a cell whose
        stored pose may lie up to half a cell from this one, and near an obstacle a way on
        open from there may be shut from here (measured: a plan ended 4 cm from a slot's
        neighbour, where ``at`` read 7.0 m reversing on and every reverse move collided). Only
        where the pose is closer to an obstacle than V's own poses (``clearance``): elsewhere,
        and within two moves of the target, ``at`` (in a tight slot V's finer in-slot turns
        know ways that the moves do not: tried everywhere, 4 tight parallel cases of 500 were
        lost)."""
        pose = np.asarray(pose, float)[:3]
        v0, _ = self.at(pose, gear)
        gap = self._gap(pose)
        if v0 < 2 * self.step or gap >= self.cfg.clearance:
            return v0
        best = math.inf
        for p, v, _ in self._moves_from(pose, None, gap):
            switch = switch_price(self.cfg.price, int(gear is not None and self.gear[p] != gear))
            best = min(best, self.cost[p] + switch + v)
        return best

    def _moves_from(self, pose: np.ndarray, gear: int | None, need: float) -> list[tuple[int, float, int]]:
        """(move, V where it lands having arrived in its gear, that state) for each exact move
        from ``pose`` (in ``gear``; None: either) whose midpoint and end keep ``need``."""
        out = []
        for p in range(len(self.gear)):
            g = int(self.gear[p])
            if gear is not None and g != gear:
                continue
            q = arc(pose, self.kappa[p], np.array([0.5 * g * self.step, g * self.step]))
            if np.any(gaps(self.g.checker, q, all_axes=True) < need):
                continue
            v, s = self.at(q[1], g)
            out.append((p, v, s))
        return out

    def _col(self, s: int, gear: int | None) -> int:
        """The arrival gear's column at ``s`` (None: the cheaper)."""
        if gear is None:
            return int(np.argmin(self.V[s]))
        return 1 if gear > 0 else 0

    # -- V's way on ---------------------------------------------------------------------
    def way_on(self, s: int, g: int) -> list[tuple[np.ndarray, float]]:
        """V's cheapest way on from node (state ``s``, arrival column ``g``): the exact poses
        (the node's own first) and the gear of the step to each, to the target."""
        out: list[tuple[np.ndarray, float]] = [(self.P[s, g].astype(float), 0.0)]
        node = s * 2 + g
        while True:
            st, col = node // 2, node % 2
            nxt = int(self.next[st, col])
            if nxt < 0:  # a source: the target, an in-slot tail or an entry
                tail = self._tail(st)
                if tail is not None:
                    poses, gears = tail
                    out += [(poses[m + 1], float(gears[m])) for m in range(len(poses) - 1)]
                return out
            out.append((self.P[nxt // 2, nxt % 2].astype(float), 1.0 if nxt % 2 else -1.0))
            node = nxt

    def descend(self, pose, gear: int, max_length: float = math.inf, move_on: bool = False) -> np.ndarray | None:
        """The exact pose where V's cheapest way on from ``pose`` (arrived in ``gear``) first
        changes gear, reaches the target or has run ``max_length`` metres. None where V is
        infinite. ``move_on``: where that way changes gear before its first step (the way
        on from the pose the cell stores, up to a cell and a half away, may shuffle first
        where the car need not), the pose down V from where one exact move in ``gear``
        lands, the move ``policy_path`` takes (None where no such move reaches a finite V)."""
        v, s = self.at(pose, gear)
        if not math.isfinite(v):
            return None
        way = self.way_on(s, self._col(s, gear))
        g, length, last = (1.0 if gear > 0 else -1.0), 0.0, way[0][0]
        steps = 0
        for q, gr in way[1:]:
            length += math.hypot(q[0] - last[0], q[1] - last[1])
            if gr != g or length > max_length + 1e-9:
                break
            last = q
            steps += 1
        if move_on and steps == 0 and len(way) > 1 and way[1][1] != g:
            p0 = np.asarray(pose, float)[:3]
            pick = self._first_move(p0, int(g))
            if pick is None:
                return None
            landed = arc(p0, self.kappa[pick[0]], np.array([g * self.step]))[0]
            return self.descend(landed, int(g), max_length - self.step)
        return last.copy()

    def _first_move(self, pose: np.ndarray, gear: int) -> tuple[int, int] | None:
        """(move, state it lands in) of the cheapest exact move in ``gear`` from ``pose`` by
        V where it lands plus the move's cost (None: none keeps its gap)."""
        best, pick = math.inf, None
        for p, v, s in self._moves_from(pose, gear, min(self.cfg.clearance, self._gap(pose))):
            if v + self.cost[p] < best:
                best, pick = v + self.cost[p], (p, s)
        return pick

    def policy_path(
        self, pose, first_gear: int, changes: int, max_length: float, sample_step: float = 0.1
    ) -> np.ndarray | None:
        """Poses from ``pose`` along V's cheapest way on that starts in ``first_gear``: one
        exact move from the pose itself, then the way on from where it lands, through at
        most ``changes`` gear changes and ``max_length`` metres (a warm start for a plan;
        None where no move in that gear reaches a finite V)."""
        pose = np.asarray(pose, float)[:3]
        g = 1.0 if first_gear > 0 else -1.0
        col = 1 if g > 0 else 0
        pick = self._first_move(pose, int(g))
        if pick is None:
            return None
        p, s = pick
        m = max(1, round(self.step / sample_step))
        head = np.concatenate([pose[None], arc(pose, self.kappa[p], g * self.step * np.arange(1, m + 1) / m)])
        # The way goes on from the pose stored in the cell the move lands in, up to a cell
        # and a half from where it lands: joined there, a way that goes on in fine steps
        # (an in-slot tail, 2 cm) or changes gear at once may first back up a few
        # centimetres, a gear change that a tracker would drive (measured: 37 of 288 warm
        # starts on every 50th standard case). So it joins, straight, at its first pose
        # that lies ahead in the gear of the step to it.
        way = _ahead(head[-1], self.way_on(s, col)[1:], 0.5 * sample_step)
        if not way:
            return head
        (q, gq), way = way[0], way[1:]
        if gq != g:
            if changes == 0:
                return head
            changes -= 1
        d = math.hypot(q[0] - head[-1, 0], q[1] - head[-1, 1])
        head = np.concatenate([head, _straight(head[-1], q, d, sample_step)])
        return self._follow(head, way, gq, changes, self.step + d, max_length, sample_step)

    def read_path(self, pose, changes: int, max_length: float, sample_step: float = 0.1) -> np.ndarray | None:
        """Poses along the way on that V prices at ``pose``: from the pose of the state that
        ``at`` reads there (the pose's own cell, or where that is unreached a neighbour, up
        to a cell and a half away), in its cheaper arrival gear, through at most ``changes``
        gear changes and ``max_length`` metres. A warm start besides ``policy_path``, whose
        first exact move from the pose may land on a way that V's reading at the pose does
        not price (measured: V read 12.05 m at a car in front of an angle slot from a
        neighbour's pose 20 cm nearer the slot, whose way reverses straight in; one reverse
        move from the car itself landed where the way on shuffles forward and back first).
        None where V is infinite or the way is a single step."""
        v, s = self.at(pose, None)
        if not math.isfinite(v):
            return None
        way = self.way_on(s, self._col(s, None))
        if len(way) < 2:
            return None
        poses = self._follow(way[0][0][None], way[1:], way[1][1], changes, 0.0, max_length, sample_step)
        return poses if poses is not None and len(poses) > 2 else None

    @staticmethod
    def _follow(head, way, gear, changes, length, max_length, sample_step) -> np.ndarray | None:
        """``head`` (poses), then ``way``'s steps ((pose, gear) from ``way_on``) resampled,
        through at most ``changes`` gear changes from ``gear`` and ``max_length`` metres in
        all (``length`` already driven by ``head``)."""
        out, last, cur = [head], head[-1], gear
        starts, ends, gears, dists = [], [], [], []
        for q, gr in way:
            if gr != cur:
                changes -= 1
                if changes < 0:
                    break
                cur = gr
            d = math.hypot(q[0] - last[0], q[1] - last[1])
            length += d
            if length > max_length + 1e-9:
                break
            starts.append(last)
            ends.append(q)
            gears.append(gr)
            dists.append(d)
            last = q
        if starts:
            out.append(_between(np.array(starts), np.array(ends), np.array(gears), np.array(dists), sample_step))
        poses = np.concatenate(out)
        return poses if len(poses) > 1 else None

    def _gap(self, pose: np.ndarray) -> float:
        return float(gaps(self.g.checker, np.asarray(pose, float)[None, :3], all_axes=True)[0])


def lattice_box(geometry: ScenarioGeometry, cfg: CostToGoConfig) -> tuple[float, float, float, float]:
    """(x0, x1, y0, y1) V covers: the road beside the slot, ``margin`` beyond it along the
    road, within the scene's bounds; where the start lies outside that (a lot's far aisle),
    also the start and ``start_margin`` around it. Starts inside it share one box, so that
    a slot's V is the same whichever of them an episode starts from."""
    slot = np.asarray(geometry.slot, float)
    bx0, bx1, by0, by1 = geometry.bounds
    x0, x1 = max(bx0, slot[:, 0].min() - cfg.margin), min(bx1, slot[:, 0].max() + cfg.margin)
    y0, y1 = max(by0, slot[:, 1].min() - 1.0), min(by1, geometry.road_width + 1.0)
    sx, sy, m = geometry.start.x, geometry.start.y, cfg.start_margin
    if not (x0 <= sx <= x1 and y0 <= sy <= y1):
        x0, x1 = min(x0, max(bx0, sx - m)), max(x1, min(bx1, sx + m))
        y0, y1 = min(y0, max(by0, sy - m)), max(y1, min(by1, sy + m))
    return x0, x1, y0, y1


_CACHE: SlotCache[CostToGo] = SlotCache(8)


def cost_to_go(geometry: ScenarioGeometry, config: CostToGoConfig | None = None) -> CostToGo:
    """A ``CostToGo`` shared by the episodes of one process in the same slot (and lattice box)."""
    cfg = config or CostToGoConfig()
    return _CACHE.get(geometry, (cfg.model_dump_json(), lattice_box(geometry, cfg)), lambda: CostToGo(geometry, cfg))
