"""Plug-in planners: ``package.module:factory`` and the ``mirrorpark.planners`` entry points,
one-line errors for each way a plug-in can be wrong, and ``check_policy``."""

from __future__ import annotations

import textwrap
from pathlib import Path

import pytest

from evaluation import registry
from evaluation.check_policy import check_policy
from evaluation.cli import main
from evaluation.registry import make_policy
from planners.base import Policy

PLUGIN = textwrap.dedent(
    """
    import numpy as np
    from planners.base import Policy, PlanStats

    class Creep(Policy):
        name = "creep"

        def reset(self, geometry):
            self.stats = [PlanStats(0.0, "ok")]

        def act(self, obs, info):
            return np.array([-0.05, 0.0], dtype=np.float32)  # reverses slowly, straight

    def make():
        return Creep()

    def broken():
        raise RuntimeError("no licence server")

    def not_a_policy():
        return object()

    class Wrong(Creep):
        def act(self, obs, info):
            return np.array([2.0, 0.0, 1.0])

    def wrong():
        return Wrong()

    class Loud(Creep):
        def act(self, obs, info):
            return np.array([3.0, 0.0], dtype=np.float32)  # beyond the normalised range

    def loud():
        return Loud()

    class NoReset:  # a duck that forgot reset
        name, stats, status, gave_up = "noreset", [], "ok", False

        def act(self, obs, info):
            return np.zeros(2, dtype=np.float32)

    def noreset():
        return NoReset()
    """
)


@pytest.fixture
def plugin(tmp_path, monkeypatch):
    (tmp_path / "myplug.py").write_text(PLUGIN)
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setenv("PYTHONPATH", str(tmp_path))  # for workers started afresh
    return "myplug"


def test_a_factory_by_module_and_name_is_a_planner(plugin):
    p = make_policy(f"{plugin}:make")
    assert isinstance(p, Policy) and p.name == "creep"
    assert check_policy(p) == []


