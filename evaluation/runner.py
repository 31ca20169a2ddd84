"""Run a planner over cases: one row per (case, planner), locally on all cores or on Ray.

A case that raises becomes an error row carrying its message, and the run goes on.
Rows are appended to the store as they finish; a rerun over the same folder resumes.
"""

from __future__ import annotations

import dataclasses
import math
import os
import queue
import sys
import time
import traceback
from collections.abc import Callable, Hashable, Iterable
from pathlib import Path
from typing import Any

import numpy as np

from mirrorpark_env.criteria import iso_pose_exists
from mirrorpark_env.layout import Layout
from mirrorpark_env.scenario import Scenario
from mirrorpark_env.vehicle import VehicleParams, vehicle_name

from .causes import episode_cause
from .provenance import current_id
from .schema import MARGINS
from .store import ResultStore, locked

_ENV = None  # one environment per worker process


def worker_env():
    global _ENV
    if _ENV is None:
        import gymnasium as gym

        import mirrorpark_env  # noqa: F401

        _ENV = gym.make("MirrorPark-v0")  # with its TimeLimit: episodes end at 180 s
    return _ENV


def case_fields(sc: Scenario) -> dict[str, Any]:
    """The case's own values, as run (the id is only its name)."""
    return {
        "case_id": sc.case_id,
        "parking_type": sc.parking_type.value,
        "road_width": sc.road_width,
        "slot_length": sc.slot_length,
        "slot_width": sc.slot_width,
        "theta0_deg": round(sc.theta0_deg, 9),
        "y0": sc.y0,
        "y1": round(sc.road_width - sc.y0, 9),  # distance from the rear axle to the road boundary
        "start_x_offset": sc.start_x_offset,
    }


def layout_fields(lay: Layout) -> dict[str, Any]:
    """A layout's row fields: its name, slot and start (the grid's columns where they apply)."""
    s = lay.slot
    return {
        "case_id": lay.name,
        "layout": lay.name,
        "vehicle": "paper" if lay.vehicle is None else (vehicle_name(lay.vehicle) or "custom"),
        "parking_type": s.parking_type.value if s is not None else "none",
        "road_width": lay.road_width,
        "slot_length": s.length if s is not None else math.nan,
        "slot_width": s.width if s is not None else math.nan,
        "theta0_deg": round(math.degrees(lay.start[2]), 9),
        "y0": math.nan,
        "y1": math.nan,
        "start_x_offset": math.nan,
    }


def _feasible(case: Scenario | Layout) -> bool:
    """Whether the case's slot admits an ISO pose (a layout without a slot: always)."""
    if isinstance(case, Layout):
        if case.slot is None:
            return True
        ptype, sl, sw = case.slot.parking_type, case.slot.length, case.slot.width
    else:
        ptype, sl, sw = case.parking_type, case.slot_length, case.slot_width
    car = case.vehicle if isinstance(case, Layout) and case.vehicle is not None else VehicleParams.table_ii()
    return bool(iso_pose_exists(ptype.value, sl, sw, car))


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


