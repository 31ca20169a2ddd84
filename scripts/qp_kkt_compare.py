"""Would piqp's multistage KKT solver be faster on the planner's QPs with slacks per stage?

    python scripts/qp_kkt_compare.py [--qps 400] [--start 1] [--every 7]

The planner orders its QP variables stage by stage, then the switch point S, then one
slack per inequality row; piqp's ``sparse_multistage`` solver takes trailing variables
as dense coupling, so the planner uses ``sparse_ldlt`` whenever a QP has more than a few
rows. This script captures the first ``qps`` QPs that ``mirror`` solves on every
``every``-th smoke case from ``start`` (one process), then solves each three times from
a cold start with the planner's tolerances: as captured with ``sparse_ldlt``; with each
row's slack moved into the block of the stage its row constrains and S last (the layout
the multistage solver can exploit) with ``sparse_ldlt``; and that layout with
``sparse_multistage``. It prints the median setup and solve times, the interior-point
iterations, and how far the solutions differ.
"""

from __future__ import annotations

import argparse
import time
from dataclasses import replace

import numpy as np

from evaluation.cases import from_sample
from evaluation.runner import run_case
from planners.mirror import solvers
from planners.mirror.config import MirrorPlannerConfig
from planners.mirror.layout import switch_index
from planners.mirror.model import NU, NX


def capture(n: int, start: int, every: int) -> list[solvers.QP]:
    """The first ``n`` QPs ``mirror`` hands to piqp on the chosen smoke cases."""
    qps: list[solvers.QP] = []
    solve = solvers.PiqpQP.solve

    def grab(self, qp):
        if len(qps) < n:
            qps.append(replace(qp))
        return solve(self, qp)

    solvers.PiqpQP.solve = grab
    try:
        for sc in from_sample("smoke")[start::every]:
            run_case("mirror", sc)
            if len(qps) >= n:
                break
    finally:
        solvers.PiqpQP.solve = solve
    return qps


def staged_order(qp: solvers.QP, horizon: int) -> np.ndarray:
    """A permutation of z: each stage's states and commands, then the slacks of the rows
    on that stage (a row belongs to the last stage it touches), S at the end."""
    blk, i_s = NX + NU, switch_index(horizon)
    nz0 = i_s + 2
    G = qp.G.tocsr()
    stage = np.empty(G.shape[0], int)
    for r in range(G.shape[0]):
        cols = G.indices[G.indptr[r] : G.indptr[r + 1]]
        cols = cols[cols < i_s]
        stage[r] = cols.max() // blk if len(cols) else horizon
    order: list[int] = []
    for i in range(horizon + 1):
        order += range(blk * i, min(blk * (i + 1), i_s))
        order += list(nz0 + np.flatnonzero(stage == i))
    return np.array(order + [i_s, i_s + 1])


def solve(qp: solvers.QP, kkt: str, eps: float) -> tuple[float, int, float, float, np.ndarray]:
    """(objective, iterations, setup s, solve s, x) from a fresh piqp solver with the
    planner's settings (``PiqpQP``'s)."""
    s = solvers.PiqpQP(eps, 0.1 * eps, kkt_solver=kkt, eps_gap=(eps, 0.1 * eps))._new_solver(qp.G.shape[0])
    t0 = time.perf_counter()
    s.setup(qp.P, qp.c, qp.A, qp.b, qp.G, qp.h_l, qp.h_u, qp.x_l, qp.x_u)
    t1 = time.perf_counter()
    s.solve()
    t2 = time.perf_counter()
    return float(s.result.info.primal_obj), int(s.result.info.iter), t1 - t0, t2 - t1, np.array(s.result.x)


def permuted(qp: solvers.QP, p: np.ndarray) -> solvers.QP:
    mats = [m.tocsc() for m in (qp.P[p][:, p], qp.A[:, p], qp.G[:, p])]
    for m in mats:
        m.sort_indices()
    P, A, G = mats
    return solvers.QP(P, qp.c[p], A, qp.b, G, qp.h_l, qp.h_u, qp.x_l[p], qp.x_u[p])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--qps", type=int, default=400)
    ap.add_argument("--start", type=int, default=1)
    ap.add_argument("--every", type=int, default=7)
    a = ap.parse_args()
    cfg = MirrorPlannerConfig()
    eps = cfg.qp_tolerance
    qps = capture(a.qps, a.start, a.every)
    out = []
    for qp in qps:
        p = staged_order(qp, cfg.horizon)
        q2 = permuted(qp, p)
        ref = solve(qp, "sparse_ldlt", eps)
        lay = solve(q2, "sparse_ldlt", eps)
        ms = solve(q2, "sparse_multistage", eps)
        x = np.empty_like(ms[4])
        x[p] = ms[4]
        out.append((qp.G.shape[0], ref[1], ref[2], ref[3], lay[3], ms[1], ms[2], ms[3],
                    abs(ref[0] - ms[0]) / max(1.0, abs(ref[0])), float(np.abs(ref[4] - x).max())))  # fmt: skip
    R = np.array(out)
    med = lambda j: float(np.median(R[:, j]))  # noqa: E731
    print(f"{len(R)} QPs; inequality rows: median {med(0):.0f}, max {R[:, 0].max():.0f}")
    ms = lambda j: f"{1e3 * med(j):.2f} ms"  # noqa: E731
    print(f"sparse_ldlt, as built:        {med(1):.0f} iterations, setup {ms(2)}, solve {ms(3)}")
    print(f"sparse_ldlt, slacks staged:   solve {ms(4)}")
    print(f"sparse_multistage, staged:    {med(5):.0f} iterations, setup {ms(6)}, solve {ms(7)}")
    print(f"solve time as built / multistage: median ratio {np.median(R[:, 3] / R[:, 7]):.2f}, "
          f"totals {R[:, 3].sum():.3f} s / {R[:, 7].sum():.3f} s")  # fmt: skip
    print(f"objectives differ by at most {R[:, 8].max():.1e} (relative); solutions by at most {R[:, 9].max():.1e}")


if __name__ == "__main__":
    main()
