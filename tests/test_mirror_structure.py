"""The mirror planner's shape: its parts are handed over explicitly, the planner owns the
call, one preset table names its planners, and one module prices every plan.

Read from the source (``ast``), as ``test_architecture.py`` reads imports.
"""

from __future__ import annotations

import ast
import math
from pathlib import Path

import numpy as np
import pytest

from evaluation import registry
from mirrorpark_env.scenario import Scenario
from planners.common import cost_to_go_config as price_of
from planners.common.cost_to_go import CostToGo
from planners.mirror import cost
from planners.mirror.config import CostToGoConfig, GuideConfig, PriceConfig
from planners.mirror.guide import GuideSearch
from planners.mirror.presets import PRESETS, preset_config, strategy_for

MIRROR = Path(__file__).resolve().parent.parent / "planners" / "mirror"
SOURCES = {p.relative_to(MIRROR).as_posix(): ast.parse(p.read_text()) for p in sorted(MIRROR.rglob("*.py"))}
OWNERS = {"core.py", "planner.py"}  # where the core is built and the call is owned


def _functions(tree: ast.AST):
    for node in ast.walk(tree):
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
            yield node


def _is_config(node: ast.AST) -> bool:
    """``config`` or ``cfg``, or an attribute of that name: a planner config, whose ``core``
    part (``MirrorPlannerConfig.core``) is settings, not the planner's parts."""
    name = node.id if isinstance(node, ast.Name) else getattr(node, "attr", "")
    return name in ("config", "cfg")


def _core_attributes(tree: ast.AST):
    """Attribute nodes that read the planner's core: ``core.X`` or ``anything.core``."""
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute):
            v = node.value
            if (isinstance(v, ast.Name) and v.id == "core") or (node.attr == "core" and not _is_config(v)):
                yield node


def _reads_of_core(tree: ast.AST) -> list[tuple[str, int]]:
    """(function, line) of every read of the core, by the function it sits in."""
    return [(fn.name, node.lineno) for fn in _functions(tree) for node in _core_attributes(fn)]


def test_no_part_keeps_the_core_or_reads_it_after_construction():
    """Outside core.py and planner.py, ``core.`` is read only in constructors (taking the
    parts a strategy uses), and nothing keeps the core as an attribute."""
    bad, kept = {}, {}
    for name, tree in SOURCES.items():
        if name in OWNERS:
            continue
        if reads := [(fn, line) for fn, line in _reads_of_core(tree) if fn != "__init__"]:
            bad[name] = reads
        if held := [n.lineno for n in _core_attributes(tree) if n.attr == "core"]:
            kept[name] = held
    assert not bad, "the core read outside a constructor"
    assert not kept, "the core kept as an attribute outside core.py and planner.py"


def test_the_checker_finds_a_read_of_the_core_in_a_method():
    tree = ast.parse("class S:\n    def plan(self):\n        return self.core.checks\n")
    assert _reads_of_core(tree) == [("plan", 3)]
    assert _reads_of_core(ast.parse("def f(self):\n    return self.config.core.dt\n")) == []  # settings


def test_no_parameter_is_typed_any():
    """Every part is passed with its type: no parameter of the planner is annotated ``Any``."""
    bad = []
    for name, tree in SOURCES.items():
        for fn in _functions(tree):
            a = fn.args
            for arg in [*a.posonlyargs, *a.args, *a.kwonlyargs]:
                if isinstance(arg.annotation, ast.Name) and arg.annotation.id == "Any":
                    bad.append(f"{name}:{fn.name}({arg.arg})")
    assert not bad


WEIGHTS = (
    "reverse_cost",
    "steer_cost",
    "switch_cost",
    "penetration_cost",
    "w_slack",
    "finish_position",
    "finish_heading",
    "finish_cap",
)


def test_the_prices_weights_are_read_in_cost_py_alone():
    """Every ranking goes through ``cost.py`` and the price functions it shares with the cost
    to go (``common/cost_to_go_config.py``): the weights' names appear in cost.py and config.py
    only, so no module of the planner prices a path by its own sum."""
    found = {}
    for name, tree in SOURCES.items():
        if name in ("cost.py", "config.py"):
            continue
        names = {n.attr for n in ast.walk(tree) if isinstance(n, ast.Attribute)}
        names |= {n.id for n in ast.walk(tree) if isinstance(n, ast.Name)}
        names |= {k.arg for n in ast.walk(tree) if isinstance(n, ast.Call) for k in n.keywords if k.arg}
        hits = sorted(names & set(WEIGHTS))
        if hits:
            found[name] = hits
    assert not found


def test_a_paths_price_worked_by_hand():
    """4 m forward, 2 m reversed, one switch, 1 cm of penetration at two steps:
    4 + 2 (1 + 0.5) + 3 = 10 m, and the penetration 100 x 0.02 = 2 m more."""
    price = PriceConfig()
    ds = np.array([4.0, 2.0])
    assert price_of.path_price(price, ds, np.array([False, True]), 1) == pytest.approx(10.0)
    assert cost.penetration_price(price, np.array([0.01, -0.5, 0.01])) == pytest.approx(2.0)
    real = np.array([[0, 0, 0, 1.0], [4, 0, 0, 1.0], [2, 0, 0, -1.0]])
    assert cost.plan_price(price, real, 1, 5.0) == pytest.approx(15.0)
    assert price_of.move_cost(price, 2.0, reverse=True, steered=True) == pytest.approx(2.0 * 1.55)


def test_the_lattice_and_the_guide_price_by_cost_py():
    """The cost to go's moves and the guide's paths cost what the price functions say under their price."""
    g = Scenario.from_case_id("reverse_rw6.00_sl4.82_sw2.32_th+40_y3.00").build()
    price = PriceConfig(reverse_cost=0.7, steer_cost=0.1, switch_cost=4.0)
    V = CostToGo(g, CostToGoConfig(headings=72, in_slot_arcs=0, entry_length=0, price=price))
    for p, (gear, kappa) in enumerate(zip(V.gear, V.kappa)):
        assert V.cost[p] == price_of.move_cost(price, V.step, gear < 0, kappa != 0.0)
    search = GuideSearch(g, GuideConfig(price=price))
    back = np.array([[2.0 - x, 3.0, 0.0] for x in np.arange(0.0, 2.01, 0.1)])  # 2 m straight back
    assert search._cost(back, gear=1) == pytest.approx(2.0 * 1.7 + 4.0)  # reversed, after a switch


def test_one_preset_table_names_the_registrys_mirror_planners():
    """Each ``mirror*`` planner is one entry; its config selects its strategy."""
    assert [n for n in registry.PLANNERS if n.startswith("mirror")] == list(PRESETS)
    for name, preset in PRESETS.items():
        cfg = preset_config(name)
        assert strategy_for(cfg.strategy) is preset.strategy
        assert all(getattr(cfg.core, k) == v for k, v in preset.core_settings.items())
    with pytest.raises(ValueError, match="unknown 'mirror-fast'; available: mirror, "):
        preset_config("mirror-fast")
    with pytest.raises(ValueError, match="unknown field.*nodelimit"):
        preset_config("mirror", nodelimit=3)
    assert math.isclose(preset_config("mirror-paper", max_iterations=3).core.max_iterations, 3)
