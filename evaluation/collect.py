"""Expert demonstrations: a planner's closed-loop episodes recorded as a Minari dataset.

Each finished episode is written whole to ``OUT/episodes/<case_id>.npz`` (then renamed
into place), so an interrupted collection resumes without redoing or losing episodes;
the Minari dataset is then built from all of them in ``OUT/minari/`` (rebuilt on every
run, so it always holds every recorded episode). Load it with
``MINARI_DATASETS_PATH=OUT/minari`` and ``minari.load_dataset("mirrorpark/<planner>-v0")``,
or from its path with ``minari.MinariDataset("OUT/minari/mirrorpark/<planner>-v0/data")``.

Per step it holds the observation (the env's ``Dict``), the normalised action, the reward,
termination, truncation (also where the policy gave up and the car stood), and the infos
that matter: ``is_success``, ``collision``, ``min_margin`` (the smallest ISO margin) and
``heading_error_deg``. Each episode's options name its scenario (``{"scenario": case_id}``),
so ``env.reset(options=...)`` replays it; the dataset's description names the planner.
"""

from __future__ import annotations

import os
import re
import shutil
import warnings
from collections.abc import Iterable
from pathlib import Path
from typing import Any
from unittest import mock

import numpy as np

from mirrorpark_env.scenario import Scenario

from .runner import progress_bar, run_parallel, slot_of, unique, worker_env

INFO_KEYS = ("is_success", "collision", "min_margin", "heading_error_deg")


def record_episode(planner: str, sc: Scenario) -> dict[str, np.ndarray]:
    """One closed-loop episode of ``planner`` on ``sc``, as arrays (observations n + 1)."""
    from planners.base import run_episode

    from .registry import make_policy

    record: list[tuple] = []
    run_episode(worker_env(), make_policy(planner), sc, record=record)
    obs0, info0 = record[0]
    steps = record[1:]
    out: dict[str, np.ndarray] = {}
    for key in obs0:
        out[f"obs/{key}"] = np.stack([obs0[key]] + [s[1][key] for s in steps])
    out["actions"] = np.asarray([s[0] for s in steps], np.float32)
    out["rewards"] = np.asarray([s[2] for s in steps], float)
    out["terminations"] = np.asarray([s[3] for s in steps], bool)
    out["truncations"] = np.asarray([s[4] for s in steps], bool)
    for key, values in _infos([info0] + [s[5] for s in steps]).items():
        out[f"info/{key}"] = values
    return out


def _infos(infos: list[dict[str, Any]]) -> dict[str, np.ndarray]:
    """The recorded infos as (n + 1, 1) arrays (Minari's storage wants a trailing axis)."""
    return {
        "is_success": np.array([[i["is_success"]] for i in infos], bool),
        "collision": np.array([[i["collision"]] for i in infos], bool),
        "min_margin": np.array([[min(i["margins"].values())] for i in infos], float),
        "heading_error_deg": np.array([[i["heading_error_deg"]] for i in infos], float),
    }


def _record_to_file(args: tuple[str, Scenario, str]) -> str:
    planner, sc, folder = args
    data = record_episode(planner, sc)
    final = Path(folder) / f"{sc.case_id}.npz"
    tmp = final.with_name(f".{final.name}.{os.getpid()}.tmp")
    with tmp.open("wb") as f:
        np.savez(f, **data)
    os.replace(tmp, final)
    return sc.case_id


def dataset_id(planner: str) -> str:
    return f"mirrorpark/{re.sub(r'[^A-Za-z0-9_-]+', '_', planner)}-v0"


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
    from .provenance import check_resume
    from .registry import make_policy
    from .store import read_environments, record_environment

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


def build_dataset(planner: str, files: list[Path], root: Path):
    """The Minari dataset of these episode files, (re)built under ``root``."""
    import minari
    from minari.data_collector import EpisodeBuffer
    from minari.dataset.minari_storage import MinariStorage

    buffers = []
    for k, f in enumerate(files):
        with np.load(f) as z:
            buffers.append(
                EpisodeBuffer(
                    id=k,
                    options={"scenario": f.stem},
                    observations={key[4:]: z[key] for key in z.files if key.startswith("obs/")},
                    actions=z["actions"],
                    rewards=z["rewards"].tolist(),
                    terminations=z["terminations"].tolist(),
                    truncations=z["truncations"].tolist(),
                    infos={key[5:]: z[key] for key in z.files if key.startswith("info/")},
                )
            )
    did = dataset_id(planner)
    shutil.rmtree(root / did, ignore_errors=True)
    old = os.environ.get("MINARI_DATASETS_PATH")
    os.environ["MINARI_DATASETS_PATH"] = str(root.resolve())
    try:
        # Minari 0.5 re-measures the whole dataset folder after every episode it writes
        # (``get_size`` walks every file), which makes a build quadratic in the episodes:
        # 1,500 episodes took 91 s. The size is measured once, at the end, instead.
        with warnings.catch_warnings(), mock.patch.object(MinariStorage, "get_size", lambda self: 0.0):
            warnings.simplefilter("ignore", UserWarning)  # author e-mail and eval env: not ours to give
            dataset = minari.create_dataset_from_buffers(
                did,
                buffers,
                env="MirrorPark-v0",
                algorithm_name=planner,
                description=f"MirrorPark-v0 episodes of the {planner!r} planner on {len(files)} cases "
                "(each episode's options name its scenario); recorded with `mirrorpark collect`.",
                data_format="arrow",
            )
        dataset.storage.update_metadata({"dataset_size": dataset.storage.get_size()})
    finally:
        if old is None:
            os.environ.pop("MINARI_DATASETS_PATH", None)
        else:
            os.environ["MINARI_DATASETS_PATH"] = old
    return root / did
