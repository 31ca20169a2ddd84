"""``mirror`` (the default) and ``mirror-cold``: candidates aimed down a cost to go, compared by optimisation.

One call solves several candidates (first gear, with or without a switch), each by the same
SCP with Algorithm I inside toward its own mirrored goal, and executes the one whose
optimised trajectory is cheapest by

    J = driven metres (reversing dearer) + a price per direction switch + V(end)

(``cost.plan_price``), with V the cost to go of ``cost_to_go.py``: the terminal cost beyond
the one-switch horizon. A candidate's goal lies down V from its own switch pose (or start),
in its last gear, as far as the rest of the horizon reaches; the leading candidate's goal then moves with its
optimised plan (``updates``). Within ``finish_radius`` of the target the paper's own
candidates, aimed at the target itself, join in. V's cheapest way on, tracked on the
planning model, warm-starts each candidate (``mirror-cold``: the classic shapes do); it
picks neither the goal nor the winner.
"""

from __future__ import annotations

import math

import numpy as np

from mirrorpark_env.angles import unwrap_near, wrap_angle
from mirrorpark_env.vehicle import VehicleState

from ...common.cost_to_go import CostToGo, cost_to_go
from ...common.path import Path
from ..checks import Start
from ..config import AimedConfig
from ..core import PlannerCore
from ..cost import finish_price, penetration_price, plan_price
from ..guide import Guide
from ..mirror_line import MirrorLine
from ..plans import Candidate, Plan, Tally
from ..seeds import TrackedSeed
from ..solvers import BranchAndBound
from .base import Outcome, Strategy


def last_gear(c: Candidate) -> int:
    """The gear a candidate's plan ends in."""
    return -c.direction if c.switch is not None else c.direction


