"""The settings of the cost to go (``cost_to_go.py``) and the price of driving it is counted in.

The price is the one set of weights by which a planner ranks paths, in metres of driving:
the mirror planner's cost to go, guide, seeds and plans, and hybrid A*'s heuristic, each
with its planner's own weights.
"""

from __future__ import annotations

from typing import Annotated

import numpy as np
from pydantic import Field

from mirrorpark_env.config import StrictModel


class PriceConfig(StrictModel):
    """What driving costs, in metres of driving: the one set of weights by which a planner
    ranks paths (``cost.py`` prices every term; the cost to go, the guide, the seeds and the
    plans of a call all use their planner's)."""

    reverse_cost: float = Field(0.5, ge=0)  # extra per metre reversed
    steer_cost: float = Field(0.05, ge=0)  # extra per metre at full lock: straight wins ties, no needless S-bends
    switch_cost: float = Field(3.0, ge=0)  # per direction switch
    penetration_cost: float = Field(100.0, ge=0)  # per metre of footprint penetration, summed over a rollout's steps


class CostToGoConfig(StrictModel):
    """Lattice and price of the cost to go (lengths in m)."""

    xy_resolution: float = Field(0.15, gt=0.01, le=2)
    headings: int = Field(72, ge=8, le=360)  # heading cells in a full turn
    steer_fraction: float = Field(0.9, gt=0, le=1)  # moves turn at this fraction of the curvature limit
    clearance: float = Field(0.05, ge=0, le=1)  # gap every lattice pose and move midpoint keeps
    price: PriceConfig = PriceConfig()
    margin: float = Field(10.0, gt=0, le=50)  # [m] along the road beyond the slot
    start_margin: float = Field(3.0, ge=0, le=50)  # [m] the lattice reaches this far around the start
    # Exact multi-point turns out of the slot from the target (arcs per turn, 0: none): V's
    # sources besides the target, where a tight slot is finer than the lattice.
    in_slot_arcs: int = Field(12, ge=0, le=100)
    tail_step: float = Field(0.02, gt=0, le=1)  # [m] spacing of their poses (an arc ends where it would touch)
    # Exact single-gear entries into the slot (straight, full-lock arc, straight, driven out
    # from the target until they would touch, 0: none): V's sources near the slot, where the
    # lattice's moves, a cell apart, reach the mouth only roughly (measured: V read twice the
    # cost of a one-switch park from a pose 5 m from a reverse slot).
    entry_length: float = Field(6.0, ge=0, le=20)  # [m] longest straight of an entry, either side of its arc
    entry_step: float = Field(0.1, gt=0.01, le=1)  # [m] spacing of the entries' straights and arc samples
    # Their arcs' curvatures, as fractions of the car's limit: each adds a family of poses
    entry_steer: tuple[Annotated[float, Field(gt=0, le=1)], ...] = (0.9,)
    # Near the target, where the cells are too coarse to rank poses: the pose error priced
    # in metres of driving (per m, per rad), at most this much above V.
    finish_position: float = Field(50.0, ge=0)
    finish_heading: float = Field(30.0, ge=0)
    finish_cap: float = Field(20.0, ge=0)


# -- the price of driving, in metres ---------------------------------------------------
def move_cost(price: PriceConfig, length: float, reverse: bool, steered: bool) -> float:
    """A move of ``length`` metres, reversed or not, at full lock or straight."""
    return length * (1.0 + (price.reverse_cost if reverse else 0.0) + (price.steer_cost if steered else 0.0))


def driven_metres(price: PriceConfig, ds: np.ndarray, reverse: np.ndarray) -> np.ndarray:
    """Each step's priced length: ``ds`` metres, those where ``reverse`` at 1 + ``reverse_cost``."""
    return ds * np.where(reverse, 1.0 + price.reverse_cost, 1.0)


def steering_cost(price: PriceConfig, fraction: np.ndarray | float, length: np.ndarray | float):
    """Extra for ``length`` metres turned at ``fraction`` of full lock."""
    return price.steer_cost * fraction * length


def switch_price(price: PriceConfig, switches):
    """``switches`` direction switches (a count, or counts)."""
    return price.switch_cost * switches


def path_price(price: PriceConfig, ds: np.ndarray, reverse: np.ndarray, switches: int) -> float:
    """Steps of ``ds`` metres (reversed where ``reverse``) through ``switches`` switches."""
    return float(ds.sum()) + price.reverse_cost * float(ds[reverse].sum()) + price.switch_cost * switches
