"""Settings of the hybrid A* search (``search.py``): resolution, costs, heuristic, budget."""

from __future__ import annotations

from typing import Literal

from pydantic import Field, model_validator

from mirrorpark_env.config import StrictModel

from ..common.cost_to_go_config import CostToGoConfig


class HybridAStarConfig(StrictModel):
    """Search resolution, costs and budget. Lengths in metres, costs in metres of driving."""

    xy_resolution: float = Field(0.1, gt=0, le=5)
    heading_resolution_deg: float = Field(5.0, gt=0, le=90)
    # Where the car is tight (closer than ``fine_gap`` to an obstacle) cells are finer: the
    # short shuffles of a tight manoeuvre turn the car by a degree or two each, and cells of
    # 5 deg would close every one of them as a state already seen.
    fine_gap: float = Field(0.15, ge=0, le=5)  # 0: coarse cells everywhere
    fine_xy_resolution: float = Field(0.1, gt=0, le=5)
    fine_heading_resolution_deg: float = Field(1.0, gt=0, le=90)
    step: float = Field(0.4, gt=0, le=5)  # arc length of one motion primitive
    min_step: float = Field(0.1, gt=0, le=5)  # shortest primitive left after cutting one short at an obstacle
    n_steer: int = Field(5, ge=1, le=99)  # steering angles per direction, odd (straight included)
    steer_fraction: float = Field(0.9, gt=0, le=1)  # plan curvature to this fraction of the car's limit
    sample_step: float = Field(0.05, gt=0, le=1)  # pose spacing of the collision checks
    clearance: float = Field(0.05, ge=0, le=1)  # gap kept to every obstacle, for tracking error
    # Near a start closer than that gap: within ``start_relief`` of it, keep this share of the
    # start's gap (the stopping check keeps half of it too): a car parked along a wall must
    # turn away from it, and its far corner first swings closer.
    start_relief: float = Field(2.5, gt=0, le=10)
    start_gap_share: float = Field(0.5, ge=0.5, le=1)
    reverse_cost: float = Field(1.5, ge=1)  # per metre reversed (forward: 1)
    switch_cost: float = Field(2.0, ge=0)  # per direction switch
    steer_cost: float = Field(0.2, ge=0)  # per metre, times |steer| / max steer
    steer_change_cost: float = Field(0.5, ge=0)  # per change of steering between primitives, times |change| / max
    heuristic_weight: float = Field(2.0, ge=1, le=100)  # > 1: greedy, not optimal (docs/hybrid_astar.md)
    # The forward search's estimate besides the Reeds-Shepp length: the cost to go over
    # (x, y, heading) that knows the car ("cost_to_go"), or the 2D grid distance ("grid", the
    # ablation). The lattice's price is the search's own (its ``price`` field is replaced).
    heuristic: Literal["cost_to_go", "grid"] = "cost_to_go"
    lattice: CostToGoConfig = CostToGoConfig(xy_resolution=0.3, entry_length=0.0)
    first: Literal["backward", "forward"] = "backward"  # which search spends its share of the budget first
    # The cost to go is built as far as this x V(start) + this many metres (``CostToGoHeuristic``)
    lattice_stop: tuple[float, float] = (1.25, 5.0)
    # ... and takes over from the grid distance after this many forward expansions: a forward
    # search that finds its way at once keeps its paths, one that stalls is steered by it
    plain_expansions: int = Field(1_000, ge=0)
    analytic_every: int = Field(2, ge=1)  # try a Reeds-Shepp connection every k-th expansion
    backward_share: float = Field(0.5, ge=0, le=1)  # of the budget, for the search out of the slot
    # The two searches take turns of this many expansions (0: the first runs to its end, then
    # the second): a call costs about twice the quicker search's work, not the first's whole
    # share. 1,000: lots' p95 work 0.57x, standard's 0.76x, switches +3 % and +0.4 % (docs)
    interleave: int = Field(1_000, ge=0)
    grid_resolution: float = Field(0.25, gt=0, le=5)
    goal_margin: float = Field(0.05, ge=0, le=1)  # ISO margins plus this, for the goal set
    goal_heading_deg: float = Field(2.0, ge=0, le=45)
    # Analytic shots go to the target and to up to this many more poses of the goal set: the
    # target shifted along the slot's axis, as far as the ISO check (with ``goal_margin``) allows
    goal_shots: int = Field(0, ge=0, le=20)  # 0: the target alone (2 gained nothing measured: docs)
    goal_shot_range: float = Field(8.0, ge=0, le=100)  # [m] ... from nodes this near the target (Reeds-Shepp)
    window_margin: float = Field(10.0, gt=0, le=100)  # search window beyond the slot and start
    max_expansions: int = Field(9_000, ge=1)  # the budget, in work: node expansions per call (~1 s here)
    wall_clock_limit_s: float = Field(120.0, gt=0, le=3600)  # a safety net only; a call where it fires says so

    @model_validator(mode="after")
    def _consistent(self) -> HybridAStarConfig:
        if self.n_steer % 2 == 0:
            raise ValueError(f"n_steer: must be odd (straight included), got {self.n_steer}")
        if self.min_step > self.step:
            raise ValueError(f"min_step: must be <= step={self.step} m, got {self.min_step}")
        if self.lattice_stop[0] < 1 or self.lattice_stop[1] < 0:
            raise ValueError(f"lattice_stop: must be (>= 1, >= 0 m), got {self.lattice_stop}")
        if self.sample_step > self.step:
            raise ValueError(f"sample_step: must be <= step={self.step} m, got {self.sample_step}")
        return self
