"""The packages' shape: data flows one way (configs -> scenario -> environment <- policy;
evaluation drives both), no package's modules import each other in a circle, and no module
grows past what one reader holds in mind.

Imports are read from the source (``ast``), function-local ones included; those under
``if TYPE_CHECKING:`` are annotations only and never run, so they are left out.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
PACKAGES = ("mirrorpark_env", "planners", "evaluation")
MAX_LINES = 450


def _modules() -> dict[str, Path]:
    out = {}
    for pkg in PACKAGES:
        for f in sorted((ROOT / pkg).rglob("*.py")):
            parts = list(f.relative_to(ROOT).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts.pop()
            out[".".join(parts)] = f
    return out


MODULES = _modules()


def _is_type_checking(node: ast.If) -> bool:
    t = node.test
    return (isinstance(t, ast.Name) and t.id == "TYPE_CHECKING") or (
        isinstance(t, ast.Attribute) and t.attr == "TYPE_CHECKING"
    )


def _imports(name: str, path: Path) -> set[str]:
    """The project modules that ``name`` imports at run time."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found: set[str] = set()

    def resolve(target: str) -> str | None:
        while target and target not in MODULES:  # a name inside a module: the module
            target = target.rpartition(".")[0]
        return target or None

    def visit(node: ast.AST) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.If) and _is_type_checking(child):
                for n in child.orelse:
                    visit(n)
                continue
            if isinstance(child, ast.Import):
                for a in child.names:
                    m = resolve(a.name)
                    if m:
                        found.add(m)
            elif isinstance(child, ast.ImportFrom):
                if child.level:
                    base = package.split(".")
                    base = base[: len(base) - (child.level - 1)]
                    mod = ".".join(base + ([child.module] if child.module else []))
                else:
                    mod = child.module or ""
                for a in child.names:  # ``from pkg import module`` names the module itself
                    m = resolve(f"{mod}.{a.name}") or resolve(mod)
                    if m:
                        found.add(m)
            visit(child)

    visit(ast.parse(path.read_text(), str(path)))
    found.discard(name)
    return found


GRAPH = {name: _imports(name, path) for name, path in MODULES.items()}


def _top(module: str) -> str:
    return module.split(".")[0]


def test_the_reader_sees_imports_the_way_python_runs_them():
    """A check of the checker: known edges are found, TYPE_CHECKING ones are not."""
    assert "planners.mirror.core" in GRAPH["planners.mirror.planner"]
    assert "planners.mirror.config" in GRAPH["planners.mirror.strategies.aimed"]  # ``from ..config import``
    assert "evaluation.registry" in GRAPH["evaluation.collect"]  # a function-local import
    assert "mirrorpark_env.scenario" not in GRAPH["mirrorpark_env.scene"]  # under TYPE_CHECKING


@pytest.mark.parametrize(
    ("lower", "upper"),
    [("planners", "evaluation"), ("mirrorpark_env", "planners"), ("mirrorpark_env", "evaluation")],
)
def test_imports_point_down_only(lower, upper):
    """Planners never import evaluation (the expert for DAgger and collection is handed in);
    the environment imports neither."""
    bad = sorted(f"{m} -> {t}" for m, ts in GRAPH.items() if _top(m) == lower for t in ts if _top(t) == upper)
    assert not bad


def _cycle(nodes: list[str]) -> list[str] | None:
    """A cycle among ``nodes`` (edges of ``GRAPH`` between them), or None."""
    inside = set(nodes)
    state: dict[str, int] = {}
    stack: list[str] = []

    def dfs(n: str) -> list[str] | None:
        state[n] = 1
        stack.append(n)
        for t in sorted(GRAPH[n] & inside):
            if state.get(t) == 1:
                return stack[stack.index(t) :] + [t]
            if t not in state and (found := dfs(t)):
                return found
        stack.pop()
        state[n] = 2
        return None

    for n in sorted(inside):
        if n not in state and (found := dfs(n)):
            return found
    return None


@pytest.mark.parametrize("package", PACKAGES)
def test_no_modules_of_a_package_import_each_other_in_a_circle(package):
    cycle = _cycle([m for m in MODULES if _top(m) == package])
    assert cycle is None, " -> ".join(cycle)


def test_the_cycle_finder_finds_a_cycle():
    GRAPH["evaluation.__probe_a"], GRAPH["evaluation.__probe_b"] = {"evaluation.__probe_b"}, {"evaluation.__probe_a"}
    try:
        assert _cycle(["evaluation.__probe_a", "evaluation.__probe_b"]) is not None
    finally:
        del GRAPH["evaluation.__probe_a"], GRAPH["evaluation.__probe_b"]


def test_no_module_is_longer_than_one_reader_holds():
    long = {m: n for m, p in MODULES.items() if (n := len(p.read_text().splitlines())) > MAX_LINES}
    assert not long, f"split these by concept: {long}"
