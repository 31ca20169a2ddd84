"""A wall-clock safety net for each planner call: a plug-in that hangs becomes its case's
error row instead of a run that never ends.

Budgets in work (QP solves, expansions) are what stop our planners; this limit is only a
net, far above any call they make (the longest in the committed full-grid rows: under 10 s).
It uses ``SIGALRM``, so it acts in the main thread of a POSIX process (each worker's, or
the command's with one worker) and stops Python code and sleeps; a call stuck inside
compiled code that never returns to Python is not stopped (kill its worker: the run then
names the case, ``pool.WorkerDied``).
"""

from __future__ import annotations

import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

CALL_LIMIT_S = 60.0  # the default net per reset or act, seconds (``evaluate --call-limit``)


class CallTimeout(BaseException):
    """A planner call ran past the limit. A ``BaseException``, so that a planner's own
    ``except Exception`` does not swallow it."""


def usable() -> bool:
    """Whether the net can act here (a POSIX process's main thread)."""
    return hasattr(signal, "setitimer") and threading.current_thread() is threading.main_thread()


class Limited:
    """``policy`` with each ``reset`` and ``act`` stopped by ``CallTimeout`` after ``seconds``
    of wall time; everything else is the policy's own."""

    def __init__(self, policy: Any, seconds: float) -> None:
        self._policy = policy
        self._seconds = seconds

    def __getattr__(self, name: str) -> Any:
        return getattr(self._policy, name)

    def reset(self, geometry: Any) -> Any:
        with self._timer("reset"):
            return self._policy.reset(geometry)

    def act(self, obs: Any, info: Any) -> Any:
        with self._timer("act"):
            return self._policy.act(obs, info)

    @contextmanager
    def _timer(self, what: str) -> Iterator[None]:
        def over(signum, frame):
            raise CallTimeout(f"{what} ran past the {self._seconds:g} s safety net per call (evaluate --call-limit)")

        before = signal.signal(signal.SIGALRM, over)
        signal.setitimer(signal.ITIMER_REAL, self._seconds)
        try:
            yield
        finally:
            signal.setitimer(signal.ITIMER_REAL, 0)
            signal.signal(signal.SIGALRM, before)


def limited(policy: Any, seconds: float | None) -> Any:
    """``policy`` under the net of ``seconds`` (None or 0: none, or where it cannot act)."""
    if not seconds or not usable():
        return policy
    return Limited(policy, float(seconds))
