"""Run a planner over cases: one row per (case, planner), locally on all cores or on Ray.

A case that raises becomes an error row carrying its message, and the run goes on.
Rows are appended to the store as they finish; a rerun over the same folder resumes.
"""

from __future__ import annotations

import ctypes
import dataclasses
import multiprocessing as mp
import os
import pickle
import signal
import sys
from collections.abc import Callable, Hashable, Iterable
from multiprocessing.connection import wait
from pathlib import Path
from typing import Any

from tqdm import tqdm

from mirrorpark_env.layout import Layout
from mirrorpark_env.scenario import Scenario

from . import registry
from .call_limit import CALL_LIMIT_S
from .episode import run_case, worker_env
from .provenance import check_resume
from .registry import make_policy
from .store import ResultStore, check_columns, locked

__all__ = ["WorkerDied", "evaluate", "run_case", "run_parallel", "slot_of", "unique", "worker_env"]


def unique(scenarios: Iterable[Scenario]) -> tuple[list[Scenario], int]:
    """The scenarios in order with repeats (same id) dropped, and how many were dropped. Two
    grid cases that share an id but differ (by less than the ids' precision) are refused,
    both named: one would silently stand for the other."""
    out, seen, objects, n_in = [], {}, {}, 0
    for sc in scenarios:
        n_in += 1
        if id(sc) in objects:  # the very object again (a case file's repeated rows): nothing to check
            continue
        objects[id(sc)] = sc  # held, so that no other object takes its id
        first = seen.get(sc.case_id)  # a Scenario's or a Layout's
        if first is None:
            seen[sc.case_id] = sc
            out.append(sc)
        elif isinstance(sc, Scenario) and sc != first:
            differ = "; ".join(
                f"{f.name} {getattr(first, f.name)!r} and {getattr(sc, f.name)!r}"
                for f in dataclasses.fields(sc)
                if getattr(first, f.name) != getattr(sc, f.name)
            )
            raise ValueError(
                f"cases: two share the id {sc.case_id} but differ ({differ}): ids keep 1e-9; give each once"
            )
    return out, n_in - len(out)


def _run_case_tuple(args: tuple[str, Scenario, bool, float | None]) -> dict[str, Any]:
    planner, sc, trajectory, call_limit_s = args
    return run_case(planner, sc, trajectory=trajectory, call_limit_s=call_limit_s)


def evaluate(
    planner: str,
    scenarios: Iterable[Scenario],
    out: str | Path,
    workers: int | None = None,
    backend: str = "local",
    ray_address: str | None = None,
    progress: bool = True,
    mixed_code: bool = False,
    trajectories: bool = False,
    call_limit_s: float | None = CALL_LIMIT_S,
) -> ResultStore:
    """Run ``planner`` over ``scenarios`` into the store at ``out``; resume where it stopped,
    if its rows of ``planner`` came from this code (``provenance.check_resume``; ``mixed_code``:
    whatever code they came from). ``trajectories``: rows keep the driven trajectory (layout
    rows always do). ``call_limit_s``: the wall-clock safety net per planner call
    (``call_limit.py``; None or 0: none); a call past it ends its case as an error row."""

    make_policy(planner)  # an unknown planner fails now, not in every worker
    if backend not in ("local", "ray"):
        raise ValueError(f"backend: must be 'local' or 'ray', got {backend!r}")
    workers = (os.cpu_count() or 1) if workers is None else workers
    if workers < 1:
        raise ValueError(f"workers: must be >= 1, got {workers}")
    if call_limit_s is not None and not call_limit_s >= 0:
        raise ValueError(f"call_limit_s: seconds >= 0 (0: none), got {call_limit_s}")
    store = ResultStore(out)
    with locked(store.folder):  # one run per results folder at a time
        stored = store.table()
        if len(stored):  # a folder of some other tool's table: refused before anything runs
            check_columns(stored, store.parquet if store.parquet.exists() else store.folder)
        _run_into(
            store, planner, scenarios, workers, backend, ray_address, progress, mixed_code, trajectories, call_limit_s
        )
    return store


