"""Run a planner over cases: one row per (case, planner), locally on all cores or on Ray.

A case that raises becomes an error row carrying its message, and the run goes on.
Rows are appended to the store as they finish; a rerun over the same folder resumes.
"""

from __future__ import annotations

import ctypes
import dataclasses
import multiprocessing as mp
import os
import queue
import signal
import sys
from collections.abc import Callable, Hashable, Iterable
from pathlib import Path
from typing import Any

from tqdm import tqdm

from mirrorpark_env.layout import Layout
from mirrorpark_env.scenario import Scenario

from . import registry
from .episode import run_case, worker_env
from .provenance import check_resume
from .registry import make_policy
from .store import ResultStore, locked

__all__ = ["evaluate", "run_case", "run_parallel", "slot_of", "unique", "worker_env"]


def unique(scenarios: Iterable[Scenario]) -> tuple[list[Scenario], int]:
    """The scenarios in order with repeats (same id) dropped, and how many were dropped. Two
    grid cases that share an id but differ (by less than the ids' precision) are refused,
    both named: one would silently stand for the other."""
    out, seen, n_in = [], {}, 0
    for sc in scenarios:
        n_in += 1
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


def _run_case_tuple(args: tuple[str, Scenario, bool]) -> dict[str, Any]:
    planner, sc, trajectory = args
    return run_case(planner, sc, trajectory=trajectory)


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
) -> ResultStore:
    """Run ``planner`` over ``scenarios`` into the store at ``out``; resume where it stopped,
    if its rows of ``planner`` came from this code (``provenance.check_resume``; ``mixed_code``:
    whatever code they came from). ``trajectories``: rows keep the driven trajectory (layout
    rows always do)."""

    make_policy(planner)  # an unknown planner fails now, not in every worker
    if backend not in ("local", "ray"):
        raise ValueError(f"backend: must be 'local' or 'ray', got {backend!r}")
    workers = (os.cpu_count() or 1) if workers is None else workers
    if workers < 1:
        raise ValueError(f"workers: must be >= 1, got {workers}")
    store = ResultStore(out)
    with locked(store.folder):  # one run per results folder at a time
        _run_into(store, planner, scenarios, workers, backend, ray_address, progress, mixed_code, trajectories)
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
            _run_ray(planner, todo, keep, ray_address, workers, trajectories)
        elif min(workers, len(todo)) <= 1:  # no processes to start for one case
            for sc in todo:
                keep(run_case(planner, sc, trajectory=trajectories))
        else:
            items = [(planner, sc, trajectories) for sc in todo]
            run_parallel(_run_case_tuple, items, keep, workers, group=lambda it: slot_of(it[1]))
    except KeyboardInterrupt:
        bar.close()
        store.compact()
        left = len(todo) - stored
        raise KeyboardInterrupt(
            f"{len(store.done())} cases stored in {store.folder}, {left} not run; rerun the same command to resume"
        ) from None
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


def run_parallel(
    fn: Callable[[Any], Any],
    items: list,
    keep: Callable[[Any], None],
    workers: int,
    group: Callable[[Any], Hashable] | None = None,
    batch: int = 8,
) -> None:
    """``keep(fn(item))`` for every item, in ``workers`` processes, as each finishes.

    ``fn`` must be a module-level function (it is pickled for the workers); no more workers
    start than there are items. ``group(item)`` (optional) names what items may share: items
    of one group, in the order given, go to one worker in runs of up to ``batch``, so that
    what a planner builds once per slot (``planners.common.slot_cache``) is built once per
    run, not once in every worker that meets the slot. Results do not change, only the
    work. Each item's result comes back as soon as it is done, not with its run: an
    interruption loses only the items in progress.
    """
    runs = batches(items, group, batch)
    if not runs:
        return
    ctx, extra = _pool_context()
    results = ctx.Queue()
    n_proc = min(workers, len(runs))
    with ctx.Pool(n_proc, initializer=_init_worker, initargs=(extra, results), maxtasksperchild=200) as pool:
        pending = pool.map_async(_run_batch, [(fn, run) for run in runs], chunksize=1)
        left = len(items)
        while left:
            try:
                ok, out = results.get(timeout=1.0 if not pending.ready() else 30.0)
            except queue.Empty:
                if not pending.ready():
                    continue
                pending.get()  # a run that failed outside ``fn`` raises here
                raise RuntimeError(f"run_parallel: {left} of {len(items)} items gave no result") from None
            if not ok:
                raise out
            keep(out)
            left -= 1


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


def _run_batch(task: tuple) -> None:
    """Run items one after another in this worker, each result sent on as it is done."""
    fn, items = task
    for item in items:
        try:
            out = fn(item)
        except Exception as err:
            _RESULTS.put((False, err))
            raise
        _RESULTS.put((True, out))


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


_RESULTS = None  # a worker's queue to the parent (``run_parallel``)


def _init_worker(extra: dict, results=None) -> None:
    """Workers leave Ctrl-C to the parent, know the planners registered at run time, and
    send their results on ``results``."""
    global _RESULTS

    _worker_signals()
    registry.PLANNERS.update(extra)
    _RESULTS = results


def _run_ray(
    planner: str, todo: list[Scenario], keep, address: str | None, workers: int, trajectories: bool = False
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
    task = ray.remote(num_cpus=1)(run_case)
    limit = 4 * max(1, int(ray.available_resources().get("CPU", workers)))
    pending = []

    def collect() -> None:
        nonlocal pending
        ready, pending = ray.wait(pending, num_returns=1)
        for ref in ready:
            keep(ray.get(ref))

    for sc in todo:  # a few tasks in flight per CPU; one new task per finished one
        pending.append(task.remote(planner, sc, trajectory=trajectories))
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
