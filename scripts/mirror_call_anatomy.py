"""Where the default planner's calls spend their work: a diagnostic, not a benchmark.

    python scripts/mirror_call_anatomy.py [--sample smoke] [--step 3] [--set key=JSON ...]

Runs ``mirror`` (``MirrorPlannerConfig`` with the ``--set`` changes) on every ``step``-th
case of a sample, in this process, and reports per planning call: what made the policy
call (the first call, the car standing at the end of its plan, the plan run out, a drift,
a retry after a failure), the candidate solves and QP solves of scouting and of the
full budget (the leader's refinement and the retries), what branch and bound bought over
the assignment it starts from (each point behind the face its reference lies behind), and
whether the candidate that scouting picks was already the cheapest after the seed or after
one or two SCP rounds (J of each rollout with a price on penetration). A candidate solve
(SCP rounds with Algorithm I and branch and bound toward one goal) is the unit the paper
times as one plan; its median and p95 wall time are printed beside the counts. Counts do
not depend on the machine; the times printed do.

It wraps a few of the planner's methods for the run (it reads, never changes, what they
return), so it lives here and not in the package.
"""

from __future__ import annotations

import argparse
import functools
import json
import math
import time

import numpy as np

from evaluation import registry
from evaluation.cases import from_sample
from evaluation.runner import run_case
from planners.common.slot_frame import InSlotFrame
from planners.mirror import planner as mp
from planners.mirror import policy as mpol
from planners.mirror import solvers
from planners.mirror import value_plan as vp
from planners.mirror.config import MirrorPlannerConfig
from planners.mirror.policy import MirrorPolicy

calls: list[dict] = []  # one per planning call
bnb: list[dict] = []  # one per branch-and-bound run
_call: dict | None = None
_trace: list[float] | None = None


def _wrap(cls, name, wrapper):
    orig = getattr(cls, name)
    setattr(cls, name, functools.wraps(orig)(lambda *a, **k: wrapper(orig, *a, **k)))


def _act(orig, self, obs, info):
    s = info["vehicle_state"]
    if self.plan is None:
        why = "first" if not self.stats else "after a failure"
    elif self.k >= len(self.plan.commands):
        why = "plan ran out"
    elif self._drifted(s):
        why = "drift"
    elif self._idle(s):
        why = "stood at its plan's end"
    else:
        why = None
    n = len(self.stats)
    out = orig(self, obs, info)
    if len(self.stats) > n and calls and calls[-1].get("why") is None:
        st = self.stats[-1]
        calls[-1].update(why=why, ms=1e3 * st.wall_time_s, qps=st.qp_solves, moving=abs(s.v) > mpol.IDLE_SPEED)
    return out


def _plan(orig, self, *a):
    global _call
    _call = {"vp": self, "solves": [], "why": None}
    try:
        return orig(self, *a)
    finally:
        calls.append(_call)


def _solve(orig, self, cand, goal, seed, miqp):
    global _trace
    _trace = []
    q0, r0 = self.totals["qp_solves"], self.totals["iterations"]
    t0 = time.perf_counter()
    out = orig(self, cand, goal, seed, miqp)
    ms = 1e3 * (time.perf_counter() - t0)
    scouting = miqp is self.pl.scout_miqp
    _call["solves"].append(
        dict(
            scouting=scouting,
            qps=self.totals["qp_solves"] - q0,
            rounds=self.totals["iterations"] - r0,
            j=out[0],
            ms=ms,
            trace=_trace,
        )
    )
    _trace = None
    return out


def _score(orig, self, real, *a):
    out = orig(self, real, *a)
    if _trace is not None and _call is not None:
        _trace.append(_call["vp"]._seed_merit(real))
    return out


class _Counting:
    """A QP backend that records each solve's objective (inf: no solution)."""

    def __init__(self, inner):
        self.inner, self.objs = inner, []

    def solve(self, qp):
        r = self.inner.solve(qp)
        self.objs.append(r.obj if r.x is not None else math.inf)
        return r