def _run_into(
    store: ResultStore,
    planner: str,
    scenarios: Iterable[Scenario],
    workers: int,
    backend: str,
    ray_address: str | None,
    progress: bool,
    mixed_code: bool,
    trajectories: bool = False,
    call_limit_s: float | None = CALL_LIMIT_S,
) -> None:
    """``evaluate``'s run, the folder locked: the cases not yet stored, their rows appended."""

    done = store.done()
    check_resume(store.environments(), planner, sum(p == planner for p, _ in done), store.folder, mixed_code)
    todo = [sc for sc in unique(scenarios)[0] if (planner, sc.case_id) not in done]
    if todo:
        store.record_environment(planner, len(todo))
    bar = progress_bar(len(todo), f"{planner}", progress, initial=0)
    stored = 0

    def keep(row: dict[str, Any]) -> None:
        nonlocal stored
        store.append(row)
        stored += 1
        bar.update(1)

    try:
        if backend == "ray":
            _run_ray(planner, todo, keep, ray_address, workers, trajectories, call_limit_s)
        elif min(workers, len(todo)) <= 1:  # no processes to start for one case
            for sc in todo:
                keep(run_case(planner, sc, trajectory=trajectories, call_limit_s=call_limit_s))
        else:
            items = [(planner, sc, trajectories, call_limit_s) for sc in todo]
            run_parallel(
                _run_case_tuple,
                items,
                keep,
                workers,
                group=lambda it: slot_of(it[1]),
                describe=lambda it: it[1].case_id,
            )
    except (KeyboardInterrupt, WorkerDied) as err:
        bar.close()
        store.compact()
        left = len(todo) - stored
        where = f"{len(store.done())} cases stored in {store.folder}, {left} not run; rerun the same command to resume"
        if isinstance(err, WorkerDied):
            raise WorkerDied(f"{err}; {where}") from None
        raise KeyboardInterrupt(where) from None
    finally:
        bar.close()
    store.compact()


def _worker_signals() -> None:
    """Workers leave Ctrl-C to the parent, which stops them and keeps what is stored, and
    die at SIGTERM, which is how the parent stops them (a forked worker would otherwise
    inherit the command line's SIGTERM handler)."""

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    if sys.platform.startswith("linux"):  # die with the parent, however it dies: SIGKILL leaves it no clean-up
        PR_SET_PDEATHSIG = 1
        ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, signal.SIGKILL)


class WorkerDied(RuntimeError):
    """A worker process ended while it ran an item (killed, out of memory, ``os._exit``)."""


def run_parallel(
    fn: Callable[[Any], Any],
    items: list,
    keep: Callable[[Any], None],
    workers: int,
    group: Callable[[Any], Hashable] | None = None,
    batch: int = 8,
    describe: Callable[[Any], str] = repr,
) -> None:
    """``keep(fn(item))`` for every item, in ``workers`` processes, as each finishes.

    ``fn`` must be a module-level function (it is pickled for the workers); no more workers
    start than there are items. ``group(item)`` (optional) names what items may share: items
    of one group, in the order given, go to one worker in runs of up to ``batch``, so that
    what a planner builds once per slot (``planners.common.slot_cache``) is built once per
    run, not once in every worker that meets the slot. Results do not change, only the
    work. Each item's result comes back as soon as it is done, not with its run: an
    interruption loses only the items in progress.

    A worker that dies while it runs an item stops the run within about a second with
    ``WorkerDied``, naming the item (``describe(item)``); an item whose ``fn`` raises stops
    it with that exception (one that is not an ``Exception``, such as ``SystemExit``, as a
    ``RuntimeError`` saying so). Either way every worker is stopped before this returns.
    """
    runs = [
        list(run) for run in batches(list(enumerate(items)), None if group is None else lambda it: group(it[1]), batch)
    ]
    if not runs:
        return
    ctx, extra = _pool_context()
    todo = list(reversed(runs))  # popped from the end: in order
    pool: list[_Worker] = []
    left = len(items)
    try:
        for _ in range(min(workers, len(runs))):
            pool.append(_Worker.start(ctx, fn, extra))
            pool[-1].give(todo.pop())
        while left:
            ready = wait([w.conn for w in pool] + [w.proc.sentinel for w in pool], timeout=1.0)
            for w in list(pool):
                if w.conn not in ready and w.proc.sentinel not in ready:
                    continue
                for msg in w.messages():
                    kind = msg[0]
                    if kind == "done":
                        keep(msg[2])
                        left -= 1
                    elif kind == "error":
                        raise msg[2]
                    elif kind == "idle":
                        w.runs_done += 1
                        w.run = None
                        if w.runs_done >= _RUNS_PER_WORKER and todo:  # a fresh process now and then
                            w.stop()
                            pool[pool.index(w)] = w = _Worker.start(ctx, fn, extra)
                        if todo:
                            w.give(todo.pop())
                if not w.proc.is_alive() and w.run is not None:
                    w.proc.join(1.0)
                    item = items[w.current] if w.current is not None else None
                    what = describe(item) if item is not None else "a run of items"
                    raise WorkerDied(
                        f"a worker process (PID {w.proc.pid}) died ({_exit_name(w.proc.exitcode)}) while running {what}"
                    )
    finally:
        for w in pool:
            w.stop()


