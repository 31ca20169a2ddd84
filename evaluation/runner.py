"""Run a planner over cases: one row per (case, planner), locally on all cores or on Ray.

A case that raises becomes an error row carrying its message, and the run goes on.
Rows are appended to the store as they finish; a rerun over the same folder resumes.
"""

from __future__ import annotations

import dataclasses
import os
import warnings
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from tqdm import tqdm

from mirrorpark_env.config import PerturbConfig
from mirrorpark_env.layout import Layout
from mirrorpark_env.layout_io import content_key
from mirrorpark_env.scenario import Scenario

from .call_limit import CALL_LIMIT_S
from .episode import run_case, worker_env
from .perturbations import check_folder
from .pool import WorkerDied, run_parallel
from .provenance import check_resume
from .registry import make_policy
from .store import ResultStore, StoreWarning, check_columns, locked

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
        elif isinstance(sc, Layout) and content_key(sc) != content_key(first):
            raise ValueError(
                f"layouts: two different layouts are named {sc.name!r}: rename one (a layout's name keys its rows)"
            )
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


def _run_case_tuple(args: tuple[str, Scenario, bool, float | None, PerturbConfig | None]) -> dict[str, Any]:
    planner, sc, trajectory, call_limit_s, perturb = args
    return run_case(planner, sc, trajectory=trajectory, call_limit_s=call_limit_s, perturb=perturb)


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
    perturb: PerturbConfig | None = None,
) -> ResultStore:
    """Run ``planner`` over ``scenarios`` into the store at ``out``; resume where it stopped,
    if its rows of ``planner`` came from this code (``provenance.check_resume``; ``mixed_code``:
    whatever code they came from). ``trajectories``: rows keep the driven trajectory (layout
    rows always do). ``call_limit_s``: the wall-clock safety net per planner call
    (``call_limit.py``; None or 0: none); a call past it ends its case as an error row.
    ``perturb``: the world differs from what the planner is told (``mirrorpark_env.perturb``);
    a folder holds rows of one perturbation (``perturbations.check_folder``)."""

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
        _run_into(
            store,
            planner,
            scenarios,
            workers,
            backend,
            ray_address,
            progress,
            mixed_code,
            trajectories,
            call_limit_s,
            perturb,
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
    perturb: PerturbConfig | None = None,
) -> None:
    """``evaluate``'s run, the folder locked: the cases not yet stored, their rows appended."""

    table = store.table()
    if len(table):  # a folder of some other tool's table: refused before anything runs
        check_columns(table, store.parquet if store.parquet.exists() else store.folder)
    check_folder(store.folder, perturb, len(table))
    done = stored_keys(table, planner)
    check_resume(store.environments(), planner, len(done), store.folder, mixed_code)
    cases = unique(scenarios)[0]
    todo = [sc for sc in cases if not _finished(sc, done)]
    changed = sum(isinstance(sc, Layout) and sc.case_id in done for sc in todo)
    if changed:
        warnings.warn(
            f"{store.folder}: {changed} layout(s) changed since their rows were stored: run again", StoreWarning, 2
        )
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
            _run_ray(planner, todo, keep, ray_address, workers, trajectories, call_limit_s, perturb)
        elif min(workers, len(todo)) <= 1:  # no processes to start for one case
            for sc in todo:
                keep(run_case(planner, sc, trajectory=trajectories, call_limit_s=call_limit_s, perturb=perturb))
        else:
            items = [(planner, sc, trajectories, call_limit_s, perturb) for sc in todo]
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


def stored_keys(table, planner: str) -> dict[str, str | None]:
    """``planner``'s stored cases: case id -> the layout's content key (None: a grid case, or a
    layout row stored before rows had keys)."""
    if not len(table):
        return {}
    mine = table[table["planner"] == planner]
    keys = mine["layout_key"] if "layout_key" in mine else [None] * len(mine)
    return {cid: (k if isinstance(k, str) else None) for cid, k in zip(mine["case_id"], keys)}


def _finished(case: Scenario | Layout, done: dict[str, str | None]) -> bool:
    """Whether ``case`` has a stored row: a layout's only if it ran on the same content."""
    if case.case_id not in done:
        return False
    return not isinstance(case, Layout) or done[case.case_id] == content_key(case)


def slot_of(case: Scenario | Layout) -> tuple:
    """What a case's slot geometry depends on (its start does not): a grid case's slot
    factors; a layout is a scene of its own."""
    if isinstance(case, Layout):
        return ("layout", case.name)
    return (case.parking_type, case.road_width, case.slot_length, case.slot_width)


def _run_ray(
    planner: str,
    todo: list[Scenario],
    keep,
    address: str | None,
    workers: int,
    trajectories: bool = False,
    call_limit_s: float | None = CALL_LIMIT_S,
    perturb: PerturbConfig | None = None,
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
        pending[task.remote(planner, sc, trajectory=trajectories, call_limit_s=call_limit_s, perturb=perturb)] = sc
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
