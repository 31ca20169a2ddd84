"""Validated settings of the mirrored-target planner and its policy (lengths in m, angles in rad)."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field

from mirrorpark_env.config import StrictModel

from .value import ValueConfig


class MirrorPlannerConfig(StrictModel):
    """Weights, limits and solver settings of the mirrored-target planner.

    The defaults are the registry's ``mirror``: no guide; each call's candidates over first
    gear and switch are aimed down the cost to go (and, within ``value_finish_radius``, at
    the target itself) and compared by their optimised cost (``value_plan.py``). Its SCP
    stops early only within 1 cm and 0.3 deg of a goal (a tight slot's ISO window is a few
    centimetres wide); its cost to go has 3 deg heading cells and prices a direction switch
    at 5 m of driving (measured against 3 and 8 m, docs/mirror_planner.md). The ablation's
    variants are the functions below the class."""

    horizon: int = Field(60, ge=10, le=400)  # N (Table II)
    dt: float = Field(0.1, gt=0, le=1)
    model_substeps: int = Field(2, ge=1, le=20)
    linearisation: Literal["scp", "paper"] = "scp"
    # The speed inside the paper model's v gamma and v / l terms (Eq. 31's A_i; the paper
    # leaves it open): "nominal", 1 m/s in the plan's gear at every step; "previous", each
    # step's speed in the previous round's rollout (1 m/s in the first round), the rounds
    # going on until the rollout is clear and its speeds stay within ``paper_speed_tolerance``.
    paper_speed: Literal["nominal", "previous"] = "nominal"
    paper_speed_tolerance: float = Field(0.1, gt=0)  # [m/s]
    paper_speed_floor: float = Field(0.0, ge=0, le=3)  # [m/s] "previous": at least this, in the plan's gear
    # Its linearising angle ("close to the average yaw angle of the parking path", Fig. 13):
    # "ends", the mean of the start and goal headings; "previous", from the second round on,
    # the mean heading of the previous round's rollout (what the path turned out to be).
    paper_angle: Literal["ends", "previous"] = "ends"
    paper_angle_tolerance: float = Field(0.02, gt=0)  # [rad]
    # The first round's speeds and angle ("previous" only): "nominal", 1 m/s about the ends'
    # mean heading; "seed", those of the candidate's shape seed rollout, as a round zero.
    paper_first: Literal["nominal", "seed"] = "nominal"
    # The obstacle rows hold on the paper model's states, the check on the truth model's
    # rollout. "full": from the second round on, each row is shifted by what the previous
    # round's rollout made of it against the QP's prediction (the model's error at that
    # row), so that a row the QP meets holds on the car, not only on the model; "tighten":
    # only where the rollout came closer to the obstacle than predicted; "off": never.
    paper_correction: Literal["off", "full", "tighten"] = "off"
    max_iterations: int = Field(6, ge=1, le=1000)  # SCP + Algorithm I rounds per candidate
    max_trust_scale: float = Field(64.0, gt=0)  # give up on a candidate when the trust penalty grows past this
    w_trust_position: float = Field(0.5, ge=0)  # SCP trust region, as a penalty per m^2 of planned x, y moved
    w_trust_heading: float = Field(2.0, ge=0)  # ... and per rad^2 of heading
    converge_position: float = Field(0.02, gt=0)  # [m] SCP stops when the rollout moves less
    converge_heading: float = Field(0.01, gt=0)  # [rad]
    settle_position: float = Field(0.01, ge=0)  # [m] ... or when a clear rollout ends this close to its goal
    settle_heading: float = Field(0.005, ge=0)  # [rad] (0: never)
    w_position: float = Field(0.2, ge=0)  # running cost per m^2 toward the mirrored target
    w_heading: float = Field(0.2, ge=0)  # per rad^2
    w_terminal_position: float = Field(400.0, ge=0)
    w_terminal_heading: float = Field(400.0, ge=0)
    # [m] Where the target's ISO window across the slot is narrower than this to the nearer
    # side, the end's position costs w_terminal_position x (this / window)^2 across the
    # target's heading (window.py); wider windows keep one weight (0: always one weight).
    lateral_window: float = Field(0.06, ge=0, le=1)
    w_terminal_accel: float = Field(1.0, ge=0)
    w_accel_cmd: float = Field(0.02, ge=0)
    w_steer_cmd: float = Field(0.05, ge=0)
    w_accel_rate: float = Field(0.5, ge=0)
    w_steer_rate: float = Field(2.0, ge=0)
    obstacle_margin: float = Field(0.04, ge=0, le=1)  # [m] planned clearance to infeasible regions
    w_slack: float = Field(1e5, gt=0)  # exact penalty per m of obstacle-row violation (rows are soft)
    check_margin: float = Field(0.01, ge=0, le=1)  # [m] a rollout closer than this to an obstacle is not clear
    band_tolerance: float = Field(0.008, ge=0, le=0.1)  # [m] a plan's switch may lie this far outside its band
    mirror_margin: float = Field(1.1, ge=1, le=3)  # reverse / angle: l_mi >= margin * r_min (1 - cos psi)
    node_limit: int = Field(100, ge=1, le=100_000)  # branch-and-bound nodes per MIQP (a work budget)
    kkt_solver: Literal["sparse_ldlt", "sparse_multistage", "auto"] = "auto"  # piqp's (solvers.PiqpQP)
    qp_tolerance: float = Field(1e-4, gt=0, lt=1)  # piqp's absolute residual and duality-gap tolerance
    seed_swings: tuple[float, ...] = (-0.8, -0.4, 0.4, 0.8)  # [rad] heading excursions tried as seeds
    refine_candidates: int = Field(2, ge=1)  # candidates refined by SCP after the seed search
    refine_candidates_parallel: int | None = Field(None, ge=1)  # ... in parallel slots (None: as above)
    time_limit_s: float = Field(5.0, gt=0)  # branch and bound's wall-clock safety net per MIQP (recorded)
    guide: bool = False  # seed each plan from a geometric guide (guide.py); SCP only, not in value mode
    guide_iterations: int = Field(2, ge=1, le=1000)  # SCP rounds on a guided candidate
    seed_speed: float = Field(2.0, gt=0, le=3)  # [m/s] cruise speed of the guided seed rollout
    # [m/s] more seed speeds for a plan with a switch: other switch steps, the cheapest plan used
    switch_speeds: tuple[Annotated[float, Field(gt=0, le=3)], ...] = (1.5, 2.5)
    seed_accel: float = Field(1.5, gt=0, le=3)  # [m/s^2] its acceleration and planned deceleration
    # Where the guide finds no path from a standing car, plan without it (the multi-start of
    # an unguided planner) on at most this many calls in a row (0: never), within a smaller
    # budget: one candidate refined, these SCP rounds and branch-and-bound nodes.
    fallback_calls: int = Field(0, ge=0, le=10)
    fallback_iterations: int = Field(4, ge=1, le=1000)
    fallback_node_limit: int = Field(10, ge=1, le=100_000)
    # The value mode (``mirror``, value_plan.py): candidates over first gear and switch,
    # each aimed down a cost to go (value.py) and compared by driven cost plus V at the end.
    # False: the guided planner or the multi-start (``guide``).
    value: bool = True
    # Every plan ends settled: stopped, its lagged acceleration not pointing back (in the planned
    # frame, direction x a_N >= 0). Without it a plan may stop while still braking, and the lag
    # rolls the car back across zero: a direction switch of a centimetre that the env counts.
    end_settled: bool = True
    # [m/s] A car rolling against a candidate's gear slower than this (creeping, its lag
    # still pushing) may roll on until the model's fastest stop has stopped it; else the
    # gear's speed bound holds from the first step and no such candidate exists (0: never).
    stop_first_speed: float = Field(0.0, ge=0, le=1)
    value_lattice: ValueConfig = ValueConfig(headings=120, switch_cost=5.0)
    value_candidates: int = Field(3, ge=1, le=20)  # switch candidates refined where V is blind
    value_updates: int = Field(2, ge=1, le=10)  # solves of the leading candidate, its goal moved down V each time
    value_iterations: int = Field(3, ge=1, le=100)  # SCP rounds per solve
    value_scout_node_limit: int = Field(5, ge=1, le=100_000)  # branch-and-bound nodes per MIQP while scouting
    value_retry_nodes: int = Field(100, ge=0, le=1_000_000)  # nodes in all for re-solving on the full budget
    value_reach_speed: float = Field(1.2, gt=0, le=3)  # [m/s] a goal lies at most this far down V per second left
    value_finish_radius: float = Field(8.0, ge=0)  # [m] within this of the target, also plan toward it
    # False: no path warm-starts a candidate (neither V's cheapest way on nor the guide); the
    # classic shapes seed them, as in the multi-start, and V stays the terminal cost (``mirror-cold``).
    value_warm_start: bool = True
    # Also the way V prices at the car (``CostToGo.read_path``) as a warm start, beside V's
    # way on after one exact move (added on 2026-12-04; False: the default before it).
    value_read_seed: bool = True
    # Without path warm starts: a candidate without a switch is also seeded by the classic
    # shape sized to its own goal (down V from the car) instead of the target, where that
    # seed's merit (J, its penetration priced) is lower. What V's way gives the default; a shape
    # sized to the target from a car across the road runs into a wall (``mirror-cold``; 2026-12-04).
    value_goal_shapes: bool = False


def cold_config(**changes) -> MirrorPlannerConfig:
    """``mirror-cold``: ``mirror`` without any path as a warm start (neither the cost to go's
    cheapest way on nor the guide); the classic shapes seed the candidates, those without a
    switch also the shape sized to their own goal down V, and V stays the terminal cost. The
    ablation that shows what the warm start adds."""
    return MirrorPlannerConfig(**{"value_warm_start": False, "value_goal_shapes": True, **changes})


def guided_config(**changes) -> MirrorPlannerConfig:
    """``mirror-guided``: each plan along the geometric guide (Reeds-Shepp paths through
    switch poses), tracked as the seed and polished by SCP toward the guide's goal. The
    guide chooses the manoeuvre, its switch and its goal; the QP where on the mirror line
    the car switches. The default planner until 2026-12-02, kept for the ablation."""
    base = dict(
        guide=True,
        value=False,
        end_settled=False,
        settle_position=0.06,
        settle_heading=0.02,
        value_finish_radius=3.0,
        value_lattice=ValueConfig(),
        lateral_window=0.0,  # one terminal weight, as before 5ce4cc2 (and as Eq. 33 for mirror-paper)
    )
    return MirrorPlannerConfig(**{**base, **changes})


def multistart_config(**changes) -> MirrorPlannerConfig:
    """``mirror-multistart``: neither guide nor cost to go; candidates over both gears at
    two switch steps and without a switch, seeded by the classic shapes, refined by SCP
    and compared by their optimal cost toward the mirrored target."""
    return guided_config(**{"guide": False, **changes})


def paper_config(**changes) -> MirrorPlannerConfig:
    """``mirror-paper``: the multi-start with the paper's fixed-angle linearisation
    (Eqs. 22-32) in place of SCP's Jacobians about each rollout. Where the paper leaves
    them open, the speed in its v terms and the linearising angle come from the previous
    round's rollout (its speeds, its mean heading; docs/mirror_planner.md). Algorithm I
    runs up to 12 rounds per candidate, twice the multi-start's: its rounds also wait for
    those numbers to settle (32.8 % of the ablation's cases against 27.6 % with 6). In
    parallel slots four candidates are refined, not two (15.5 % -> 23.8 % of the ablation's
    parallel cases; reverse and angle lose with four). The first round's speeds and angle
    come from the candidate's shape seed: at 1 m/s the model turns a standing car, and the
    rounds froze at zero speed (35.6 % -> 42.0 %). A car still creeping (under 5 cm/s)
    against a candidate's gear may stop first: its plans end with the lag still pushing,
    and the gear's bound from step 1 left it no plan the other way (docs/mirror_planner.md)."""
    base = {
        "linearisation": "paper",
        "paper_speed": "previous",
        "paper_angle": "previous",
        "max_iterations": 12,
        "refine_candidates_parallel": 4,
        "paper_first": "seed",
        "stop_first_speed": 0.05,
    }
    return multistart_config(**{**base, **changes})


class MirrorPolicyConfig(StrictModel):
    """When the policy replans, and when it gives up (Fig. 11's decision loop)."""

    drift_position: float = Field(0.10, gt=0)  # [m] replan when the car is this far off the plan
    drift_heading_deg: float = Field(3.0, gt=0, le=180)
    retry_every: int = Field(5, ge=0)  # control steps to wait after a failed solve
    max_failures: int = Field(8, ge=1)  # consecutive failed solves before giving up
    max_plans: int = Field(40, ge=1)  # plans per episode before giving up
    # Plans in a row without lowering the cost of standing still by 1 %. In tight parallel
    # slots the car shuffles in and that cost falls one switch's price every few plans (up
    # to 7 plans between gains): at 6, 12 standard episodes that park at 8 gave up
    # (docs/mirror_planner.md, "Execution").
    patience: int = Field(8, ge=1)
