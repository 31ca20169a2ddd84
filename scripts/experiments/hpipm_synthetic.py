"""How fast is HPIPM (a Riccati-based interior-point QP solver) at the planner's sizes?

    pip install casadi==3.8.2     # not a MirrorPark dependency: its wheel ships HPIPM
    python scripts/experiments/hpipm_synthetic.py [--horizon 60] [--repeats 20]

HPIPM needs a QP in optimal-control form (stage-wise dynamics, costs and rows). The
planner's QP reaches that form only after a rewrite (S and the previous command as extra
states, each row's slack as an extra input of its stage), so this script times HPIPM,
through casadi's ``conic`` interface, on a random problem of those dimensions: 10 states,
3 inputs and one inequality row per stage, over the planner's horizon of 60 steps. It
prints the median time of a call, HPIPM's own solver time and its iterations, next to
piqp on the same QP through casadi and directly (the planner's way: its sparse solver,
set up once, then solved again).
"""

from __future__ import annotations

import argparse
import time

import numpy as np


def ocp_qp(n: int, nx: int = 10, nu: int = 3, ng: int = 1, seed: int = 0):
    """(H, g, A, lba, uba, lbx, ubx) of a random, well-posed OCP QP in casadi's HPIPM
    layout: variables [x0 u0 x1 u1 ... xN], rows [gap0 con0 gap1 con1 ... conN]."""
    rng = np.random.default_rng(seed)
    nv = (n + 1) * nx + n * nu
    xi = lambda k: k * (nx + nu)  # noqa: E731
    H = np.zeros((nv, nv))
    for k in range(n + 1):
        Q = rng.normal(size=(nx, nx))
        H[xi(k) : xi(k) + nx, xi(k) : xi(k) + nx] = 0.1 * Q @ Q.T + np.eye(nx)
        if k < n:
            H[xi(k) + nx : xi(k) + nx + nu, xi(k) + nx : xi(k) + nx + nu] = np.eye(nu)
    Ad = np.eye(nx) + 0.05 * rng.normal(size=(nx, nx))
    Bd = 0.1 * rng.normal(size=(nx, nu))
    rows, lba, uba = [], [], []
    for k in range(n + 1):
        if k < n:
            gap = np.zeros((nx, nv))
            gap[:, xi(k) : xi(k) + nx] = Ad
            gap[:, xi(k) + nx : xi(k) + nx + nu] = Bd
            gap[:, xi(k + 1) : xi(k + 1) + nx] = -np.eye(nx)
            rows.append(gap)
            lba += [0.0] * nx
            uba += [0.0] * nx
        con = np.zeros((ng, nv))
        con[:, xi(k) : xi(k) + nx] = rng.normal(size=(ng, nx))
        if k < n:
            con[:, xi(k) + nx] = 1.0  # the row's slack, an input of its stage
        rows.append(con)
        lba += [-1.0] * ng
        uba += [np.inf] * ng
    lbx, ubx = -10.0 * np.ones(nv), 10.0 * np.ones(nv)
    lbx[:nx] = ubx[:nx] = rng.normal(size=nx)  # the initial state
    return H, rng.normal(size=nv), np.vstack(rows), np.array(lba), np.array(uba), lbx, ubx, (nx, nu, ng)


def main() -> None:
    import casadi as ca

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--horizon", type=int, default=60)
    ap.add_argument("--repeats", type=int, default=20)
    a = ap.parse_args()
    n = a.horizon
    H, g, A, lba, uba, lbx, ubx, (nx, nu, ng) = ocp_qp(n)
    Hs, As = ca.sparsify(ca.DM(H)), ca.sparsify(ca.DM(A))
    hpipm = {"N": n, "nx": [nx] * (n + 1), "nu": [nu] * n + [0], "ng": [ng] * (n + 1), "print_problem": False}
    hpipm["hpipm"] = {"mode": "speed", "iter_max": 100, **{f"res_{r}_max": 1e-6 for r in "gbdm"}}
    for name, opts in (("hpipm", hpipm), ("piqp", {})):
        S = ca.conic("S", name, {"h": Hs.sparsity(), "a": As.sparsity()}, {**opts, "error_on_fail": False})
        args = dict(h=Hs, g=g, a=As, lba=lba, uba=uba, lbx=lbx, ubx=ubx)
        S(**args)
        ts, solver = [], []
        for _ in range(a.repeats):
            t = time.perf_counter()
            r = S(**args)
            ts.append(time.perf_counter() - t)
            solver.append(S.stats().get("t_proc_solver", float("nan")))
        st = S.stats()
        print(
            f"{name}: objective {float(r['cost']):.8f}, call {1e3 * np.median(ts):.2f} ms (median of {a.repeats}), "
            f"solver {1e3 * np.nanmedian(solver):.2f} ms, iterations {st.get('iter_count', st.get('iter'))}"
        )
    direct_piqp(H, g, A, lba, uba, lbx, ubx, a.repeats)


def direct_piqp(H, g, A, lba, uba, lbx, ubx, repeats: int) -> None:
    """piqp's own Python binding on the same QP, as the planner calls it."""
    import scipy.sparse as sp

    from planners.mirror.solvers import PIQP

    eq = lba == uba
    s = PIQP.SparseSolver()
    s.settings.verbose = False
    G = sp.csc_matrix(A[~eq])
    s.setup(sp.csc_matrix(H), g, sp.csc_matrix(A[eq]), lba[eq], G, lba[~eq], uba[~eq], lbx, ubx)
    ts = []
    for _ in range(repeats):
        t = time.perf_counter()
        s.solve()
        ts.append(time.perf_counter() - t)
    r = s.result
    med = 1e3 * np.median(ts)
    print(f"piqp, direct: objective {r.info.primal_obj:.8f}, solve {med:.2f} ms, iterations {r.info.iter}")


if __name__ == "__main__":
    main()
