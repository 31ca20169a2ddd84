"""Angle helpers shared by the environment and the planners (radians)."""

from __future__ import annotations

import math

import numpy as np


def wrap_angle(angle: float) -> float:
    """``angle`` brought into [-pi, pi]."""
    return math.remainder(angle, math.tau)


def wrap_angles(angles: np.ndarray) -> np.ndarray:
    """``wrap_angle`` on an array, in [-pi, pi)."""
    return np.remainder(angles + math.pi, math.tau) - math.pi


def unwrap_near(angle: float, reference: float) -> float:
    """``angle`` plus the multiple of 2 pi that brings it nearest ``reference``."""
    return angle + math.tau * round((reference - angle) / math.tau)
