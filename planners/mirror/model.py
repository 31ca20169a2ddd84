"""The planning model: discrete dynamics over one control step and its linearisations.

State [x, y, theta, v, a, delta] (the environment's order; the paper writes
[x, v, a, y, theta, delta]), control [a_cmd, delta_cmd]. The nonlinear step is the truth
model's own discretisation (exact lags, exact arcs) with fewer sub-steps, so plans and
the environment agree to millimetres. Two linearisations (docs/design.md):

- ``paper_linearisation``: Eqs. (22)-(29): heading linearised about a fixed angle,
  a given speed (one, or one per step) in the v terms, forward-Euler lags;
- ``jacobian_linearisation``: the exact Jacobians of the nonlinear step about a
  reference trajectory (sequential convex programming re-linearises about each solution).

Both return (A, B, c) with ``xi[i+1] = A[i] @ xi[i] + B[i] @ u[i] + c[i]``.
"""

from __future__ import annotations

import math

import numpy as np

from mirrorpark_env.vehicle import VehicleParams

NX, NU = 6, 2
X, Y, TH, V, A, D = range(6)


class PlanningModel:
    def __init__(self, params: VehicleParams, dt: float = 0.1, n_sub: int = 2):
        self.params, self.dt, self.n_sub = params, dt, n_sub
        h = dt / n_sub
        self.h = h
        ta, td = params.tau_accel_s, params.tau_steer_s
        self._ea0 = np.array([math.exp(-j * h / ta) for j in range(n_sub)])
        self._edm = np.array([math.exp(-(j + 0.5) * h / td) for j in range(n_sub)])
        self._dv_lag = ta * (1 - math.exp(-h / ta))
        self._ea_dt = math.exp(-dt / ta)
        self._ed_dt = math.exp(-dt / td)

    def step(self, xi: np.ndarray, u: np.ndarray) -> np.ndarray:
        """Nonlinear step for a batch: ``xi`` (..., 6), ``u`` (..., 2) -> (..., 6)."""
        x, y, th, v, a, d = (xi[..., k] for k in range(6))
        ac, dc = u[..., 0], u[..., 1]
        da, dd = a - ac, d - dc
        h, inv_l = self.h, 1.0 / self.params.wheelbase
        for j in range(self.n_sub):
            v1 = v + ac * h + da * (self._ea0[j] * self._dv_lag)
            ds = 0.5 * (v + v1) * h
            dth = ds * np.tan(dc + dd * self._edm[j]) * inv_l
            chord = ds * np.sinc(dth / (2 * np.pi))
            x = x + chord * np.cos(th + 0.5 * dth)
            y = y + chord * np.sin(th + 0.5 * dth)
            th = th + dth
            v = v1
        return np.stack([x, y, th, v, ac + da * self._ea_dt, dc + dd * self._ed_dt], axis=-1)

    def jacobian_linearisation(self, xi_ref: np.ndarray, u_ref: np.ndarray, eps: float = 1e-6):
        """Jacobians about (xi_ref[i], u_ref[i]) for all i at once, by batched differences."""
        n = len(u_ref)
        z = np.concatenate([xi_ref[:n], u_ref], axis=1)  # (n, 8)
        pert = np.concatenate([np.zeros((1, 8)), eps * np.eye(8)])  # (9, 8)
        zz = z[None, :, :] + pert[:, None, :]  # (9, n, 8)
        f = self.step(zz[..., :6], zz[..., 6:])  # (9, n, 6)
        jac = (f[1:] - f[0]) / eps  # (8, n, 6): d f / d input_k
        A_ = np.transpose(jac[:6], (1, 2, 0))  # (n, 6, 6)
        B_ = np.transpose(jac[6:], (1, 2, 0))  # (n, 6, 2)
        c_ = f[0] - np.einsum("nij,nj->ni", A_, xi_ref[:n]) - np.einsum("nij,nj->ni", B_, u_ref)
        return A_, B_, c_

    def paper_linearisation(self, n: int, angle: float, v_nominal: float | np.ndarray):
        """Eqs. (22)-(29) about the linearising ``angle`` with speed ``v_nominal`` in the
        speed terms: one number, or one per step (the speed v_i of Eq. 31's A_i).

        The paper's gamma_1 v = (cos A - sin A (theta - A)) v is bilinear in v and theta;
        its first-order expansion about (v_nominal, A) keeps gamma_1(A) = cos A on v and
        puts -v_nominal sin A on theta (likewise for y). Without the theta term a fixed
        angle could not move the car sideways at all. Eq. (24) uses v_nominal as printed.
        """
        p, dt = self.params, self.dt
        v = np.broadcast_to(np.asarray(v_nominal, float), (n,))
        ca, sa = math.cos(angle), math.sin(angle)
        A_ = np.tile(np.eye(NX), (n, 1, 1))
        A_[:, X, V] = dt * ca
        A_[:, X, TH] = -dt * v * sa
        A_[:, Y, V] = dt * sa
        A_[:, Y, TH] = dt * v * ca
        A_[:, TH, D] = dt * v / p.wheelbase
        A_[:, V, A] = dt
        A_[:, A, A] = 1 - dt / p.tau_accel_s
        A_[:, D, D] = 1 - dt / p.tau_steer_s
        B_ = np.zeros((n, NX, NU))
        B_[:, A, 0] = dt / p.tau_accel_s
        B_[:, D, 1] = dt / p.tau_steer_s
        c_ = np.zeros((n, NX))
        c_[:, X] = dt * v * sa * angle
        c_[:, Y] = -dt * v * ca * angle
        return A_, B_, c_
