"""``mirror-paper``: the paper's method as written, on the multi-start.

Each candidate is solved on the fixed-angle model of Eqs. (22)-(32) (``linearisation.PaperModel``)
in place of SCP's Jacobians, Algorithm I adding obstacle rows until the rollout is clear.
What the paper leaves open is decided in ``config.PaperConfig``.
"""

from __future__ import annotations

from ..config import PaperConfig
from ..linearisation import RoundsFactory, paper_model
from .multistart import MultiStart


class PaperMultiStart(MultiStart):
    """The multi-start on the paper's model."""

    @classmethod
    def rounds(cls, config: PaperConfig) -> RoundsFactory:
        return paper_model(config)