_RUNS_PER_WORKER = 200  # a worker is replaced after this many runs (what a long run leaks, it frees)


class _Worker:
    """One worker process, its end of a pipe, the run it was given and the item in hand."""

    def __init__(self, proc, conn) -> None:
        self.proc, self.conn = proc, conn
        self.run: list | None = None
        self.current: int | None = None
        self.runs_done = 0

    @classmethod
    def start(cls, ctx, fn, extra) -> _Worker:
        mine, theirs = ctx.Pipe()
        proc = ctx.Process(target=_worker_main, args=(theirs, fn, extra), daemon=True)
        proc.start()
        theirs.close()
        return cls(proc, mine)

    def give(self, run: list) -> None:
        self.run = run
        self.conn.send(run)

    def messages(self) -> list[tuple]:
        """What the worker has sent so far (all of it, once it has ended)."""
        out = []
        try:
            while self.conn.poll():
                msg = self.conn.recv()
                if msg[0] == "start":
                    self.current = msg[1]
                else:
                    if msg[0] == "done":
                        self.current = None
                    out.append(msg)
        except (EOFError, OSError):  # the worker is gone; its sentinel says so
            pass
        return out

    def stop(self) -> None:
        if self.proc.is_alive():
            try:
                self.conn.send(None)
            except OSError:
                pass
            self.proc.join(0.2)
        if self.proc.is_alive():
            self.proc.terminate()  # SIGTERM: a worker dies at once (``_worker_signals``)
            self.proc.join(2.0)
        if self.proc.is_alive():
            self.proc.kill()
            self.proc.join(2.0)
        self.conn.close()


def _exit_name(code: int | None) -> str:
    if code is not None and code < 0:
        try:
            return signal.Signals(-code).name
        except ValueError:
            return f"signal {-code}"
    return f"exit code {code}"


def _worker_main(conn, fn, extra: dict) -> None:
    """A worker: runs of (index, item) in, ``start``/``done`` per item and ``idle`` per run out."""
    _init_worker(extra)
    while True:
        try:
            run = conn.recv()
        except EOFError:
            return
        if run is None:
            return
        for idx, item in run:
            conn.send(("start", idx))
            try:
                out = fn(item)
            except BaseException as err:  # noqa: BLE001 - sent to the parent, which stops the run
                conn.send(("error", idx, _sendable(err)))
                return
            conn.send(("done", idx, out))
        conn.send(("idle",))


def _sendable(err: BaseException) -> Exception:
    """``err`` as the parent can raise it: itself where it pickles and is an ``Exception``."""
    if isinstance(err, Exception):
        try:
            pickle.loads(pickle.dumps(err))
            return err
        except Exception:  # noqa: BLE001
            pass
    return RuntimeError(f"{type(err).__name__}: {err}")


