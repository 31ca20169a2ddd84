"""QP and disjunctive-MIQP solvers behind one small interface.

A QP is ``min 1/2 z'Pz + c'z`` s.t. ``Az = b``, ``h_l <= Gz <= h_u``, ``x_l <= z <= x_u``
(scipy CSC matrices, infinite bounds allowed). The MIQP of Eq. (40) is handed over in
disjunctive form: each ``Disjunction`` lists rows of G, one per alternative (a face of an
obstacle a point stays behind); at least one alternative must hold. Rows are *active*
at their ``h_l`` and inactive at ``INACTIVE``, so every node of a search shares one sparsity
pattern and only ``h_l`` is refilled. Big-M with binaries z_l (Eq. 40) describes the same
feasible set; solving the disjunctions directly avoids big-M's weak relaxation.

piqp drops G rows whose bounds are both infinite and does not restore them when an
update makes them finite, so an inactive row sits at the finite ``INACTIVE`` instead.

Backends: ``PiqpQP`` (piqp, pattern-aware), ``BranchAndBound`` (depth-first B&B over
any QP backend), ``Enumeration`` (every assignment; the reference for tests).
"""

from __future__ import annotations

import itertools
import math
import time
from dataclasses import dataclass, replace

import numpy as np
import piqp
import scipy.sparse as sp

from .lean_qp import INACTIVE, lean

__all__ = [
    "INACTIVE",
    "QP",
    "BranchAndBound",
    "Disjunction",
    "Enumeration",
    "PiqpQP",
    "QPResult",
    "MIQPResult",
    "CscPattern",
]


def _piqp_build():
    """piqp's extension built for AVX2 where the CPU has it, else its generic one.

    piqp itself picks its AVX-512 build on CPUs that have AVX-512. Each build rounds
    differently, and a QP's last bits decide some plans: the same case then gives another
    row on such a machine (docs/evaluation.md). So every x86-64 CPU with AVX2, AVX-512
    ones included, runs one build: the AVX2 one, which reproduced the committed grid rows
    checked on 2026-12-03 (all but 8 of 1,500, which another build most likely made)."""
    import importlib

    from piqp import instruction_set

    return importlib.import_module("piqp.piqp_python_avx2" if instruction_set.avx2 else "piqp.piqp_python")


PIQP = _piqp_build()


@dataclass(eq=False)
class QP:
    """``row_slacks``: the last ``G.shape[0]`` variables are the rows' slacks, one each, in
    G's row order, absent from P and A, bounded below by 0 and priced by ``c`` >= 0 (the
    planner's soft rows). A switched-off row's slack is then 0 at the optimum, and the
    solver drops both (``lean``): the same optimum from a smaller QP."""

    P: sp.csc_matrix
    c: np.ndarray
    A: sp.csc_matrix
    b: np.ndarray
    G: sp.csc_matrix
    h_l: np.ndarray
    h_u: np.ndarray
    x_l: np.ndarray
    x_u: np.ndarray
    row_slacks: bool = False


@dataclass(frozen=True)
class QPResult:
    x: np.ndarray | None
    obj: float
    status: str  # "solved", "infeasible", "failed"
    iterations: int
    solve_time_s: float


@dataclass(frozen=True)
class Disjunction:
    """At least one of these G rows must be active (row >= its h_l)."""

    rows: tuple[int, ...]


@dataclass(frozen=True)
class MIQPResult:
    x: np.ndarray | None
    obj: float
    status: str  # "solved", "infeasible", "node_limit", "time_limit", "budget"
    nodes: int
    qp_solves: int
    assignment: tuple[int, ...]  # chosen row per disjunction (-1: satisfied unforced)
    solve_time_s: float


