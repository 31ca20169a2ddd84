"""A training config small enough for a test: a few hundred steps of a tiny network."""

from __future__ import annotations

from planners.rl.config import RLConfig, load_rl_config

TINY = dict(learning_starts=100, batch_size=32, net_arch=[32, 32])


def tiny_config(**overrides) -> RLConfig:
    """``configs/rl.yaml`` with a tiny network and batch, then ``overrides``."""
    return load_rl_config(overrides={**TINY, **overrides})
