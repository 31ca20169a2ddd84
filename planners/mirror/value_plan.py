"""Plans chosen by a cost to go: the optimisation compares manoeuvres (``mirror-value``).

One call solves several candidates (first gear, with or without a switch), each by the same
SCP with Algorithm I inside toward its own mirrored goal, and executes the one whose
optimised trajectory is cheapest by

    J = driven metres (reversing dearer) + a price per direction switch + V(end),

with V the cost to go of ``value.py``: the terminal cost beyond the one-switch horizon. A
candidate's goal lies down V from its own switch pose (or start), in its last gear, as far
as the rest of the horizon reaches, and moves with the optimised plan (``updates``); within
``finish_radius`` of the target the paper's own candidates, aimed at the target itself,
join in. V's cheapest way on, tracked on the planning model, warm-starts each candidate,
and so may the geometric guide; neither picks the goal or the winner.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from mirrorpark_env.angles import unwrap_near
from mirrorpark_env.vehicle import VehicleState

from ..common.path import Path
from .checks import Start
from .guide import Guide
from .plans import Candidate, Plan
from .value import CostToGo

if TYPE_CHECKING:
    from .planner import MirrorPlanner


def last_gear(c: Candidate) -> int:
    return -c.direction if c.switch is not None else c.direction


def driven_cost(real: np.ndarray, reverse_cost: float) -> float:
    """Metres driven by states (x, y, theta, v, ...), each reversed metre at 1 + ``reverse_cost``."""
    d = np.diff(real[:, :2], axis=0)
    ds = np.hypot(d[:, 0], d[:, 1])
    return float(ds.sum()) + reverse_cost * float(ds[real[1:, 3] < 0].sum())


class ValuePlanning:
    """The ``value`` mode of a ``MirrorPlanner`` (its solver, seeds and checks)."""

    def __init__(self, planner: MirrorPlanner, value: CostToGo):
        self.pl = planner
        self.V = value
        self.last_gear = 0  # the gear the last plan ended in (0: none yet), for the switch price

    def cost_to_go(self, pose, gear: int | None = None) -> float:
        """V at ``pose`` (arrived in ``gear``; None: at rest), and near the target, where V's
        cells are too coarse, the pose error in metres of driving, at most ``finish_cap``
        above V (so that it ranks poses near the target and nowhere else)."""
        c = self.V.cfg
        v, _ = self.V.at(pose, gear)
        tx, ty, tth = self.pl.g.target
        e = c.finish_position * math.hypot(pose[0] - tx, pose[1] - ty) + c.finish_heading * abs(
            unwrap_near(tth, pose[2]) - pose[2]
        )
        return v + min(max(e - v, 0.0), c.finish_cap)

    def plan(self, state: VehicleState, xi0: np.ndarray, start: Start, t0: float) -> Plan | None:
        pl, cfg, V = self.pl, self.pl.cfg, self.V
        line = pl.line_from(state.theta)
        target = np.array(pl.g.target, float)
        sw, rc = V.cfg.switch_cost, V.cfg.reverse_cost
        prev = self.last_gear if abs(state.v) < 0.05 else (1 if state.v > 0 else -1)
        reach = cfg.value_reach_speed * cfg.dt  # [m] per step of horizon left

        def score(real: np.ndarray, c: Candidate) -> float:
            switches = (c.switch is not None) + (prev != 0 and c.direction != prev)
            return driven_cost(real, rc) + sw * switches + self.cost_to_go(real[-1, :3], last_gear(c))

        def aim(real: np.ndarray, c: Candidate) -> np.ndarray:
            k = 0 if c.switch is None else c.switch
            pose = real[k * cfg.model_substeps, :3] if len(real) > pl.N + 1 else real[k, :3]
            goal = V.descend(pose, last_gear(c), reach * (pl.N - k))
            return target.copy() if goal is None else goal

        picked, fixed = self._warm_starts(state, xi0, line, reach), set()  # fixed: aimed at the target
        if math.hypot(xi0[0] - target[0], xi0[1] - target[1]) < cfg.value_finish_radius:
            theta_t = unwrap_near(target[2], state.theta)
            merit = lambda real: pl.checks.merit(real, target, theta_t)  # noqa: E731
            for cs in pl.shape_seeds.ranked(xi0, pl.shape_seeds.candidates(state, line), line, merit)[:2]:
                fixed.add(len(picked))
                picked.append(cs)
        best, best_j, partial = None, math.inf, None
        totals = {"iterations": 0, "qp_solves": 0, "nodes": 0}
        tried, net = [], False
        for n, (cand, seed) in enumerate(picked):
            goal = target.copy() if n in fixed else aim(seed, cand)
            natural = cand.direction == pl.shape_seeds.first_direction
            for _ in range(1 if n in fixed else cfg.value_updates):
                plan, st = pl.solve_candidate(
                    xi0, cand, goal, start, line, seed, iterations=cfg.value_iterations, band=natural
                )
                for k in totals:
                    totals[k] += st[k]
                net = net or st.get("safety_net", False)
                if st.get("partial") is not None and (partial is None or st["partial"].cost < partial.cost):
                    partial = st["partial"]
                if plan is None:
                    tried.append((cand, None, st["status"], tuple(np.round(goal, 3))))
                    break
                moved = float(np.abs(plan.states[:, 3]).sum()) * cfg.dt
                j = score(plan.states, cand) if moved > 0.05 else math.inf  # standing is no plan
                tried.append((cand, round(j, 3), st["status"], tuple(np.round(goal, 3))))
                if j < best_j:
                    best, best_j = plan, j
                new = aim(plan.states, cand)
                if np.hypot(*(new[:2] - goal[:2])) < 0.05 and abs(new[2] - goal[2]) % (2 * math.pi) < 0.02:
                    break
                goal = new
                seed = np.concatenate([xi0[None], pl.coarse.rollout(xi0, plan.commands)[:, :6]])
        status = "ok" if best is not None else "infeasible"
        if best is None and partial is not None:
            best, status = partial, "partial"
        if best is not None:
            self.last_gear = last_gear(best.candidate)
        detail = {
            "candidates": tried,
            "guided": False,
            "stay_cost": self.cost_to_go(xi0[:3], prev or None),  # the policy's progress measure
            "value": best_j,
            "safety_net": net,
        }
        return pl.finish(t0, status, totals, best_j if math.isfinite(best_j) else math.nan, detail, best)

    def _seed_merit(self, real: np.ndarray) -> float:
        """J of a seed rollout, plus a steep price on its footprint's penetration."""
        gears = np.sign(real[np.abs(real[:, 3]) > 0.05, 3])
        switches = int(np.count_nonzero(gears[1:] != gears[:-1]))
        pen = np.clip(self.pl.checks.penetration(real).max(axis=1), 0, None).sum()
        v = min(self.cost_to_go(real[-1, :3]), 1e3)
        return driven_cost(real, self.V.cfg.reverse_cost) + self.V.cfg.switch_cost * switches + v + 100.0 * float(pen)

    def _warm_starts(self, state: VehicleState, xi0: np.ndarray, line, reach: float):
        """(candidate, seed) pairs: V's cheapest way on in each first gear allowed, through
        no switch and through one, tracked; the guide's, where the planner has one; the
        classic shapes where V is blind."""
        pl, cfg = self.pl, self.pl.cfg
        picked: list[tuple[Candidate, np.ndarray]] = []
        dirs = [1 if state.v > 0 else -1] if abs(state.v) > 0.1 else [1, -1]
        for d in dirs:
            for changes in (0, 1):
                poses = self.V.policy_path(xi0[:3], d, changes, 1.5 * reach * pl.N)
                if poses is not None:
                    c, seed, _ = pl.guided_seed.seed(xi0, Guide(Path.from_poses(poses), 0.0))
                    if all(c != q for q, _ in picked):
                        picked.append((c, seed))
        if pl.guided:
            guide = pl.guide_search(xi0[:3])
            if guide is not None:
                c, seed, _ = pl.guided_seed.seed(xi0, guide)
                picked = [(q, s) for q, s in picked if q != c] + [(c, seed)]
        if not picked:
            ranked = pl.shape_seeds.ranked(xi0, pl.shape_seeds.candidates(state, line), line, self._seed_merit)
            picked = [cs for cs in ranked if cs[0].switch is None]
            picked += [cs for cs in ranked if cs[0].switch is not None][: cfg.value_candidates]
        return picked