def _bnb(orig, self, qp, disj, active, preferred=None):
    inner, spy = self.qp_backend, _Counting(self.qp_backend)
    self.qp_backend = spy
    try:
        r = orig(self, qp, disj, active, preferred)
    finally:
        self.qp_backend = inner
    o = np.array(spy.objs)
    found = int(np.flatnonzero(o == r.obj)[0]) if r.x is not None and np.isfinite(r.obj) else -1
    # The root (every disjunction open) is solve 0; where it leaves one violated, the
    # reference's sides are solve 1.
    pref = o[1] if preferred is not None and len(o) > 1 else math.inf
    gain = (pref - r.obj) / max(1.0, abs(pref)) if np.isfinite(pref) and np.isfinite(r.obj) else math.nan
    bnb.append(dict(limit=self.node_limit, disj=len(disj), status=r.status, qps=r.qp_solves, found=found, gain=gain))
    return r


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sample", default="smoke")
    ap.add_argument("--step", type=int, default=3)
    ap.add_argument("--set", nargs="*", default=[], metavar="KEY=JSON", help="MirrorPlannerConfig changes")
    args = ap.parse_args()
    changes = {k: json.loads(v) for k, v in (a.split("=", 1) for a in args.set)}
    cfg = MirrorPlannerConfig(**changes)  # validated here, before any case runs
    registry.PLANNERS["mirror-anatomy"] = lambda: InSlotFrame(MirrorPolicy(cfg))
    _wrap(MirrorPolicy, "act", _act)
    _wrap(vp.ValuePlanning, "plan", _plan)
    _wrap(vp._Call, "solve", _solve)
    _wrap(mp.MirrorPlanner, "_score", _score)
    _wrap(solvers.BranchAndBound, "solve", _bnb)

    rows = [run_case("mirror-anatomy", sc) for sc in from_sample(args.sample)[:: args.step]]
    ok = [r for r in rows if r["success"]]
    errors = [r["error"] for r in rows if r.get("error")]
    print(
        f"{len(rows)} cases: {100 * len(ok) / len(rows):.1f} % parked, {sum(r['collision'] for r in rows)} collisions, "
        f"{np.mean([r['switches'] for r in ok]) if ok else math.nan:.2f} switches where parked, {len(errors)} errors"
    )
    ms = np.array([c["ms"] for c in calls if "ms" in c])
    qps = np.array([c["qps"] for c in calls if "qps" in c])
    print(
        f"{len(calls)} calls: {np.median(ms):.0f} / {np.percentile(ms, 95):.0f} ms (median / p95, this machine now), "
        f"QP solves {np.median(qps):.0f} / {np.percentile(qps, 95):.0f}, "
        f"{sum(c.get('moving', False) for c in calls)} from a moving car"
    )
    print("why the policy called:")
    for why in sorted({c.get("why") for c in calls}, key=str):
        cs = [c for c in calls if c.get("why") == why]
        print(f"  {why}: {len(cs)} calls, QP solves median {np.median([c['qps'] for c in cs]):.0f}")
    solves = [s for c in calls for s in c["solves"]]
    print(f"candidate solves per call: median {np.median([len(c['solves']) for c in calls]):.0f}")
    for label, flag in (("scouting", True), ("full budget (refinement, retries)", False)):
        ss = [s for s in solves if s["scouting"] is flag]
        solve_ms = [s["ms"] for s in ss]
        times = f"{np.median(solve_ms):.1f} / {np.percentile(solve_ms, 95):.1f} ms per solve" if ss else "no solves"
        print(
            f"  {label}: {len(ss)} solves, {sum(s['rounds'] for s in ss)} SCP rounds, "
            f"{sum(s['qps'] for s in ss)} QP solves, {times}"
        )
    print(
        "branch and bound (found: the solve that gave the incumbent; 0 = the root relaxation, 1 = the reference's"
        " sides; gain: what it saved against the reference's sides, relative, where the root did not end it):"
    )
    for limit in sorted({b["limit"] for b in bnb}):
        for status in sorted({b["status"] for b in bnb if b["limit"] == limit}):
            bs = [b for b in bnb if b["limit"] == limit and b["status"] == status]
            f = np.array([b["found"] for b in bs])
            g = np.array([b["gain"] for b in bs], float)
            g = g[np.isfinite(g)]
            gains = f"median {np.median(g):.1e}, p90 {np.percentile(g, 90):.1e}" if len(g) else "n/a"
            print(
                f"  {limit} nodes, {status}: {len(bs)} runs, {sum(b['qps'] for b in bs)} QP solves, "
                f"disjunctions median {np.median([b['disj'] for b in bs]):.0f}, found at quartiles "
                f"{np.percentile(f, [25, 50, 75]).tolist()}, "
                f"ended at the root {int((f == 0).sum())}, gain over the reference's sides {gains}"
            )
    ranks: dict[int, list[int]] = {0: [], 1: [], 2: []}
    for c in calls:
        sc = [s for s in c["solves"] if s["scouting"] and s["trace"]]
        j = np.array([s["j"] for s in sc])
        if len(sc) < 2 or not np.isfinite(j).any():
            continue
        w = int(np.argmin(j))
        for r in ranks:
            proxy = np.array([s["trace"][min(r, len(s["trace"]) - 1)] for s in sc])
            ranks[r].append(int((proxy < proxy[w]).sum()))
    print(f"the scouting winner's rank among its call's candidates ({len(ranks[0])} calls with two or more):")
    for r, v in ranks.items():
        v = np.array(v)
        print(
            f"  after {'the seed' if r == 0 else f'SCP round {r}'}: first {int((v == 0).sum())}, "
            f"second {int((v == 1).sum())}, lower {int((v >= 2).sum())}"
        )


if __name__ == "__main__":
    main()
