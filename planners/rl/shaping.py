"""Potential-based reward shaping with the scene's cost to go (Ng, Harada and Russell 1999).

The learner's reward becomes r + gamma Phi(s') - Phi(s) with Phi(s) = -min(V(s), cap) / scale,
V the cost to go over (x, y, heading) that the mirror planner and hybrid A* read
(``planners/common/cost_to_go.py``): metres of driving, reversing and switching still
needed, around the obstacles. Shaping of this form keeps the optimal policy; Phi is 0 at a
terminal state (success, collision, leaving the scene), so that over any episode that ends
the shaping adds -Phi(s0), whatever the policy did. Over an episode cut by the time limit it
adds gamma^T Phi(s_T) - Phi(s0) (a test checks both).

It is a wrapper of the learner's, not an option of the environment: the environment never
imports a planner's parts (configs -> scenario -> environment <- policy). The potential reads
the true state: it is part of the reward, which the learner never observes as input.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym

from ..common.cost_to_go import CostToGo
from ..common.cost_to_go_config import CostToGoConfig
from ..common.slot_cache import SlotCache

_CACHE: SlotCache[CostToGo] = SlotCache(64)  # grid slots repeat across cases


class CostToGoShaping(gym.Wrapper):
    """Adds gamma Phi(s') - Phi(s) to every step's reward; ``info["shaping"]`` is that term."""

    def __init__(self, env: gym.Env, gamma: float, scale: float = 10.0, cap: float = 60.0) -> None:
        super().__init__(env)
        if not 0 < gamma <= 1:
            raise ValueError(f"gamma: must be in (0, 1], got {gamma}")
        if not scale > 0 or not cap > 0:
            raise ValueError(f"scale, cap: must be > 0, got {scale}, {cap}")
        self.gamma, self.scale, self.cap = gamma, scale, cap
        self.config = CostToGoConfig()
        self.V: CostToGo | None = None
        self.phi = 0.0

    def potential(self) -> float:
        """Phi of the environment's true state: -min(V, cap) / scale (V inf where the lattice
        finds no way, so there the cap)."""
        x, y, th = (float(q) for q in self.env.unwrapped.state[:3])
        v, _ = self.V.at((x, y, th))
        return -min(v, self.cap) / self.scale

    def reset(self, **kwargs) -> tuple[Any, dict]:
        obs, info = self.env.reset(**kwargs)
        g = self.env.unwrapped.geometry
        self.V = _CACHE.get(g, self.config.model_dump_json(), lambda: CostToGo(g, self.config))
        self.phi = self.potential()
        return obs, info

    def step(self, action) -> tuple[Any, float, bool, bool, dict]:
        obs, reward, terminated, truncated, info = self.env.step(action)
        phi = 0.0 if terminated else self.potential()
        shaping = self.gamma * phi - self.phi
        self.phi = phi
        info = dict(info, shaping=shaping)
        return obs, float(reward) + shaping, terminated, truncated, info
