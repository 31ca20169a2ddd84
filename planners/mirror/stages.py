"""A planning call's bookkeeping: where its wall time goes, stage by stage (for
``mirrorpark bench``), and the QP solves its work budget has left.

A call's time is split into: the QP and branch-and-bound solves (``solve``), building the
QPs (linearisation and rows, ``build``), rollouts and footprint checks (``checks``),
reading the cost to go (``cost_to_go``) and making seeds (``seeds``); the rest of the
call is "other". Timing costs about a microsecond a section, a few hundred a call.
"""

from __future__ import annotations

import math
import time

STAGES = ("solve", "build", "checks", "cost_to_go", "seeds")


class StageClock:
    """Seconds per stage since ``reset``; ``with clock("solve"): ...`` times a section.

    Sections may nest in different stages (a seed's rollout inside ``seeds``): the inner
    one's time is taken out of the outer one, so that the stages add up to at most the call."""

    def __init__(self) -> None:
        self.seconds = dict.fromkeys(STAGES, 0.0)
        self._stack: list[_Section] = []

    def reset(self) -> None:
        self.seconds = dict.fromkeys(STAGES, 0.0)
        self._stack.clear()

    def __call__(self, stage: str) -> _Section:
        if stage not in self.seconds:
            raise ValueError(f"stage: must be one of {STAGES}, got {stage!r}")
        return _Section(self, stage)

    def ms(self) -> dict[str, float]:
        """Milliseconds per stage, rounded to microseconds."""
        return {k: round(1e3 * v, 3) for k, v in self.seconds.items()}


class _Section:
    __slots__ = ("clock", "stage", "t0", "inner")

    def __init__(self, clock: StageClock, stage: str) -> None:
        self.clock, self.stage = clock, stage

    def __enter__(self) -> None:
        self.inner = 0.0
        self.clock._stack.append(self)
        self.t0 = time.perf_counter()

    def __exit__(self, *exc) -> None:
        dt = time.perf_counter() - self.t0
        stack = self.clock._stack
        stack.pop()
        self.clock.seconds[self.stage] += dt - self.inner
        if stack:
            stack[-1].inner += dt


class CallBudget:
    """QP solves left to the current call (``CoreConfig.call_qp_budget``; None: no limit)."""

    def __init__(self, limit: int | None):
        self.limit = limit
        self.left: float = math.inf

    def reset(self) -> None:
        self.left = math.inf if self.limit is None else self.limit

    def spend(self, solves: int) -> None:
        self.left -= solves

    @property
    def spent(self) -> bool:
        return self.left <= 0
