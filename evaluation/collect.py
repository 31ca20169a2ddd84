"""``mirrorpark collect``: a planner's episodes over cases, in parallel and resumable, as a Minari dataset.

Each finished episode is written whole to ``OUT/episodes/<case_id>.npz`` (then renamed into
place), so an interrupted collection resumes without redoing or losing episodes; the
dataset is then (re)built from all of them (``planners/rl/demos.py``, which says what it holds).
"""

from __future__ import annotations

import os
from collections.abc import Iterable
from pathlib import Path

import numpy as np

from mirrorpark_env.scenario import Scenario
from planners.rl.demos import build_dataset, record_episode

from .provenance import check_resume
from .registry import make_policy
from .runner import progress_bar, run_parallel, slot_of, unique, worker_env
from .store import read_environments, record_environment


def _record_to_file(args: tuple[str, Scenario, str]) -> str:

    planner, sc, folder = args
    data = record_episode(worker_env(), make_policy(planner), sc)
    final = Path(folder) / f"{sc.case_id}.npz"
    tmp = final.with_name(f".{final.name}.{os.getpid()}.tmp")
    with tmp.open("wb") as f:
        np.savez(f, **data)
    os.replace(tmp, final)
    return sc.case_id


def collect(
    planner: str,
    scenarios: Iterable[Scenario],
    out: str | Path,
    workers: int | None = None,
    progress: bool = True,
    mixed_code: bool = False,
) -> Path:
    """Record ``planner``'s episodes on ``scenarios`` into ``out``; resume where it stopped,
    if the episodes there are ``planner``'s and came from this code (``mixed_code``: whatever
    code they came from). Returns the Minari dataset's folder."""

    try:  # before any case runs, not after all of them
        import minari  # noqa: F401
    except ImportError:
        raise ValueError("collect needs the rl extra (minari is missing): pip install -e '.[rl]'") from None
    make_policy(planner)  # an unknown planner fails now
    workers = (os.cpu_count() or 1) if workers is None else workers
    if workers < 1:
        raise ValueError(f"workers: must be >= 1, got {workers}")
    out = Path(out)
    episodes = out / "episodes"
    episodes.mkdir(parents=True, exist_ok=True)
    log = out / "environment.jsonl"
    records, stored = read_environments(log), sum(1 for _ in episodes.glob("*.npz"))
    others = {r.get("planner") for r in records} - {planner}
    if stored and others:
        raise ValueError(
            f"{out}: holds episodes of {', '.join(sorted(map(str, others)))}, not only of {planner!r}: "
            "collect into another --out folder"
        )
    check_resume(records, planner, stored, out, mixed_code)
    cases = unique(scenarios)[0]
    todo = [sc for sc in cases if not (episodes / f"{sc.case_id}.npz").exists()]
    if todo:
        record_environment(log, planner, len(todo))
    bar = progress_bar(len(todo), f"collect {planner}", progress)
    try:
        items = [(planner, sc, str(episodes)) for sc in todo]
        if min(workers, len(items)) <= 1:
            for item in items:
                _record_to_file(item)
                bar.update(1)
        else:
            run_parallel(_record_to_file, items, lambda _: bar.update(1), workers, group=lambda it: slot_of(it[1]))
    except KeyboardInterrupt:
        done = len(list(episodes.glob("*.npz")))
        raise KeyboardInterrupt(f"{done} episodes stored in {episodes}; rerun the same command to resume") from None
    finally:
        bar.close()
    return build_dataset(planner, [episodes / f"{sc.case_id}.npz" for sc in cases], out / "minari")
