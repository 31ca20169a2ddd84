"""The mirror planner's presets, one table: each name, its strategy, the strategy's config
and the core's settings where they differ from ``CoreConfig``'s defaults. The registry's
``mirror*`` planners are these entries; a new preset is one entry here (and, where it
chooses differently, one small ``Strategy`` subclass with its config).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from mirrorpark_env.config import StrictModel

from .config import (
    AimedConfig,
    ColdConfig,
    CoreConfig,
    GuidedConfig,
    MirrorPlannerConfig,
    MultistartConfig,
    PaperConfig,
)
from .strategies.aimed import AimedCandidates, ColdStart
from .strategies.base import Strategy
from .strategies.guided import Guided
from .strategies.multistart import MultiStart
from .strategies.paper import PaperMultiStart


@dataclass(frozen=True)
class Preset:
    """A named planner: its strategy, the strategy's config, the core's settings where they
    differ from ``CoreConfig``'s defaults, and what it is."""

    strategy: type[Strategy]
    config: StrictModel
    core_settings: dict[str, Any] = field(default_factory=dict)
    doc: str = ""

    def planner_config(self, **changes: Any) -> MirrorPlannerConfig:
        """This preset with ``changes`` applied to whichever part has the field; an unknown
        field is an error naming it and the fields allowed."""
        cfg_type = type(self.config)
        core_fields, strategy_fields = set(CoreConfig.model_fields), set(cfg_type.model_fields) - {"kind"}
        unknown = sorted(set(changes) - core_fields - strategy_fields)
        if unknown:
            raise ValueError(
                f"{cfg_type.__name__}: unknown field(s) {', '.join(unknown)}; "
                f"allowed: {', '.join(sorted(core_fields | strategy_fields))}"
            )
        settings = {**self.core_settings, **{k: v for k, v in changes.items() if k in core_fields}}
        kept = self.config.model_dump(exclude_defaults=True)
        strat = {**kept, **{k: v for k, v in changes.items() if k in strategy_fields}}
        return MirrorPlannerConfig(core=CoreConfig(**settings), strategy=cfg_type(**strat))


# The guided and multi-start planners predate the cost to go's settled ends: their plans may
# end braking, their SCP stops within 6 cm and 0.02 rad, and one terminal weight serves every
# slot (as Eq. 33 has it). No budget per call either: their calls are bounded by their
# candidates' node budgets alone.
_GUIDED_CORE = {
    "end_settled": False,
    "settle_position": 0.06,
    "settle_heading": 0.02,
    "lateral_window": 0.0,
    "call_qp_budget": None,
}

PRESETS: dict[str, Preset] = {
    "mirror": Preset(AimedCandidates, AimedConfig(), doc="the default: candidates aimed and compared by a cost to go"),
    "mirror-exhaustive": Preset(
        AimedCandidates, AimedConfig(margin=None), doc="mirror solving every candidate: what best first costs"
    ),
    "mirror-cold": Preset(
        ColdStart, ColdConfig(), doc="mirror without any path as a warm start (shape seeds): what the warm start adds"
    ),
    "mirror-paper": Preset(
        PaperMultiStart,
        PaperConfig(),
        # Algorithm I runs up to 12 rounds per candidate, twice the multi-start's: its rounds
        # also wait for the model's speeds and angle to settle (32.8 % of the ablation's cases
        # against 27.6 % with 6). A car still creeping (under 5 cm/s) against a candidate's
        # gear may stop first: its plans end with the lag still pushing, and the gear's bound
        # from step 1 left it no plan the other way (docs/mirror_planner.md).
        {**_GUIDED_CORE, "max_iterations": 12, "stop_first_speed": 0.05},
        doc="the paper's fixed-angle linearisation, multi-start",
    ),
    "mirror-guided": Preset(
        Guided, GuidedConfig(), _GUIDED_CORE, doc="the geometric guide chooses, the QP polishes (the ablation)"
    ),
    "mirror-multistart": Preset(
        MultiStart, MultistartConfig(), _GUIDED_CORE, doc="neither guide nor cost to go: shape seeds"
    ),
}

# Each strategy config's type and the strategy it configures (a config names one).
_STRATEGIES: dict[type, type[Strategy]] = {type(p.config): p.strategy for p in PRESETS.values()}


def preset_config(name: str, **changes: Any) -> MirrorPlannerConfig:
    """The config of preset ``name`` with ``changes`` (fields of the core or the strategy)."""
    if name not in PRESETS:
        raise ValueError(f"preset: unknown {name!r}; available: {', '.join(PRESETS)}")
    return PRESETS[name].planner_config(**changes)


def strategy_for(config: StrictModel) -> type[Strategy]:
    """The strategy a strategy config configures."""
    return _STRATEGIES[type(config)]