def batches(items: list, group: Callable[[Any], Hashable] | None = None, batch: int = 8) -> list[list]:
    """``items`` in order, cut into runs of one group each (``group(item)``; None: one run
    per item), none longer than ``batch``."""
    if batch < 1:
        raise ValueError(f"batch: must be >= 1, got {batch}")
    if group is None:
        return [[item] for item in items]
    runs: list[list] = []
    last = object()
    for item in items:
        key = group(item)
        if not runs or key != last or len(runs[-1]) >= batch:
            runs.append([])
        runs[-1].append(item)
        last = key
    return runs


def slot_of(case: Scenario | Layout) -> tuple:
    """What a case's slot geometry depends on (its start does not): a grid case's slot
    factors; a layout is a scene of its own."""
    if isinstance(case, Layout):
        return ("layout", case.name)
    return (case.parking_type, case.road_width, case.slot_length, case.slot_width)


def _pool_context():
    """The start method for worker processes, and the planners the workers must be told of.

    ``fork`` is cheap and keeps planners registered at run time (a script's or a notebook's
    own), but a fork copies every lock as it was: one held by another thread of the parent
    (an I/O thread, a progress bar's, a thread pool's) stays held in the child for good, and the
    worker hangs. So fork only a single-threaded process; otherwise start the workers from a
    fresh ``forkserver`` and pass them the planners registered at run time by reference.
    """

    extra = {k: f for k, f in registry.PLANNERS.items() if registry.BUILTIN.get(k) is not f}
    if not hasattr(os, "fork"):
        return mp.get_context("spawn"), extra
    if _native_threads() == 1 or any(getattr(f, "__module__", None) == "__main__" for f in extra.values()):
        # A planner defined in __main__ (``python -c``, a notebook) exists only in a fork.
        return mp.get_context("fork"), {}
    ctx = mp.get_context("forkserver")
    ctx.set_forkserver_preload(["evaluation.runner", "evaluation.registry", "mirrorpark_env"])
    return ctx, extra


def _native_threads() -> int:
    try:
        return len(os.listdir("/proc/self/task"))  # every thread, those of C libraries too
    except OSError:
        import threading

        return threading.active_count()


def _init_worker(extra: dict) -> None:
    """Workers leave Ctrl-C to the parent and know the planners registered at run time."""

    _worker_signals()
    registry.PLANNERS.update(extra)


def _run_ray(
    planner: str,
    todo: list[Scenario],
    keep,
    address: str | None,
    workers: int,
    trajectories: bool = False,
    call_limit_s: float | None = CALL_LIMIT_S,
) -> None:
    try:
        import ray
    except ImportError:
        raise ValueError("backend 'ray' needs the ray extra: pip install 'mirrorpark[ray]'") from None
    if not ray.is_initialized():
        if address:
            ray.init(address=address, ignore_reinit_error=True, log_to_driver=False)
        else:
            ray.init(num_cpus=workers, ignore_reinit_error=True, log_to_driver=False, include_dashboard=False)
    task = ray.remote(num_cpus=1, max_retries=0)(run_case)  # a crashed worker is reported, not retried
    limit = 4 * max(1, int(ray.available_resources().get("CPU", workers)))
    pending: dict = {}  # task -> its case

    def collect() -> None:
        ready, _ = ray.wait(list(pending), num_returns=1)
        for ref in ready:
            sc = pending.pop(ref)
            try:
                row = ray.get(ref)
            except ray.exceptions.RayError as err:  # run_case never raises: its worker died
                for other in pending:
                    ray.cancel(other, force=True)
                why = type(err).__name__
                raise WorkerDied(f"a Ray worker died ({why}) while running {sc.case_id}") from None
            keep(row)

    for sc in todo:  # a few tasks in flight per CPU; one new task per finished one
        pending[task.remote(planner, sc, trajectory=trajectories, call_limit_s=call_limit_s)] = sc
        if len(pending) >= limit:
            collect()
    while pending:
        collect()


class _NoBar:
    def update(self, n: int) -> None:
        pass

    def close(self) -> None:
        pass


def progress_bar(total: int, desc: str, enabled: bool, initial: int = 0):
    if not enabled:
        return _NoBar()

    return tqdm(total=total, desc=desc, unit="case", initial=initial, dynamic_ncols=True, smoothing=0.1)
