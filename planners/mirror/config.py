"""Validated settings of the mirrored-target planner and its policy (lengths in m, angles in rad).

A planner is the core (``CoreConfig``: the model, the QP's weights, SCP, branch and bound,
the checks) plus one strategy with its own small config: which candidates a call solves
and how it picks one. The registry's planners are the presets of ``presets.py``; each
takes keyword overrides of either part
(``preset_config("mirror-paper", time_limit_s=60, paper_first="nominal")``).
"""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field

from mirrorpark_env.config import StrictModel

from ..common.cost_to_go_config import CostToGoConfig, PriceConfig


class GuideConfig(StrictModel):
    """Settings of the guide search (lengths in m, angles in rad)."""

    steer_fraction: float = Field(0.9, gt=0, le=1)  # paths turn at this fraction of the curvature limit
    sample_step: float = Field(0.1, gt=0, le=1)  # spacing of the fine collision check
    coarse_step: float = Field(0.3, gt=0, le=3)  # spacing of the first, cheap check
    gap: float = Field(0.04, gt=0, le=1)  # clearance every fine sample keeps to the obstacles
    # Its paths' price: length, reversing and switches (it does not price steering)
    price: PriceConfig = PriceConfig(steer_cost=0.0)
    max_checked: int = Field(24, ge=1)  # candidate paths checked per call
    start_gap: float = Field(0.01, gt=0, le=1)  # (or to the start's own gap, if smaller): room to leave a kerb
    in_slot_turns: bool = True  # tails that park by back-and-forth arcs inside the slot
    in_slot_arcs: int = Field(12, ge=1, le=100)  # arcs of each such multi-point turn, at most


class CoreConfig(StrictModel):
    """What every strategy shares: the planning model, the QP of one round (Eq. 33's
    weights, the obstacle rows, the switch's band), SCP with Algorithm I and the checks.

    Its SCP stops early only within 1 cm and 0.3 deg of a goal (a tight slot's ISO window
    is a few centimetres wide)."""

    horizon: int = Field(60, ge=10, le=400)  # N (Table II)
    dt: float = Field(0.1, gt=0, le=1)
    model_substeps: int = Field(2, ge=1, le=20)
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
    # target's heading (cost.py); wider windows keep one weight (0: always one weight).
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
    # QP solves per planning call (a work budget, the same on every machine): once spent, no
    # QP is solved and the call returns the best plan it has (None: no limit). At 120 the
    # tail of ``mirror``'s calls is bounded by work (docs/mirror_planner.md, "Where the time goes").
    call_qp_budget: int | None = Field(120, ge=1, le=1_000_000)
    kkt_solver: Literal["sparse_ldlt", "sparse_multistage", "auto"] = "auto"  # piqp's (solvers.PiqpQP)
    qp_tolerance: float = Field(1e-4, gt=0, lt=1)  # piqp's absolute residual and duality-gap tolerance
    time_limit_s: float = Field(5.0, gt=0)  # branch and bound's wall-clock safety net per MIQP (recorded)
    seed_swings: tuple[float, ...] = (-0.8, -0.4, 0.4, 0.8)  # [rad] heading excursions tried as shape seeds
    seed_speed: float = Field(2.0, gt=0, le=3)  # [m/s] cruise speed of a path tracked as a seed
    seed_accel: float = Field(1.5, gt=0, le=3)  # [m/s^2] its acceleration and planned deceleration
    # Every plan ends settled: stopped, its lagged acceleration not pointing back (in the planned
    # frame, direction x a_N >= 0). Without it a plan may stop while still braking, and the lag
    # rolls the car back across zero: a direction switch of a centimetre that the env counts.
    end_settled: bool = True
    # [m/s] A car rolling against a candidate's gear slower than this (creeping, its lag
    # still pushing) may roll on until the model's fastest stop has stopped it; else the
    # gear's speed bound holds from the first step and no such candidate exists (0: never).
    stop_first_speed: float = Field(0.0, ge=0, le=1)