class AimedCandidates(Strategy):
    """``mirror``: V's ways on warm-start the candidates."""

    def __init__(self, core: PlannerCore, config: AimedConfig):
        super().__init__(core, config)
        self.V: CostToGo | None = None  # built by prepare()
        self.price = config.lattice.price  # the one price of V, the seeds and the plans
        cc = self.cc
        self.miqp, self.rollouts = core.miqp, core.rollouts
        self.qp_solver = core.qp_solver  # for the branch and bound of a call's retries
        self.scout_miqp = BranchAndBound(core.qp_solver, config.scout_node_limit, cc.time_limit_s)
        self.tracked_seed = TrackedSeed(self.g, cc, core.rollouts.truth)
        self.last_gear = 0  # the gear the last plan ended in (0: none yet), for the switch price
        self.best_stay = math.inf  # the lowest cost to go at the car of the episode's calls so far

    def prepare(self) -> None:
        """The slot's cost to go, shared by episodes in the same slot (``cost_to_go.cost_to_go``)."""
        if self.V is None:
            self.V = cost_to_go(self.g, self.cfg.lattice)

    def cost_to_go(self, pose, gear: int | None = None) -> float:
        """V at ``pose`` (arrived in ``gear``; None: at rest), and near the target, where V's
        cells are too coarse, the pose error in metres of driving (``cost.finish_price``)."""
        with self.clock("cost_to_go"):
            return finish_price(self.V.cfg, self.V.lookahead(pose, gear), pose, self.g.target)

    def plan(
        self, state: VehicleState, xi0: np.ndarray, start: Start, candidates: list[Candidate] | None = None
    ) -> Outcome:
        self.prepare()
        line = self.lines.from_heading(state.theta)
        prev = self.last_gear if abs(state.v) < 0.05 else (1 if state.v > 0 else -1)
        call = _Call(self, xi0, start, line, prev)
        stay = self.cost_to_go(xi0[:3], prev or None)  # the cost to go where the car is: the progress
        # Where the calls since the best one have not brought the car 1 % nearer (a tight slot
        # shuffled into), the cheap order has not moved it on: every candidate is solved.
        stalled = stay >= 0.99 * self.best_stay
        self.best_stay = min(self.best_stay, stay)
        picked, fixed = self._candidates(state, xi0, line, call)
        best, best_j, lead, lead_converged, goals, scouted = self._scout(picked, fixed, call, stalled)
        if best is not None and lead not in fixed:
            best, best_j = call.refine(best, best_j, goals[lead], lead_converged)
        status = "ok" if best is not None else "infeasible"
        if best is None and call.partial is not None:
            best, status = call.partial, "partial"
        if best is not None:
            self.last_gear = last_gear(best.candidate)
        cost = best_j if math.isfinite(best_j) else math.nan
        detail = {"candidates": call.tried, "value": best_j, **scouted}
        return Outcome(best, status, call.tally, cost, progress=stay, safety_net=call.net, detail=detail)

    def _candidates(self, state: VehicleState, xi0: np.ndarray, line: MirrorLine, call: _Call):
        """(candidate, seed) pairs of the call (``_warm_starts``, and near the target the best
        shape seeds aimed at it) and the indices of those aimed at the target."""
        with self.clock("seeds"):
            picked, fixed = self._warm_starts(state, xi0, line, call), set()  # fixed: aimed at the target
            target = call.target
            if math.hypot(xi0[0] - target[0], xi0[1] - target[1]) < self.cfg.finish_radius:
                theta_t = unwrap_near(target[2], state.theta)
                merit = lambda real: self.checks.merit(real, target, theta_t)  # noqa: E731
                ranked = self.seeds.ranked(xi0, self.seeds.candidates(state, line), line, merit)
                for cs in ranked[: self.cfg.finish_candidates]:
                    fixed.add(len(picked))
                    picked.append(cs)
        return picked, fixed

    def _scout(self, picked: list, fixed: set[int], call: _Call, every: bool = False):
        """(best plan, its J, its index, whether its SCP converged, the goals aimed, and for best
        first the candidates in their order with their warm starts' prices) over ``picked``;
        ``every``: solve every candidate (best first's order, no margin)."""
        cfg, target = self.cfg, call.target
        # Scouting: every candidate solved once, branch and bound on a small budget; then
        # the leader alone is refined (its goal moved down V from its optimised plan, its SCP
        # continued where it had not converged, on the full budget). Where no candidate gives
        # a plan, those whose branch and bound ran out of nodes are solved again on the full
        # budget, within ``retry_nodes`` in all. Best first (``margin``): the candidates in
        # the order of their warm starts' price, the scouting ended at the first whose warm
        # start costs more than the best optimised plan by over ``margin`` metres.
        goals: dict[int, np.ndarray] = {}  # each candidate's goal, aimed when it is first solved
        order, prices = list(range(len(picked))), None
        if cfg.margin is not None:
            with self.clock("seeds"):
                prices = [self._seed_price(seed, cand, call) for cand, seed in picked]
            order.sort(key=prices.__getitem__)
        best, best_j, lead, lead_converged = None, math.inf, -1, False
        todo, retry_nodes = order, cfg.retry_nodes
        for full in (False, True):
            cut_short = []
            for n in todo:
                if self.budget.spent:
                    break  # the call's QP budget (``call_qp_budget``): the best plan so far stands
                if not full and prices is not None and not every and prices[n] - cfg.margin > best_j:
                    break  # best first: the warm starts left all cost more than the best plan found
                cand, seed = picked[n]
                if n not in goals:
                    goals[n] = target.copy() if n in fixed else call.aim(seed, cand)
                if not full:
                    j, plan, cut, conv = call.solve(cand, goals[n], seed, self.scout_miqp)
                elif retry_nodes > 0:
                    used = call.tally.nodes
                    cc = self.cc
                    miqp = BranchAndBound(self.qp_solver, min(cc.node_limit, retry_nodes), cc.time_limit_s)
                    j, plan, cut, conv = call.solve(cand, goals[n], seed, miqp)
                    retry_nodes -= call.tally.nodes - used
                else:
                    break
                if j < best_j:
                    best, best_j, lead, lead_converged = plan, j, n, conv
                if cut:
                    cut_short.append(n)
            if best is not None:
                break
            todo = cut_short
        scouted = {}
        if prices is not None:
            scouted = {"scouted": [picked[n][0] for n in order], "prices": sorted(float(p) for p in prices)}
        return best, best_j, lead, lead_converged, goals, scouted

    def _seed_price(self, seed: np.ndarray, cand: Candidate, call: _Call) -> float:
        """What a candidate's warm start costs by the price its optimised plan is compared
        by (``_Call.score``: the candidate's switch, V in its last gear), plus the price of
        its footprint's penetration: best first's order."""
        real = seed[:: self.cc.model_substeps] if len(seed) > self.cc.horizon + 1 else seed
        return call.score(real, cand) + penetration_price(self.price, self.checks.penetration(seed).max(axis=1))

    def _seed_merit(self, real: np.ndarray) -> float:
        """J of a seed rollout as driven (its own gear changes, V at rest), plus the price of
        its footprint's penetration: which of two seeds of one candidate to keep."""
        gears = np.sign(real[np.abs(real[:, 3]) > 0.05, 3])
        switches = int(np.count_nonzero(gears[1:] != gears[:-1]))
        pen = self.checks.penetration(real).max(axis=1)
        v = min(self.cost_to_go(real[-1, :3]), 1e3)
        return plan_price(self.price, real, switches, v) + penetration_price(self.price, pen)

    def _warm_starts(self, state: VehicleState, xi0: np.ndarray, line, call: _Call):
        """(candidate, seed) pairs: V's cheapest way on in each first gear allowed, through
        no switch and through one, tracked; the classic shapes where V is blind; the way V
        prices at the car, tracked."""
        reach, N = call.reach, self.cc.horizon
        picked: list[tuple[Candidate, np.ndarray]] = []
        dirs = [1 if state.v > 0 else -1] if abs(state.v) > 0.1 else [1, -1]
        for d in dirs:
            for changes in (0, 1):
                with self.clock("cost_to_go"):
                    poses = self.V.policy_path(xi0[:3], d, changes, 1.5 * reach * N)
                if poses is not None:
                    c, seed, _ = self.tracked_seed.seed(xi0, Guide(Path.from_poses(poses), 0.0))
                    if all(c != q for q, _ in picked):
                        picked.append((c, seed))
        if not picked:
            picked = self._shape_starts(state, xi0, line, call)
        # The way V prices at the car (``CostToGo.read_path``), through no switch and through
        # one: a new candidate, or a second seed for one already picked, where the better
        # seed by J (with its penetration priced) is kept. Measured on the standard sample:
        # 83.5 % parked against 83.2 %, 1.59 switches against 1.75 where it, the default
        # before it and hybrid A* all park (CHANGELOG.md, 2026-12-04).
        for changes in (0, 1):
            with self.clock("cost_to_go"):
                poses = self.V.read_path(xi0[:3], changes, 1.5 * reach * N)
            if poses is None:
                continue
            c, seed, _ = self.tracked_seed.seed(xi0, Guide(Path.from_poses(poses), 0.0))
            if c.direction not in dirs:
                continue
            same = [n for n, (q, _) in enumerate(picked) if q == c]
            if not same:
                picked.append((c, seed))
            elif self._seed_merit(seed) < self._seed_merit(picked[same[0]][1]):
                picked[same[0]] = (c, seed)
        return picked

    def _shape_starts(self, state: VehicleState, xi0: np.ndarray, line, call: _Call):
        """(candidate, seed) pairs from the classic shapes, best by the merit: every candidate
        without a switch (``_sized``) and the best ``candidates`` with one."""
        ranked = self.seeds.ranked(xi0, self.seeds.candidates(state, line), line, self._seed_merit)
        picked = self._sized(xi0, line, call, [cs for cs in ranked if cs[0].switch is None])
        return picked + [cs for cs in ranked if cs[0].switch is not None][: self.cfg.candidates]

    def _sized(self, xi0: np.ndarray, line, call: _Call, picked: list) -> list:
        """The shape seeds of candidates without a switch, as used (here: as ranked)."""
        return picked


