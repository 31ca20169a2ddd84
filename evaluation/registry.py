"""Planners by name: the only place the evaluation learns which policies exist."""

from __future__ import annotations

from collections.abc import Callable
from functools import partial

from planners.base import Policy


def _in_slot_frame(policy: Policy) -> Policy:
    """The mirror planner's parts plan in the slot's frame: any layout with a slot."""
    from planners.common.slot_frame import InSlotFrame

    return InSlotFrame(policy)


def mirror_policy(config) -> Policy:
    """A ``MirrorPolicy`` under ``config`` (a ``planners.mirror.config.MirrorPlannerConfig``),
    planning in the slot's frame as the registry's mirror planners do."""
    from planners.mirror.policy import MirrorPolicy

    return _in_slot_frame(MirrorPolicy(config))


def _mirror(preset: str) -> Policy:
    """``MirrorPolicy`` with the settings ``planners.mirror.config.<preset>()``."""
    from planners.mirror import config

    return mirror_policy(getattr(config, preset)())


def _guide_only() -> Policy:
    from planners.mirror.guide_policy import GuideOnlyPolicy

    return _in_slot_frame(GuideOnlyPolicy())


def _hybrid_astar() -> Policy:
    from planners.hybrid_astar.policy import HybridAStarPolicy

    return HybridAStarPolicy()


PLANNERS: dict[str, Callable[[], Policy]] = {
    "mirror": partial(_mirror, "mirror_config"),  # the default: candidates aimed and compared by a cost to go
    "mirror-cold": partial(_mirror, "cold_config"),  # the same without any path as warm start (shape seeds)
    "mirror-paper": partial(_mirror, "paper_config"),  # the paper's fixed-angle linearisation, multi-start
    "mirror-guided": partial(_mirror, "guided_config"),  # the geometric guide chooses, the QP polishes (the ablation)
    "mirror-multistart": partial(_mirror, "multistart_config"),  # neither guide nor cost to go: shape seeds
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


def available() -> list[str]:
    """Named planners; a trained RL model is named ``rl:PATH`` (see ``make_policy``)."""
    return list(PLANNERS)


def make_policy(name: str) -> Policy:
    """A fresh policy for ``name``; raises ``ValueError`` naming the available planners.

    ``rl:PATH`` loads the model file PATH, which unpickles code: name only files you trust;
    ``rl-shield:PATH`` runs it inside a safety filter (``planners/rl/shield.py``).
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
    if factory is None and name in RENAMED:
        raise ValueError(f"planner: {name!r} is now {RENAMED[name]}; available: {', '.join(available())}, rl:PATH")
    if factory is None:
        raise ValueError(f"planner: unknown {name!r}; available: {', '.join(available())}, rl:PATH")
    return factory()
