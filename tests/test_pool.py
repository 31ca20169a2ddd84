"""Worker processes start safely whatever the parent's other threads hold."""

from __future__ import annotations

import os
import signal
import threading
import time

import numpy as np
import pytest

from evaluation import registry
from evaluation.pool import _pool_context, batches, run_parallel
from evaluation.runner import evaluate
from evaluation.store import read_results
from mirrorpark_env import Scenario
from planners.base import Policy

CASES = ("reverse_rw6.00_sl4.82_sw2.32_th+40_y3.00", "angle_rw3.50_sl4.82_sw2.77_th+10_y1.30")
_LOCK = threading.Lock()  # module-level, like a logging or I/O lock a library keeps


class _Locking(Policy):
    """Takes the module's lock once per episode, then stops at once."""

    def reset(self, geometry):
        with _LOCK:
            self.gave_up = True

    def act(self, obs, info):
        return np.zeros(2, dtype=np.float32)


def test_a_lock_held_by_another_thread_does_not_hang_the_workers(tmp_path, monkeypatch):
    """A fork would copy the lock held for good (the hang once seen in CI); workers start clean."""
    monkeypatch.setitem(registry.PLANNERS, "locking", _Locking)
    release, held = threading.Event(), threading.Event()

    def hold() -> None:
        with _LOCK:
            held.set()
            release.wait(120)

    t = threading.Thread(target=hold, daemon=True)
    t.start()
    held.wait(10)
    ctx, extra = _pool_context()
    assert ctx.get_start_method() == "forkserver" and extra == {"locking": _Locking}
    hung = threading.Event()

    def stop() -> None:  # a hang becomes a failure here, not a stuck test run
        hung.set()
        os.kill(os.getpid(), signal.SIGINT)

    done = threading.Timer(60, stop)
    done.start()
    try:
        evaluate("locking", [Scenario.from_case_id(c) for c in CASES], tmp_path, workers=2, progress=False)
    except KeyboardInterrupt:
        if not hung.is_set():
            raise
        pytest.fail("the workers waited 60 s for a lock the parent's other thread held")
    finally:
        release.set()
        done.cancel()
        t.join()
    df = read_results([tmp_path])
    assert sorted(df["case_id"]) == sorted(CASES) and df["error"].isna().all()


def test_batches_keep_order_and_cut_at_each_new_group_and_at_the_batch_size():
    items = ["a1", "a2", "a3", "b1", "a4", "c1", "c2"]
    assert batches(items, lambda it: it[0], batch=2) == [["a1", "a2"], ["a3"], ["b1"], ["a4"], ["c1", "c2"]]
    assert batches(items) == [[it] for it in items]
    with pytest.raises(ValueError, match="batch: must be >= 1"):
        batches(items, lambda it: it[0], batch=0)


def _pid_after_a_while(item):
    time.sleep(0.05)  # long enough that both workers take items
    return item, os.getpid()


def test_a_groups_items_run_in_one_worker_and_each_runs_once():
    """What a planner builds once per slot is then built once, not once per worker."""
    items = [(g, k) for g in range(6) for k in range(3)]
    got = []
    run_parallel(_pid_after_a_while, items, got.append, workers=2, group=lambda it: it[0], batch=3)
    assert sorted(item for item, _ in got) == items
    pid = dict(got)
    assert all(pid[(g, 0)] == pid[(g, 1)] == pid[(g, 2)] for g in range(6))
    assert len(set(pid.values())) == 2


def _waits_for_the_parent(item):
    """Item k > 0 waits (10 s at most) until the parent has kept item k - 1."""
    k, folder = item
    if k == 0:
        return k, True
    flag = os.path.join(folder, f"kept{k - 1}")
    for _ in range(200):
        if os.path.exists(flag):
            return k, True
        time.sleep(0.05)
    return k, False


def test_each_result_reaches_the_parent_before_its_run_ends(tmp_path):
    """So an interruption loses only the items in progress, not a run's finished ones."""
    items = [(k, str(tmp_path)) for k in range(3)]
    got = []

    def keep(out):
        got.append(out)
        (tmp_path / f"kept{out[0]}").touch()

    run_parallel(_waits_for_the_parent, items, keep, workers=2, group=lambda it: "one slot", batch=3)
    assert got == [(0, True), (1, True), (2, True)]


def _fails_on_one(item):
    if item == 1:
        raise ValueError("item 1 is bad")
    return item


def test_an_items_failure_reaches_the_parent_as_itself():
    kept = []
    with pytest.raises(ValueError, match="item 1 is bad"):
        run_parallel(_fails_on_one, [0, 1, 2, 3], kept.append, workers=2, group=lambda it: it // 2, batch=2)
    assert 0 in kept and 1 not in kept


def test_workers_are_replaced_after_their_runs_and_every_item_runs_once(monkeypatch):
    """A worker retires after ``_RUNS_PER_WORKER`` runs (what a long run leaks, it frees); the
    run goes on in a fresh one, losing and repeating nothing."""
    from evaluation import pool

    monkeypatch.setattr(pool, "_RUNS_PER_WORKER", 2)
    items = [(k, 0) for k in range(10)]
    got = []
    run_parallel(_pid_after_a_while, items, got.append, workers=2)
    assert sorted(item for item, _ in got) == items
    assert len({pid for _, pid in got}) >= 4  # ten runs of one item, two per worker