class CscPattern:
    """A fixed CSC sparsity pattern given as (row, col) triplets, duplicates summed.

    Sorting the pattern is done once; ``matrix`` only scatters new triplet values into
    it, so that every QP of a problem shape shares one pattern (piqp then refills).
    """

    def __init__(self, rows, cols, shape: tuple[int, int]):
        rows, cols = np.asarray(rows, np.int64), np.asarray(cols, np.int64)
        if len(rows) and (rows.min() < 0 or rows.max() >= shape[0] or cols.min() < 0 or cols.max() >= shape[1]):
            raise ValueError(f"triplets: indices outside the shape {shape}")
        keys, self._pos = np.unique(cols * shape[0] + rows, return_inverse=True)
        self.shape = shape
        self.nnz = len(keys)
        self.indices = (keys % shape[0]).astype(np.int32)
        self.indptr = np.concatenate(([0], np.cumsum(np.bincount(keys // shape[0], minlength=shape[1])))).astype(
            np.int32
        )

    def matrix(self, vals, shape: tuple[int, int] | None = None) -> sp.csc_matrix:
        """The matrix with these triplet values; ``shape`` may add empty rows and columns."""
        data = np.bincount(self._pos, weights=vals, minlength=self.nnz)
        rows, cols = shape or self.shape
        indptr = self.indptr
        if cols > self.shape[1]:
            indptr = np.concatenate((indptr, np.full(cols - self.shape[1], indptr[-1], np.int32)))
        return sp.csc_matrix((data, self.indices, indptr), shape=(rows, cols))


def _same_pattern(a: sp.csc_matrix | None, b: sp.csc_matrix | None) -> bool:
    if a is None or b is None or a is b:
        return a is b
    return (
        a.shape == b.shape
        and a.nnz == b.nnz
        and np.array_equal(a.indptr, b.indptr)
        and np.array_equal(a.indices, b.indices)
    )


class PiqpQP:
    """piqp's sparse solver; sets up on a new sparsity pattern, otherwise only refills.
    Each QP is solved without its switched-off rows (``lean``)."""

    KKT_SOLVERS = ("sparse_ldlt", "sparse_multistage", "auto")
    MULTISTAGE_MAX_ROWS = 16  # "auto": multistage up to this many G rows (each has a global slack)

    def __init__(
        self,
        eps_abs: float = 1e-6,
        eps_rel: float = 1e-7,
        max_iter: int = 200,
        kkt_solver: str = "sparse_ldlt",
        eps_gap: tuple[float, float] | None = None,
    ):
        """``kkt_solver``: piqp's; ``sparse_multistage`` exploits variables ordered stage by
        stage, but treats trailing coupling variables (the planner's slacks) as dense: "auto"
        takes it only for QPs with few G rows (measured: ~1.5 s with 800 slacks).
        ``eps_gap``: (abs, rel) duality-gap tolerances; None keeps piqp's (1e-8, 1e-9)."""
        if kkt_solver not in self.KKT_SOLVERS:
            raise ValueError(f"kkt_solver: must be one of {self.KKT_SOLVERS}, got {kkt_solver!r}")
        for name, v in (("eps_abs", eps_abs), ("eps_rel", eps_rel), *zip(("eps_gap[0]", "eps_gap[1]"), eps_gap or ())):
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"{name}: must be a finite number > 0, got {v!r}")
        self.eps_abs, self.eps_rel, self.max_iter = eps_abs, eps_rel, max_iter
        self.kkt_solver = kkt_solver
        self.eps_gap = eps_gap
        self._solver: piqp.SparseSolver | None = None
        self._last: QP | None = None
        self.setups = 0
        self.updates = 0

    def _new_solver(self, g_rows: int) -> piqp.SparseSolver:
        s = PIQP.SparseSolver()
        s.settings.eps_abs = self.eps_abs
        s.settings.eps_rel = self.eps_rel
        s.settings.max_iter = self.max_iter
        s.settings.verbose = False
        if self.eps_gap is not None:
            s.settings.eps_duality_gap_abs, s.settings.eps_duality_gap_rel = self.eps_gap
        kkt = self.kkt_solver
        if kkt == "auto":
            kkt = "sparse_multistage" if g_rows <= self.MULTISTAGE_MAX_ROWS else "sparse_ldlt"
        s.settings.kkt_solver = getattr(PIQP, kkt)
        return s

    def solve(self, qp: QP) -> QPResult:
        t0 = time.perf_counter()
        n = qp.P.shape[0]
        qp, cols = lean(qp)
        for name in ("P", "A", "G"):  # piqp misreads CSC with duplicates or unsorted indices
            m = getattr(qp, name)
            if not m.has_canonical_format:
                m = m.copy()
                m.sum_duplicates()
                setattr(qp, name, m)
        last = self._last
        if (
            self._solver is None
            or last is None
            or not (_same_pattern(last.P, qp.P) and _same_pattern(last.A, qp.A) and _same_pattern(last.G, qp.G))
        ):
            self._solver = self._new_solver(qp.G.shape[0])
            self._solver.setup(qp.P, qp.c, qp.A, qp.b, qp.G, qp.h_l, qp.h_u, qp.x_l, qp.x_u)
            self.setups += 1
        else:
            changed = {}
            for name in ("P", "A", "G"):
                new, old = getattr(qp, name), getattr(last, name)
                if new is not old and not np.array_equal(new.data, old.data):
                    changed[name] = new
            for name in ("c", "b", "h_l", "h_u", "x_l", "x_u"):
                new, old = getattr(qp, name), getattr(last, name)
                if new is not old and not np.array_equal(new, old):
                    changed[name] = new
            if "h_l" in changed or "h_u" in changed:
                changed.update(h_l=qp.h_l, h_u=qp.h_u)  # piqp wants both sides together
            if changed:
                self._solver.update(**changed)
            self.updates += 1
        self._last = replace(qp)  # a snapshot: callers may reassign qp's fields later
        status = self._solver.solve()
        r = self._solver.result
        name = str(status).split(".")[-1]
        if name == "PIQP_SOLVED":
            x = np.array(r.x)
            if cols is not None:
                x, part = np.zeros(n), x
                x[cols] = part
            return QPResult(x, float(r.info.primal_obj), "solved", int(r.info.iter), time.perf_counter() - t0)
        st = "infeasible" if "INFEASIBLE" in name else "failed"
        return QPResult(None, math.inf, st, int(r.info.iter), time.perf_counter() - t0)


def _slack(qp: QP, x: np.ndarray, active_l: np.ndarray) -> np.ndarray:
    """G x - active lower bounds (>= 0 where a row holds)."""
    return qp.G @ x - active_l


class BranchAndBound:
    """Depth-first branch-and-bound over disjunctions, each node a QP.

    A node fixes one alternative for some disjunctions (their rows active). Its QP
    relaxes the rest (rows inactive), so its cost bounds every completion from below.
    Disjunctions already satisfied by a node's solution are not branched on; the most
    violated one is, children ordered by how close each alternative already is.
    """

    def __init__(
        self, qp_backend: PiqpQP | None = None, node_limit: int = 400, time_limit_s: float = 1.0, tol: float = 1e-5
    ):
        if node_limit < 1:
            raise ValueError(f"node_limit: must be >= 1 (the root is a node), got {node_limit}")
        self.qp_backend = qp_backend or PiqpQP()
        self.node_limit = node_limit
        self.time_limit_s = time_limit_s
        self.tol = tol

    def solve(
        self,
        qp: QP,
        disjunctions: list[Disjunction],
        active_bounds: np.ndarray,
        preferred: list[int] | None = None,
        max_solves: int | None = None,
    ) -> MIQPResult:
        """``active_bounds[r]``: row r's lower bound when active; ``qp.h_l`` holds ``INACTIVE`` there.

        ``preferred`` (one row per disjunction) seeds the search: where the root relaxation
        does not already satisfy every disjunction, that full assignment is solved next, and
        a feasible result is the first incumbent. (A root that satisfies them all is the
        optimum: solving the seed first would only cost a QP, measured in a third of the
        planner's MIQPs.) ``max_solves``: at most this many QP solves (>= 1; status
        "budget" where it stopped the search), the caller's work budget.
        """
        cap = math.inf if max_solves is None else max_solves
        t0 = time.perf_counter()
        base_l = qp.h_l.copy()
        best_x, best_obj, best_assign = None, math.inf, ()
        status = "solved"
        # Each disjunction's rows, end to end: a node's best alternative per disjunction is
        # one reduction over them.
        alt_rows = np.array([r for d in disjunctions for r in d.rows], np.int64)
        firsts = np.cumsum([0] + [len(d.rows) for d in disjunctions[:-1]])
        pref = set(preferred or ())

        def relax(assign: tuple[int, ...]) -> QPResult:
            chosen = np.array(assign, np.int64)  # per disjunction its row, or -1: open
            fixed = chosen[chosen >= 0]
            h_l = base_l.copy()
            h_l[fixed] = active_bounds[fixed]
            qp.h_l = h_l
            return self.qp_backend.solve(qp)

        def worst_open(assign: tuple[int, ...], x: np.ndarray) -> tuple[int, np.ndarray]:
            """The most violated open disjunction (its best alternative below -tol; the
            first of equals), or -1: a feasible leaf; with the rows' slacks."""
            slack = qp.G @ x - active_bounds
            best_alt = np.maximum.reduceat(slack[alt_rows], firsts) if disjunctions else np.zeros(0)
            open_ = (np.array(assign, np.int64) < 0) & (best_alt < -self.tol)
            return (int(np.argmin(np.where(open_, best_alt, np.inf))) if open_.any() else -1), slack

        root_assign = tuple([-1] * len(disjunctions))
        root = relax(root_assign)
        nodes = solves = 1
        if root.x is None:
            qp.h_l = base_l  # it relaxes every assignment: none is feasible
            return MIQPResult(None, math.inf, "infeasible", nodes, solves, (), time.perf_counter() - t0)
        root_split = worst_open(root_assign, root.x)
        if root_split[0] < 0:
            qp.h_l = base_l
            return MIQPResult(root.x, root.obj, "solved", nodes, solves, root_assign, time.perf_counter() - t0)
        if preferred is not None and solves < cap:
            res = relax(tuple(preferred))
            solves += 1
            if res.x is not None:
                best_x, best_obj, best_assign = res.x, res.obj, tuple(preferred)
        stack: list[tuple[int, ...]] = []

        def visit(assign: tuple[int, ...], res: QPResult, split: tuple[int, np.ndarray] | None = None) -> None:
            """Bound the node out, take it as a leaf, or branch on its worst open disjunction."""
            nonlocal best_x, best_obj, best_assign
            if res.x is None or res.obj >= best_obj - 1e-9:
                return  # infeasible or bounded out
            worst_j, slack = split or worst_open(assign, res.x)
            if worst_j < 0:
                best_x, best_obj, best_assign = res.x, res.obj, assign
                return
            for r in sorted(disjunctions[worst_j].rows, key=lambda r: (r in pref, slack[r])):  # best popped first
                child = list(assign)
                child[worst_j] = r
                stack.append(tuple(child))

        visit(root_assign, root, root_split)
        while stack:
            stop = self._out_of(nodes, solves, cap, t0)
            if stop:
                status = stop
                break
            assign = stack.pop()
            nodes += 1
            solves += 1
            visit(assign, relax(assign))
        qp.h_l = base_l
        if best_x is None and status == "solved":
            status = "infeasible"
        return MIQPResult(best_x, best_obj, status, nodes, solves, best_assign, time.perf_counter() - t0)

    def _out_of(self, nodes: int, solves: int, cap: float, t0: float) -> str | None:
        """What the search has run out of, if anything: nodes, the caller's solves, or time."""
        if nodes >= self.node_limit:
            return "node_limit"
        if solves >= cap:
            return "budget"
        if time.perf_counter() - t0 > self.time_limit_s:
            return "time_limit"
        return None


class Enumeration:
    """Solves every full assignment of alternatives; exponential, for tests and checks."""

    def __init__(self, qp_backend: PiqpQP | None = None):
        self.qp_backend = qp_backend or PiqpQP()

    def solve(
        self, qp: QP, disjunctions: list[Disjunction], active_bounds: np.ndarray, preferred: list[int] | None = None
    ) -> MIQPResult:
        t0 = time.perf_counter()
        base_l = qp.h_l.copy()
        best_x, best_obj, best_assign, solves = None, math.inf, (), 0
        for assign in itertools.product(*(d.rows for d in disjunctions)):
            h_l = base_l.copy()
            h_l[list(assign)] = active_bounds[list(assign)]
            qp.h_l = h_l
            res = self.qp_backend.solve(qp)
            solves += 1
            if res.x is not None and res.obj < best_obj:
                best_x, best_obj, best_assign = res.x, res.obj, assign
        qp.h_l = base_l
        return MIQPResult(
            best_x,
            best_obj,
            "solved" if best_x is not None else "infeasible",
            solves,
            solves,
            best_assign,
            time.perf_counter() - t0,
        )
