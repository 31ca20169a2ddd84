"""What a run ran on: the CPU, numpy's vector paths and the package versions.

Budgets count work, so a case gives the same row on any machine as far as the
arithmetic is the same. It is not always: rows of the same code have been seen to differ
between sessions in a few cases out of hundreds (docs/evaluation.md). Each evaluation
records its environment beside its results (``environment.jsonl`` in the results folder,
the metadata of an exported table), and each row names it by ``environment_id``, so that
two runs' rows can be told apart.
"""

from __future__ import annotations

import functools
import hashlib
import json
import platform
from datetime import datetime, timezone
from importlib import metadata
from typing import Any

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
