"""Where each variable sits in the QP's vector z.

Stage by stage (xi_0, u_0, xi_1, u_1, ..., xi_N), then the switch point S = (S_x, S_y),
then one slack per inequality row: the layout piqp's multistage KKT solver exploits.
"""

from __future__ import annotations

import numpy as np

from .model import NU, NX


def ix(i: int, j: int) -> int:
    """Index of state component ``j`` at step ``i``."""
    return (NX + NU) * i + j


def iu(i: int, j: int) -> int:
    """Index of command ``j`` at step ``i``."""
    return (NX + NU) * i + NX + j


def switch_index(horizon: int) -> int:
    """Index of S_x (S_y follows) for a horizon of N steps."""
    return (NX + NU) * horizon + NX


def x_index(horizon: int) -> np.ndarray:
    """(N + 1, NX): z[x_index] are the states."""
    return (NX + NU) * np.arange(horizon + 1)[:, None] + np.arange(NX)


def u_index(horizon: int) -> np.ndarray:
    """(N, NU): z[u_index] are the commands."""
    return (NX + NU) * np.arange(horizon)[:, None] + NX + np.arange(NU)
