"""Lean QPs: the solver drops switched-off rows and their slacks, and the optimum stays the same."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import scipy.sparse as sp

from evaluation.runner import run_case
from mirrorpark_env.scenario import Scenario
from planners.mirror import solvers
from planners.mirror.lean_qp import INACTIVE, lean
from planners.mirror.solvers import QP, PiqpQP

CASE = "parallel_rw4.50_sl6.72_sw2.50_th+10_y1.10"  # obstacle rows, some of them switched off by branch and bound


@pytest.fixture(scope="module")
def planner_qps():
    """Every QP one closed-loop episode of ``mirror`` hands its solver (a copy of each)."""
    seen: list[QP] = []
    solve = PiqpQP.solve

    def spy(self, qp):
        seen.append(replace(qp, h_l=qp.h_l.copy(), h_u=qp.h_u.copy(), c=qp.c.copy()))
        return solve(self, qp)

    mp = pytest.MonkeyPatch()
    mp.setattr(PiqpQP, "solve", spy)
    try:
        run_case("mirror", Scenario.from_case_id(CASE))
    finally:
        mp.undo()
    return seen


def _full(qp: QP) -> solvers.QPResult:
    """``qp`` solved whole, every row and slack kept."""
    mp = pytest.MonkeyPatch()
    mp.setattr(solvers, "lean", lambda q: (q, None))
    try:
        return PiqpQP().solve(qp)
    finally:
        mp.undo()


def test_the_planners_qps_solved_lean_have_the_same_optimum(planner_qps):
    off_rows = [int(((q.h_l <= INACTIVE) & np.isinf(q.h_u)).sum()) for q in planner_qps]
    assert sum(off_rows) > 0 and all(q.row_slacks for q in planner_qps)
    for qp, off in zip(planner_qps, off_rows):
        sub, cols = lean(qp)
        if off:  # two fewer variables' worth a row: the row and its slack
            assert sub.G.shape == (qp.G.shape[0] - off, qp.G.shape[1] - off) and len(cols) == qp.P.shape[0] - off
        a, b = _full(qp), PiqpQP().solve(qp)
        assert a.status == b.status
        if a.status == "solved":
            assert b.obj == pytest.approx(a.obj, rel=1e-6, abs=1e-6)
            assert b.x.shape == a.x.shape and np.abs(b.x - a.x).max() < 1e-3
            assert np.all(qp.G @ b.x - qp.h_l >= -1e-5)  # every row holds as given, the dropped ones too


def test_a_qp_not_laid_out_as_row_slacks_says_only_drops_its_rows():
    """min (z0 - 1)^2 + (z1 - 2)^2 with z0 + s >= 3 (soft) and z1 >= 5 (switched off); s in A too."""
    P = sp.csc_matrix(np.diag([2.0, 2.0, 0.0]))
    qp = QP(
        P,
        np.array([-2.0, -4.0, 1.0]),
        sp.csc_matrix([[0.0, 0.0, 1.0]]),  # s = 0.5 by an equality: not a slack of its own
        np.array([0.5]),
        sp.csc_matrix([[1.0, 0.0, 1.0], [0.0, 1.0, 0.0]]),
        np.array([3.0, INACTIVE]),
        np.array([np.inf, np.inf]),
        np.full(3, -np.inf),
        np.full(3, np.inf),
        row_slacks=True,
    )
    sub, cols = lean(qp)
    assert cols is None and sub.G.shape == (1, 3)  # the row goes, every variable stays
    res = PiqpQP().solve(qp)
    np.testing.assert_allclose(res.x, [2.5, 2.0, 0.5], atol=1e-6)
    assert res.obj == pytest.approx(_full(qp).obj, abs=1e-8)
