"""Planners by name: the only place the evaluation learns which policies exist."""

from __future__ import annotations

from collections.abc import Callable

from planners.base import Policy


def _mirror() -> Policy:
    from planners.mirror.policy import MirrorPolicy

    return MirrorPolicy()


def _mirror_paper() -> Policy:
    from planners.mirror.planner import MirrorPlannerConfig
    from planners.mirror.policy import MirrorPolicy

    return MirrorPolicy(MirrorPlannerConfig(linearisation="paper"))


def _hybrid_astar() -> Policy:
    from planners.hybrid_astar.policy import HybridAStarPolicy

    return HybridAStarPolicy()


PLANNERS: dict[str, Callable[[], Policy]] = {
    "mirror": _mirror,  # SCP re-linearisation (the default)
    "mirror-paper": _mirror_paper,  # the paper's fixed-angle linearisation, for comparison
    "hybrid-astar": _hybrid_astar,  # the search-based baseline
}
PLANNED = {"rl:PATH": "issue 6 (RL baseline)"}


def available() -> list[str]:
    return list(PLANNERS)


def make_policy(name: str) -> Policy:
    """A fresh policy for ``name``; raises ``ValueError`` naming the available planners."""
    factory = PLANNERS.get(name)
    if factory is None:
        key = "rl:PATH" if name.startswith("rl:") else name
        later = f" ({PLANNED[key]} has not landed yet)" if key in PLANNED else ""
        raise ValueError(f"planner: unknown {name!r}{later}; available: {', '.join(available())}")
    return factory()