@pytest.mark.parametrize(
    "name, message",
    [
        ("nosuch_mod:make", r"cannot import 'nosuch_mod' \(ModuleNotFoundError"),
        ("myplug:absent", r"module 'myplug' has no callable 'absent'"),
        ("myplug:broken", r"myplug:broken raised RuntimeError: no licence server"),
        ("myplug:not_a_policy", r"returned a object, not a Policy \(missing: reset, act, stats, status, gave_up"),
        (":make", r"a plug-in is named package.module:factory"),
    ],
)
def test_every_way_a_plugin_is_wrong_is_one_line(plugin, name, message, tmp_path, capsys):
    with pytest.raises(ValueError, match=message) as err:
        make_policy(name)
    assert "\n" not in str(err.value)
    # The CLI: exit code 2, one line, no traceback, before any case runs.
    args = ["evaluate", "--planner", name, "--sample", "smoke", "--chunk", "1/90", "--out", str(tmp_path / "r")]
    assert main([*args, "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and err.startswith("mirrorpark: error: ") and "Traceback" not in err
    assert not (tmp_path / "r").exists()


def test_check_policy_names_what_breaks_the_contract(plugin):
    problems = check_policy(make_policy(f"{plugin}:wrong"))
    assert problems == ["act at step 0: the action has shape (3,), not (2,) [accel, steer]"]
    (loud,) = check_policy(make_policy(f"{plugin}:loud"))
    assert loud.startswith("act at step 0: the action [3.0, 0.0] leaves [-1, 1]")
    import myplug

    assert check_policy(myplug.NoReset()) == [
        "reset(geometry) raised AttributeError: 'NoReset' object has no attribute 'reset'"
    ]
    with pytest.raises(ValueError, match=r"not a Policy \(missing: reset;"):
        make_policy(f"{plugin}:noreset")


class _EntryPoint:
    def __init__(self, name, value, target):
        self.name, self.value, self._target = name, value, target

    def load(self):
        if isinstance(self._target, Exception):
            raise self._target
        return self._target


def test_an_installed_packages_entry_point_adds_a_name(plugin, monkeypatch):
    import myplug

    eps = {
        "creep": _EntryPoint("creep", "myplug:make", myplug.make),
        "gone": _EntryPoint("gone", "oldpkg:make", ImportError("No module named 'oldpkg'")),
    }
    monkeypatch.setattr(registry, "_entry_points", lambda: eps)
    assert "creep" in registry.available() and registry.available()[: len(registry.PLANNERS)] == list(registry.PLANNERS)
    assert make_policy("creep").name == "creep"
    with pytest.raises(ValueError, match=r"plug-in 'gone' \(oldpkg:make\) does not load \(ImportError"):
        make_policy("gone")


@pytest.mark.slow
def test_a_plugin_runs_on_two_workers_and_the_cli_checks_it(plugin, tmp_path, capsys):
    """Workers import the plug-in by its name, whatever their start method."""
    from evaluation.store import read_results

    out = tmp_path / "r"
    args = ["evaluate", "--planner", f"{plugin}:make", "--sample", "smoke", "--chunk", "1/45", "--out", str(out)]
    assert main([*args, "--workers", "2", "--quiet"]) == 0
    df = read_results([out])
    assert len(df) == 2 and (df["planner"] == f"{plugin}:make").all() and df["error"].isna().all()
    assert main(["check-planner", f"{plugin}:wrong"]) == 1
    assert "the action has shape (3,)" in capsys.readouterr().err
    assert main(["check-planner", f"{plugin}:make"]) == 0


def test_the_builtin_planners_keep_the_contract():
    for name in ("guide-only", "mirror-guided"):
        assert check_policy(make_policy(name), steps=10) == [], name


EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "rs-planner"
# Runs the CLI with the workers' start method forced (a fresh interpreter: its own forkserver).
FORCED = textwrap.dedent(
    """
    import multiprocessing as mp, sys
    from evaluation import pool

    def forced():
        ctx = mp.get_context(sys.argv[1])
        return ctx, {}

    pool._pool_context = forced
    from evaluation.cli import main
    sys.exit(main(sys.argv[2:]))
    """
)


@pytest.mark.slow
@pytest.mark.parametrize("method", ["fork", "forkserver"])
def test_the_example_package_by_entry_point_and_by_factory_on_two_workers(method, tmp_path):
    """examples/rs-planner, found by the entry point its pyproject.toml declares (read from
    a distribution's metadata on the path, as pip installs it) and by ``rs_planner:make``,
    scored on two workers started by ``fork`` and by ``forkserver``."""
    import os
    import re
    import subprocess
    import sys

    from evaluation.store import read_results

    toml = (EXAMPLE / "pyproject.toml").read_text()  # (tomllib is Python 3.11+)
    section = toml.split('[project.entry-points."mirrorpark.planners"]', 1)[1]
    name, target = re.search(r'^\s*([\w-]+)\s*=\s*"([^"]+)"', section, re.M).groups()
    dist = tmp_path / "site" / "mirrorpark_rs_example-0.1.0.dist-info"
    dist.mkdir(parents=True)
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: mirrorpark-rs-example\nVersion: 0.1.0\n")
    (dist / "entry_points.txt").write_text(f"[mirrorpark.planners]\n{name} = {target}\n")
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(EXAMPLE), str(tmp_path / "site"), os.getcwd()]))
    for planner in (name, target):
        out = tmp_path / planner.replace(":", "_")
        args = ["evaluate", "--planner", planner, "--sample", "smoke", "--chunk", "1/45", "--workers", "2"]
        done = subprocess.run(
            [sys.executable, "-c", FORCED, method, *args, "--out", str(out), "--quiet"],
            env=env,
            capture_output=True,
            text=True,
            timeout=600,
        )
        assert done.returncode == 0, done.stderr
        df = read_results([out])
        assert len(df) == 2 and (df["planner"] == planner).all() and df["error"].isna().all()
