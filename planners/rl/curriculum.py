"""Which scenario each training episode starts from: a curriculum over the Table III grid.

Every case gets a difficulty in [0, 1]: the mean of its quantiles in slot tightness
(least spare room first), distance of the start from the slot line (y0) and |theta0|.
At curriculum level ``q`` the episodes draw uniformly from the easiest fraction ``q``.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np

from mirrorpark_env.grid import TYPES, Grid
from mirrorpark_env.scenario import ParkingType


def difficulty(grid: Grid, indices: np.ndarray) -> np.ndarray:
    """Difficulty of the cases ``indices`` of ``grid`` in [0, 1], ranked within their set."""
    c = grid.columns
    v = grid.vehicle
    t = c["type"][indices]
    parallel = t == TYPES.index(ParkingType.PARALLEL)
    spare = np.where(parallel, c["slot_length"][indices] - v.length, c["slot_width"][indices] - v.width)

    def quantile(x: np.ndarray) -> np.ndarray:
        r = np.argsort(np.argsort(x, kind="stable"), kind="stable")
        return r / max(len(x) - 1, 1)

    return (quantile(-spare) + quantile(c["y0"][indices]) + quantile(np.abs(c["theta0_deg"][indices]))) / 3.0


class CurriculumScenarios(gym.Wrapper):
    """Resets the environment into grid cases of ``parking_types``, easiest first.

    ``set_level(q)`` opens the easiest fraction ``q`` of the cases (1: all of them).
    """

    def __init__(self, env: gym.Env, parking_types: list[str], level: float = 1.0, grid: Grid | None = None):
        super().__init__(env)
        self.grid = grid or Grid.from_config()
        idx = np.concatenate([self.grid.indices(t) for t in parking_types])
        d = difficulty(self.grid, idx)
        order = np.argsort(d, kind="stable")
        self._by_difficulty = idx[order]
        self.level = 1.0
        self.set_level(level)

    def set_level(self, level: float) -> None:
        if not 0 < level <= 1:
            raise ValueError(f"curriculum level: must be in (0, 1], got {level}")
        self.level = float(level)
        self._open = max(1, int(round(level * len(self._by_difficulty))))

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        if seed is not None:
            self.env.reset(seed=seed)  # seeds np_random, from which the cases are drawn
        i = int(self.env.unwrapped.np_random.integers(self._open))
        return self.env.reset(options={"scenario": self.grid.scenario(int(self._by_difficulty[i]))})


class SuccessLadder:
    """The curriculum level, driven by the learner's success: it opens ``step`` more of the
    cases once ``window`` episodes at the current level have parked at least ``threshold``
    of the time, and stays where it is until they do."""

    def __init__(self, start: float, step: float, threshold: float, window: int) -> None:
        if not 0 < start <= 1 or not 0 < step <= 1 or not 0 < threshold <= 1 or window < 1:
            got = (start, step, threshold, window)
            raise ValueError(f"SuccessLadder: start, step and threshold in (0, 1], window >= 1; got {got}")
        self.level, self.step, self.threshold, self.window = start, step, threshold, window
        self._recent: list[bool] = []

    def record(self, success: bool) -> float:
        """Take one finished episode's outcome; the level now."""
        self._recent.append(bool(success))
        if len(self._recent) >= self.window and self.level < 1:
            if sum(self._recent[-self.window :]) >= self.threshold * self.window:
                self.level = min(1.0, self.level + self.step)
                self._recent.clear()
        return self.level


class FixedScenarios(gym.Wrapper):
    """Resets into the given scenarios in turn (evaluation on a fixed sample)."""

    def __init__(self, env: gym.Env, scenarios: list):
        super().__init__(env)
        if not scenarios:
            raise ValueError("FixedScenarios: needs at least one scenario")
        self.scenarios = list(scenarios)
        self._next = 0

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        sc = self.scenarios[self._next % len(self.scenarios)]
        self._next += 1
        return self.env.reset(seed=seed, options={"scenario": sc})


class LeanInfo(gym.Wrapper):
    """Keeps only the step-info keys that learning reads: HER copies every info it stores."""

    KEYS = ("is_success", "collision")

    def step(self, action):
        obs, reward, terminated, truncated, info = self.env.step(action)
        return obs, reward, terminated, truncated, {k: info[k] for k in self.KEYS}
