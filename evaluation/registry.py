"""Planners by name: the only place the evaluation learns which policies exist."""

from __future__ import annotations

import importlib
from collections.abc import Callable
from functools import partial
from importlib.metadata import entry_points

from planners.base import Policy
from planners.common.slot_frame import InSlotFrame
from planners.hybrid_astar.policy import HybridAStarPolicy
from planners.mirror.guide_policy import GuideOnlyPolicy
from planners.mirror.policy import MirrorPolicy
from planners.mirror.presets import PRESETS as MIRROR_PRESETS
from planners.mirror.presets import preset_config


def _in_slot_frame(policy: Policy) -> Policy:
    """The mirror planner's parts plan in the slot's frame: any layout with a slot."""

    return InSlotFrame(policy)


def mirror_policy(config) -> Policy:
    """A ``MirrorPolicy`` under ``config`` (a ``planners.mirror.config.MirrorPlannerConfig``),
    planning in the slot's frame as the registry's mirror planners do."""

    return _in_slot_frame(MirrorPolicy(config))


def _mirror(preset: str) -> Policy:
    """``MirrorPolicy`` with the settings of ``preset`` (``planners.mirror.presets``)."""
    return mirror_policy(preset_config(preset))


def _guide_only() -> Policy:

    return _in_slot_frame(GuideOnlyPolicy())


def _hybrid_astar() -> Policy:

    return HybridAStarPolicy()


PLANNERS: dict[str, Callable[[], Policy]] = {
    **{name: partial(_mirror, name) for name in MIRROR_PRESETS},  # planners/mirror/presets.py, in its order
    "guide-only": _guide_only,  # the geometric guide tracked, no QP (the ablation)
    "hybrid-astar": _hybrid_astar,  # the search-based baseline
}

# Names that changed meaning or were dropped, with what to use instead (make_policy says so).
RENAMED = {
    "mirror-value": "mirror (renamed on 2026-12-02, when it became the default)",
    "mirror-value-cold": "mirror-cold (renamed on 2026-12-02)",
}


BUILTIN = dict(PLANNERS)  # those above; others are registered at run time (evaluation.runner passes them on)

# The main job's and the benchmark's default set: the paper's comparison (the mirror planner
# against the search-based baseline) and the guide alone, the ablation that runs in seconds.
MAIN = ("mirror", "hybrid-astar", "guide-only")


ENTRY_POINTS = "mirrorpark.planners"  # the group through which an installed package adds planners


def _entry_points() -> dict:
    """Installed packages' planners: entry points of ``ENTRY_POINTS``, by name."""

    return {ep.name: ep for ep in entry_points(group=ENTRY_POINTS)}


def available() -> list[str]:
    """Named planners, the installed plug-ins' too; a trained RL model is named ``rl:PATH``
    and any importable factory ``package.module:factory`` (see ``make_policy``)."""
    return list(PLANNERS) + sorted(set(_entry_points()) - set(PLANNERS))


def _built(what: str, factory) -> Policy:
    """``factory()``, checked to be a ``Policy``; one-line errors naming ``what``."""
    try:
        policy = factory()
    except Exception as err:  # noqa: BLE001 - a plug-in's own failure, reported in one line
        raise ValueError(f"planner: {what} raised {type(err).__name__}: {err}") from None
    missing = [m for m in ("reset", "act") if not callable(getattr(policy, m, None))]
    missing += [a for a in ("stats", "status", "gave_up") if not hasattr(policy, a)]
    if missing:
        raise ValueError(
            f"planner: {what} returned a {type(policy).__name__}, not a Policy (missing: {', '.join(missing)}; "
            "subclass planners.base.Policy)"
        )
    return policy


def _plugin(name: str) -> Policy:
    """The policy of ``package.module:factory``: any importable callable that returns one."""

    module, _, attr = name.partition(":")
    if not module or not attr:
        raise ValueError(f"planner: {name!r}: a plug-in is named package.module:factory")
    try:
        mod = importlib.import_module(module)
    except Exception as err:  # noqa: BLE001 - not importable, or failing on import: one line
        raise ValueError(f"planner: cannot import {module!r} ({type(err).__name__}: {err})") from None
    factory = getattr(mod, attr, None)
    if not callable(factory):
        raise ValueError(f"planner: module {module!r} has no callable {attr!r}")
    return _built(name, factory)


def make_policy(name: str) -> Policy:
    """A fresh policy for ``name``; raises ``ValueError`` naming the available planners.

    ``rl:PATH`` loads the model file PATH, which unpickles code: name only files you trust;
    ``rl-shield:PATH`` runs it inside a safety filter (``planners/rl/shield.py``).
    ``package.module:factory`` calls any importable factory (a plug-in planner; each worker
    imports it by name, so it reaches workers on every start method), and an installed
    package's entry point in the group ``mirrorpark.planners`` adds a name.
    """
    if name.startswith("rl-shield:"):  # the learner inside a safety filter: a separate row
        from planners.rl.policy import RLPolicy
        from planners.rl.shield import Shielded

        if not name[10:].strip():
            raise ValueError("planner: 'rl-shield:' needs a model file after it, e.g. rl-shield:results/rl/model.zip")
        return Shielded(RLPolicy(name[10:]))
    if name.startswith("rl:"):
        if not name[3:].strip():
            raise ValueError("planner: 'rl:' needs a model file after it, e.g. rl:results/rl/model.zip")
        from planners.rl.policy import RLPolicy

        return RLPolicy(name[3:])
    factory = PLANNERS.get(name)
    if factory is None and ":" in name:
        return _plugin(name)
    if factory is None and name in _entry_points():
        ep = _entry_points()[name]
        try:
            loaded = ep.load()
        except Exception as err:  # noqa: BLE001 - an installed plug-in that does not load: one line
            raise ValueError(
                f"planner: plug-in {name!r} ({ep.value}) does not load ({type(err).__name__}: {err})"
            ) from None
        return _built(f"plug-in {name!r} ({ep.value})", loaded)
    if factory is None and name in RENAMED:
        raise ValueError(f"planner: {name!r} is now {RENAMED[name]}; available: {', '.join(available())}, rl:PATH")
    if factory is None:
        raise ValueError(
            f"planner: unknown {name!r}; available: {', '.join(available())}, rl:PATH, package.module:factory"
        )
    return factory()