class ColdStart(AimedCandidates):
    """``mirror-cold``: no path warm-starts a candidate (neither V's ways nor a guide); the
    classic shapes seed them, and V stays the terminal cost. The ablation that shows what
    the warm start adds."""

    def _warm_starts(self, state: VehicleState, xi0: np.ndarray, line, call: _Call):
        return self._shape_starts(state, xi0, line, call)

    def _sized(self, xi0: np.ndarray, line, call: _Call, picked: list) -> list:
        """Each seed without a switch sized to the candidate's own goal (down V from the car)
        instead of the target, where that seed's merit (J, its penetration priced) is lower:
        a shape sized to the target from a car across the road runs into a wall."""
        for n, (c, seed) in enumerate(picked):
            aimed = self.seeds.seeds(xi0, [(c, None)], line, target=tuple(call.aim(seed, c)))[0]
            if self._seed_merit(aimed) < self._seed_merit(seed):
                picked[n] = (c, aimed)
        return picked


class _Call:
    """One planning call's scoring, aiming and solving of candidates, and its tallies."""

    def __init__(self, vp: AimedCandidates, xi0: np.ndarray, start: Start, line: MirrorLine, prev: int):
        self.vp, self.cfg, self.cc = vp, vp.cfg, vp.cc
        self.N = self.cc.horizon
        self.xi0, self.start, self.line, self.prev = xi0, start, line, prev
        self.target = np.array(vp.g.target, float)
        self.reach = self.cfg.reach_speed * self.cc.dt  # [m] per step of horizon left
        self.tally = Tally()
        self.tried: list = []  # (candidate, J or None, status, goal) per solve
        self.partial: Plan | None = None
        self.net = False

    def score(self, real: np.ndarray, c: Candidate) -> float:
        """J: driven cost, the switch price (one more if the first gear is not the last plan's), V at the end."""
        switches = (c.switch is not None) + (self.prev != 0 and c.direction != self.prev)
        v = self.vp.cost_to_go(real[-1, :3], last_gear(c))
        return plan_price(self.vp.price, real, switches, v)

    def aim(self, real: np.ndarray, c: Candidate) -> np.ndarray:
        """The goal down V from the candidate's switch pose (or start) as far as the horizon left
        reaches; where V's way from that pose's cell turns back at once, from one exact move on
        in the candidate's last gear (without it such a goal is the pose itself, and the
        candidate stands: measured, 21 of 192 goals of candidates without a switch on every
        50th standard case)."""
        N, k = self.N, 0 if c.switch is None else c.switch
        pose = real[k * self.cc.model_substeps, :3] if len(real) > N + 1 else real[k, :3]
        with self.vp.clock("cost_to_go"):
            goal = self.vp.V.descend(pose, last_gear(c), self.reach * (N - k), move_on=True)
        return self.target.copy() if goal is None else goal

    def solve(self, cand: Candidate, goal: np.ndarray, seed: np.ndarray, miqp) -> tuple[float, Plan | None, bool, bool]:
        """(J, plan, cut short, converged) of the candidate solved toward ``goal`` (inf, None:
        no plan; cut short: its branch and bound ran out of nodes; converged: its SCP stopped
        before its round cap); records the try."""
        vp, cfg = self.vp, self.cfg
        natural = cand.direction == vp.seeds.first_direction
        res = vp.scp.solve(
            self.xi0, cand, goal, self.start, self.line, seed, iterations=cfg.iterations, band=natural, miqp=miqp
        )
        self.tally += res.tally
        self.net = self.net or res.safety_net
        part = res.partial
        if part is not None and (self.partial is None or part.cost < self.partial.cost):
            self.partial = part
        plan = res.plan
        if plan is None:
            self.tried.append((cand, None, res.status, tuple(np.round(goal, 3))))
            return math.inf, None, res.cut_short, False
        moved = float(np.abs(plan.states[:, 3]).sum()) * self.cc.dt
        j = self.score(plan.states, cand) if moved > 0.05 else math.inf  # standing is no plan
        self.tried.append((cand, round(j, 3), res.status, tuple(np.round(goal, 3))))
        return j, plan, res.cut_short, res.converged

    def refine(self, best: Plan, best_j: float, goal: np.ndarray, converged: bool) -> tuple[Plan, float]:
        """The leader re-aimed down V from its optimised plan and solved again from it, while
        its goal moves or its SCP has not converged (measured: three rounds left an entry
        into a 1.92 m angle slot 6 cm to one side, and the car then shuffled 29 times)."""
        vp, cand, plan = self.vp, best.candidate, best
        for _ in range(self.cfg.updates - 1):
            if vp.budget.spent:
                break
            new = self.aim(plan.states, cand)
            if np.hypot(*(new[:2] - goal[:2])) < 0.05 and abs(wrap_angle(new[2] - goal[2])) < 0.02 and converged:
                break
            goal = new
            with vp.clock("seeds"):
                seed = vp.rollouts.commands(self.xi0, plan.commands)
            j, plan, _, converged = self.solve(cand, goal, seed, vp.miqp)
            if plan is None:
                break
            if j < best_j:
                best, best_j = plan, j
        return best, best_j