class AimedConfig(StrictModel):
    """``mirror``: candidates over first gear and switch, each aimed down the cost to go
    (``cost_to_go.py``) and compared by driven cost plus the cost to go at the end
    (``strategies/aimed.py``). A switch costs 5 m of driving in its cost to go, whose
    heading cells are 3 deg (measured against 3 and 8 m, docs/mirror_planner.md)."""

    kind: Literal["aimed"] = "aimed"
    lattice: CostToGoConfig = CostToGoConfig(headings=120, price=PriceConfig(switch_cost=5.0))
    candidates: int = Field(3, ge=1, le=20)  # switch candidates refined where the cost to go is blind
    updates: int = Field(2, ge=1, le=10)  # solves of the leading candidate, its goal moved down V each time
    iterations: int = Field(3, ge=1, le=100)  # SCP rounds per solve
    scout_node_limit: int = Field(2, ge=1, le=100_000)  # branch-and-bound nodes per MIQP while scouting
    retry_nodes: int = Field(100, ge=0, le=1_000_000)  # nodes in all for re-solving on the full budget
    reach_speed: float = Field(1.2, gt=0, le=3)  # [m/s] a goal lies at most this far down V per second left
    finish_radius: float = Field(8.0, ge=0)  # [m] within this of the target, also plan toward it
    finish_candidates: int = Field(1, ge=0, le=10)  # ... with this many shape seeds, best by their merit
    # [m] Best first: candidates solved in the order of their warm starts' price, the last
    # one solved the first whose warm start costs more than the best plan found by over
    # this (None: every candidate, in the order the warm starts were found). 10 m, two
    # switches' price: 5 m costs more switches and parking time (docs/mirror_planner.md).
    margin: float | None = Field(10.0, ge=0)


class ColdConfig(AimedConfig):
    """``mirror-cold``: ``mirror`` with no path as a warm start; the classic shapes seed the
    candidates (``strategies/aimed.py``, ``ColdStart``)."""

    kind: Literal["cold"] = "cold"
    # Every candidate: the classic shapes' prices rank them too poorly for best first
    # (two of tests/test_cost_to_go.py's fixed cases missed with 5 m). Its ablation
    # partner is then ``mirror-exhaustive``.
    margin: float | None = Field(None, ge=0)


class GuidedConfig(StrictModel):
    """``mirror-guided``: one candidate along the geometric guide (``guide.py``), polished
    by SCP (``strategies/guided.py``)."""

    kind: Literal["guided"] = "guided"
    iterations: int = Field(2, ge=1, le=1000)  # SCP rounds on a guided candidate
    # [m/s] more seed speeds for a plan with a switch: other switch steps, the cheapest plan used
    switch_speeds: tuple[Annotated[float, Field(gt=0, le=3)], ...] = (1.5, 2.5)


class MultistartConfig(StrictModel):
    """``mirror-multistart``: the classic shapes of both gears at two switch steps and
    without a switch, refined by SCP and compared by their optimal cost (``strategies/multistart.py``)."""

    kind: Literal["multistart"] = "multistart"
    refine_candidates: int = Field(2, ge=1)  # candidates refined by SCP after the seed search
    refine_candidates_parallel: int | None = Field(None, ge=1)  # ... in parallel slots (None: as above)


class PaperConfig(MultistartConfig):
    """``mirror-paper``: the multi-start on the paper's fixed-angle model (Eqs. 22-32) in
    place of SCP's Jacobians (``linearisation.py``). Where the paper leaves them open:"""

    kind: Literal["paper"] = "paper"
    refine_candidates_parallel: int | None = Field(4, ge=1)
    # The speed inside the model's v gamma and v / l terms (Eq. 31's A_i): "nominal", 1 m/s
    # in the plan's gear at every step; "previous", each step's speed in the previous
    # round's rollout, the rounds going on until the rollout is clear and its speeds stay
    # within ``paper_speed_tolerance``.
    paper_speed: Literal["nominal", "previous"] = "previous"
    paper_speed_tolerance: float = Field(0.1, gt=0)  # [m/s]
    paper_speed_floor: float = Field(0.0, ge=0, le=3)  # [m/s] "previous": at least this, in the plan's gear
    # Its linearising angle ("close to the average yaw angle of the parking path", Fig. 13):
    # "ends", the mean of the start and goal headings; "previous", from the second round on,
    # the mean heading of the previous round's rollout.
    paper_angle: Literal["ends", "previous"] = "previous"
    paper_angle_tolerance: float = Field(0.02, gt=0)  # [rad]
    # The first round's speeds and angle: "nominal", 1 m/s about the ends' mean heading;
    # "seed", those of the candidate's shape seed rollout, as a round zero.
    paper_first: Literal["nominal", "seed"] = "seed"


StrategyConfig = Annotated[
    AimedConfig | ColdConfig | GuidedConfig | MultistartConfig | PaperConfig, Field(discriminator="kind")
]


class MirrorPlannerConfig(StrictModel):
    """A mirror planner: the core and its strategy (the default: ``mirror``)."""

    core: CoreConfig = CoreConfig()
    strategy: StrategyConfig = AimedConfig()


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
    # Clearances grow with the disagreement between the measured states and the model's
    # one-step predictions (``common.innovation``; exactly zero without a perturbation):
    # gain x its RMS in position, in steps, up to a most (policy._widen).
    margin_gain: float = Field(4.0, ge=0, le=50)
    margin_step: float = Field(0.02, gt=0, le=0.5)  # [m]
    margin_max: float = Field(0.2, ge=0, le=1)  # [m]
