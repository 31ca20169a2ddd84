"""What a run ran on: the CPU, numpy's vector paths and the package versions.

Budgets count work, so a case gives the same row on any machine as far as the
arithmetic is the same. It is not always: rows of the same code have been seen to differ
between sessions in a few cases out of hundreds (docs/evaluation.md). Each evaluation
records its environment beside its results (``environment.jsonl`` in the results folder,
the metadata of an exported table), and each row names it by ``environment_id``, so that
two runs' rows can be told apart.

Each run also records ``source_id``: a hash of the code and files that decide a row. A
results folder resumes only with the code its rows came from (``check_resume``): after a
change to a planner, resuming the old folder would hand back the old code's rows as if
they were the new code's.
"""

from __future__ import annotations

import functools
import hashlib
import importlib.util
import json
import platform
from datetime import datetime, timezone
from importlib import metadata
from pathlib import Path
from typing import Any

from mirrorpark_env.config import default_config_path

PACKAGES = (
    "mirrorpark",
    "numpy",
    "scipy",
    "piqp",
    "numba",
    "llvmlite",
    "gymnasium",
    "highway-env",
    "shapely",
    "pydantic",
    "pandas",
    "pyarrow",
)


def _cpu_model() -> str:
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


def _numpy_simd() -> list[str]:
    """The vector extensions numpy dispatches to on this CPU (beyond its baseline)."""
    try:
        from numpy._core._multiarray_umath import __cpu_dispatch__, __cpu_features__
    except ImportError:  # another numpy layout: leave it out rather than guess
        return []
    return [f for f in __cpu_dispatch__ if __cpu_features__.get(f)]


def _piqp_build() -> str | None:
    """The piqp extension the mirror planners solve with (its builds round differently)."""
    try:
        from planners.mirror.solvers import PIQP
    except ImportError:
        return None
    return PIQP.__name__


def _version(name: str) -> str | None:
    try:
        return metadata.version(name)
    except metadata.PackageNotFoundError:
        return None


def environment() -> dict[str, Any]:
    """This process's machine and package versions, with the time (UTC, ISO 8601)."""
    return {
        "time": datetime.now(timezone.utc).isoformat(timespec="seconds"),
        "python": platform.python_version(),
        "system": f"{platform.system()} {platform.machine()}",
        "cpu": _cpu_model(),
        "numpy_simd": _numpy_simd(),
        "piqp_build": _piqp_build(),
        "packages": {name: _version(name) for name in PACKAGES},
    }


def environment_id(env: dict[str, Any]) -> str:
    """A short name of an environment: the same for the same machine and packages (time aside)."""
    key = json.dumps({k: v for k, v in env.items() if k != "time"}, sort_keys=True)
    return hashlib.sha256(key.encode()).hexdigest()[:12]


@functools.cache
def current_id() -> str:
    """``environment_id`` of this process's environment."""
    return environment_id(environment())


# What decides a row besides the machine and the packages: the environment and the
# planners, the modules that run a case and build its row, and the environment's YAML files
# (``configs/``); for ``rl:PATH`` also the model file.
ROW_MODULES = (
    "mirrorpark_env",
    "planners",
    "evaluation.runner",
    "evaluation.episode",
    "evaluation.registry",
    "evaluation.causes",
    "evaluation.cases",
)
ROW_CONFIGS = ("env.yaml", "vehicle.yaml")


@functools.cache
def _row_files() -> tuple[tuple[str, Path], ...]:
    """(name, path) of every file ``source_id`` reads, in a fixed order."""

    files: list[tuple[str, Path]] = []
    for name in ROW_MODULES:
        spec = importlib.util.find_spec(name)
        if spec is None:
            raise RuntimeError(f"source_id: module {name!r} not found")
        if spec.submodule_search_locations:  # a package: every module in it
            for root in map(Path, spec.submodule_search_locations):
                files += [(f"{name}/{f.relative_to(root).as_posix()}", f) for f in sorted(root.rglob("*.py"))]
        else:
            files.append((name, Path(spec.origin)))
    return (*files, *((f"configs/{n}", default_config_path(n)) for n in ROW_CONFIGS))


def _planner_files(planner: str) -> list[tuple[str, Path]]:
    files = list(_row_files())
    model = planner.split(":", 1)[1] if planner.startswith(("rl:", "rl-shield:")) else None
    if model is not None and Path(model).is_file():
        files.append(("model", Path(model)))
    return files


def source_id(planner: str) -> str:
    """A short hash of what decides ``planner``'s rows on a given machine: the files of
    ``ROW_MODULES`` and ``ROW_CONFIGS`` (names and contents, wherever they are installed),
    and for ``rl:PATH`` or ``rl-shield:PATH`` the model file's content."""
    h = hashlib.sha256()
    for name, f in _planner_files(planner):
        h.update(name.encode() + b"\0" + f.read_bytes() + b"\0")
    return h.hexdigest()[:12]


def source_files(planner: str) -> dict[str, str]:
    """A short hash of each file ``source_id`` reads, by name: what tells which files a
    change of ``source_id`` came from."""
    return {name: hashlib.sha256(f.read_bytes()).hexdigest()[:12] for name, f in _planner_files(planner)}


def check_resume(records: list[dict[str, Any]], planner: str, done: int, folder: Path, mixed: bool) -> None:
    """Raise where ``folder`` holds ``done`` rows (or episodes) of ``planner`` from other
    code than this process's, as its environment ``records`` tell (``source``). Records
    from before sources were recorded tell nothing, and pass; ``mixed`` lets it pass too."""
    if not done or mixed:
        return
    known = [r for r in records if r.get("planner") == planner and r.get("source")]
    now_id = source_id(planner) if known else None
    if known and known[-1]["source"] != now_id:
        last, changed = known[-1], ""
        if isinstance(last.get("source_files"), dict):
            now = source_files(planner)
            names = sorted(n for n in {*now, *last["source_files"]} if now.get(n) != last["source_files"].get(n))
            more = f" and {len(names) - 5} more" if len(names) > 5 else ""
            changed = f"; changed: {', '.join(names[:5])}{more}" if names else ""
        raise ValueError(
            f"{folder}: its {done} result{'s' * (done != 1)} of {planner!r} came from other code (source "
            f"{last['source']}, now {now_id}{changed}): resuming would mix the two. Run into a fresh "
            "--out folder, remove this one, or pass --mixed-code to add to it anyway"
        )