def run_case(planner: str, sc: Scenario | Layout, keep_stats: list | None = None) -> dict[str, Any]:
    """One episode of ``planner`` on a grid case or a layout; never raises (errors become rows).

    A layout's row also holds the driven path (``path_t``, ``path_x``, ``path_y``,
    ``path_theta``: the rear axle at every step, in the layout's frame) for its figure and
    its trajectory file. ``keep_stats``: a list that the
    policy's ``PlanStats`` of every call are appended to (the benchmark's breakdown)."""
    from planners.base import run_episode

    from .registry import make_policy

    t0 = time.perf_counter()
    row: dict[str, Any] = {"planner": planner}
    info = None
    try:
        is_layout = isinstance(sc, Layout)
        row.update(layout_fields(sc) if is_layout else case_fields(sc))
        policy = make_policy(planner)
        trace: list[dict] | None = [] if is_layout else None
        info, steps = run_episode(worker_env(), policy, sc, trace=trace)
        if trace is not None:
            row["path_t"] = [round(float(i["parking_time"]), 6) for i in trace]
            row["path_x"] = [round(i["vehicle_state"].x, 4) for i in trace]
            row["path_y"] = [round(i["vehicle_state"].y, 4) for i in trace]
            row["path_theta"] = [round(i["vehicle_state"].theta, 6) for i in trace]
        if keep_stats is not None:
            keep_stats.extend(policy.stats)
        times = [1e3 * s.wall_time_s for s in policy.stats]
        row.update(
            success=bool(info["is_success"]),
            failed_criterion=info["failed_criterion"],
            collision=bool(info["collision"]),
            heading_error_deg=float(info["heading_error_deg"]),
            switches=int(info["direction_switches"]),
            parking_time_s=float(info["parking_time"]),
            path_length_m=float(info["path_length"]),
            steps=steps,
            planning_calls=len(times),
            plan_time_median_ms=float(np.median(times)) if times else math.nan,
            plan_time_max_ms=float(np.max(times)) if times else math.nan,
            plan_times_ms=[round(t, 3) for t in times],
            # Work per call, which (unlike time) any machine repeats: iterations (SCP rounds,
            # search expansions), QP solves, nodes (branch and bound, search).
            plan_iterations=[int(s.iterations) for s in policy.stats],
            plan_qp_solves=[int(s.qp_solves) for s in policy.stats],
            plan_nodes=[int(s.nodes) for s in policy.stats],
            safety_net_calls=sum(bool(s.detail.get("safety_net")) for s in policy.stats),
            setup_ms=1e3 * float(getattr(policy, "setup_time_s", 0.0)),
            planner_status=policy.status,
            error=None,
            inside_slot=bool(info["inside_slot"]),
            min_clearance_m=float(info["min_clearance"]),
            speed_at_min_clearance=float(info["speed_at_min_clearance"]),
            min_clearance_away_m=float(info["min_clearance_away"]),
            speed_at_min_clearance_away=float(info["speed_at_min_clearance_away"]),
        )
        for m in MARGINS:
            row[m] = float(info["margins"].get(m, math.nan))
    except Exception as err:  # noqa: BLE001  (any failure of one case must not stop the run)
        row.update(
            success=False,
            failed_criterion="error",
            planner_status="error",
            error=f"{type(err).__name__}: {err}",
            traceback=traceback.format_exc(limit=5),
        )
    feasible = _feasible(sc)
    row["feasible"] = feasible
    ended = None if row.get("planner_status") == "error" else info
    row["failure_cause"], row["failure_amount"] = episode_cause(ended, feasible)
    row["episode_wall_s"] = time.perf_counter() - t0
    row["environment"] = current_id()  # the machine and packages (``environment.jsonl``)
    return row


def _run_case_tuple(args: tuple[str, Scenario]) -> dict[str, Any]:
    return run_case(*args)


def evaluate(
    planner: str,
    scenarios: Iterable[Scenario],
    out: str | Path,
    workers: int | None = None,
    backend: str = "local",
    ray_address: str | None = None,
    progress: bool = True,
    mixed_code: bool = False,
) -> ResultStore:
    """Run ``planner`` over ``scenarios`` into the store at ``out``; resume where it stopped,
    if its rows of ``planner`` came from this code (``provenance.check_resume``; ``mixed_code``:
    whatever code they came from)."""
    from .registry import make_policy

    make_policy(planner)  # an unknown planner fails now, not in every worker
    if backend not in ("local", "ray"):
        raise ValueError(f"backend: must be 'local' or 'ray', got {backend!r}")
    workers = (os.cpu_count() or 1) if workers is None else workers
    if workers < 1:
        raise ValueError(f"workers: must be >= 1, got {workers}")
    store = ResultStore(out)
    with locked(store.folder):  # one run per results folder at a time
        _run_into(store, planner, scenarios, workers, backend, ray_address, progress, mixed_code)
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
) -> None:
    """``evaluate``'s run, the folder locked: the cases not yet stored, their rows appended."""
    from .provenance import check_resume

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
            _run_ray(planner, todo, keep, ray_address, workers)
        elif min(workers, len(todo)) <= 1:  # no processes to start for one case
            for sc in todo:
                keep(run_case(planner, sc))
        else:
            items = [(planner, sc) for sc in todo]
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
    import signal

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    if sys.platform.startswith("linux"):  # die with the parent, however it dies: SIGKILL leaves it no clean-up
        import ctypes

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
    import multiprocessing as mp

    from . import registry

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
    from . import registry

    _worker_signals()
    registry.PLANNERS.update(extra)
    _RESULTS = results


def _run_ray(planner: str, todo: list[Scenario], keep, address: str | None, workers: int) -> None:
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
        pending.append(task.remote(planner, sc))
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
    from tqdm import tqdm

    return tqdm(total=total, desc=desc, unit="case", initial=initial, dynamic_ncols=True, smoothing=0.1)
