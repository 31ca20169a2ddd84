"""Which code a planner's rows come from: ``code_id``, a stamp of that planner's code alone.

``provenance.source_id`` hashes every planner's code, so that a results folder never
resumes across any change. Committed rows need a narrower stamp: a change to hybrid A*
must not void the committed rows of ``mirror``. ``code_id(planner)`` hashes the modules
the planner's policy reaches through its imports (those inside functions too, read from
the source, within ``mirrorpark_env`` and ``planners``), the modules that turn an episode
into a row, and the environment's configs. ``mirrorpark compare --against`` takes the
committed rows of a planner only where their stamp is the installed code's.

Run as a script (``python code_stamp.py PLANNER``, from a checkout's own folder) it prints
the stamp of that checkout's code: how the stamps of tables committed before stamps were
recorded were found (``results/grid/code_ids.json``).
"""

from __future__ import annotations

import ast
import hashlib
import importlib.util
import sys
from pathlib import Path

from evaluation.registry import make_policy
from mirrorpark_env.config import default_config_path

ROOTS = ("mirrorpark_env", "planners")  # followed wherever imported
# The environment (gymnasium makes it by name, not by import) and an episode into a row.
ROW_MODULES = ("mirrorpark_env.env", "evaluation.episode", "evaluation.causes")
CONFIGS = ("env.yaml", "vehicle.yaml")


def _imported(module: str, source: Path, is_package: bool) -> set[str]:
    """Module names ``source`` imports (absolute; a ``from m import name`` gives m and m.name)."""
    package = module if is_package else module.rpartition(".")[0]
    names: set[str] = set()
    for node in ast.walk(ast.parse(source.read_text())):
        if isinstance(node, ast.Import):
            names |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parts = package.split(".")
                parent = ".".join(parts[: len(parts) - node.level + 1])
                base = f"{parent}.{base}" if base else parent
            names.add(base)
            names |= {f"{base}.{a.name}" for a in node.names}
    return {n for n in names if n.split(".")[0] in ROOTS or n in ROW_MODULES}


def code_files(start: list[str]) -> dict[str, Path]:
    """Every module reachable from ``start`` through imports within ``ROOTS`` (and the
    packages that hold them), by name."""
    found: dict[str, Path] = {}
    todo = list(start)
    while todo:
        name = todo.pop()
        if name in found:
            continue
        try:
            spec = importlib.util.find_spec(name)
        except (ImportError, ValueError):  # ``m.name`` where name is a class or function
            spec = None
        if spec is None or not (spec.origin or "").endswith(".py"):
            continue
        found[name] = Path(spec.origin)
        parts = name.split(".")
        todo += [".".join(parts[:i]) for i in range(1, len(parts))]
        todo += sorted(_imported(name, found[name], spec.submodule_search_locations is not None))
    return found


def policy_modules(planner: str) -> list[str]:
    """The modules of ``planner``'s policy class and of a policy it wraps."""

    policy = make_policy(planner)
    inner = [v for v in vars(policy).values() if type(v).__module__.split(".")[0] in ROOTS]
    return sorted({type(policy).__module__, *(type(v).__module__ for v in inner)})


def code_id(planner: str) -> str:
    """A short hash of the code that decides ``planner``'s rows (module names and contents,
    wherever installed, and the environment's configs)."""

    files = code_files([*policy_modules(planner), *ROW_MODULES])
    h = hashlib.sha256()
    for name in sorted(files):
        h.update(name.encode() + b"\0" + files[name].read_bytes() + b"\0")
    for name in CONFIGS:
        h.update(name.encode() + b"\0" + default_config_path(name).read_bytes() + b"\0")
    return h.hexdigest()[:12]


if __name__ == "__main__":
    print(code_id(sys.argv[1]))
