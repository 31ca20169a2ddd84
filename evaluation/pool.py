"""Worker processes for a run: items in runs per group, each result back as it is done,
a dead worker noticed at once (``run_parallel``)."""

from __future__ import annotations

import ctypes
import multiprocessing as mp
import os
import pickle
import signal
import sys
from collections.abc import Callable, Hashable
from multiprocessing.connection import wait
from typing import Any

from . import registry

__all__ = ["WorkerDied", "batches", "run_parallel"]


def _worker_signals() -> None:
    """Workers leave Ctrl-C to the parent, which stops them and keeps what is stored, and
    die at SIGTERM, which is how the parent stops them (a forked worker would otherwise
    inherit the command line's SIGTERM handler)."""

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    if sys.platform.startswith("linux"):  # die with the parent, however it dies: SIGKILL leaves it no clean-up
        PR_SET_PDEATHSIG = 1
        ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, signal.SIGKILL)


class WorkerDied(RuntimeError):
    """A worker process ended while it ran an item (killed, out of memory, ``os._exit``)."""


def run_parallel(
    fn: Callable[[Any], Any],
    items: list,
    keep: Callable[[Any], None],
    workers: int,
    group: Callable[[Any], Hashable] | None = None,
    batch: int = 8,
    describe: Callable[[Any], str] = repr,
) -> None:
    """``keep(fn(item))`` for every item, in ``workers`` processes, as each finishes.

    ``fn`` must be a module-level function (it is pickled for the workers); no more workers
    start than there are items. ``group(item)`` (optional) names what items may share: items
    of one group, in the order given, go to one worker in runs of up to ``batch``, so that
    what a planner builds once per slot (``planners.common.slot_cache``) is built once per
    run, not once in every worker that meets the slot. Results do not change, only the
    work. Each item's result comes back as soon as it is done, not with its run: an
    interruption loses only the items in progress.

    A worker that dies while it runs an item stops the run within about a second with
    ``WorkerDied``, naming the item (``describe(item)``); an item whose ``fn`` raises stops
    it with that exception (one that is not an ``Exception``, such as a ``KeyboardInterrupt``
    a planner raises itself, with ``WorkerDied`` saying so). Either way every worker is
    stopped before this returns.
    """
    runs = [
        list(run) for run in batches(list(enumerate(items)), None if group is None else lambda it: group(it[1]), batch)
    ]
    if not runs:
        return
    ctx, extra = _pool_context()
    todo = list(reversed(runs))  # popped from the end: in order
    pool: list[_Worker] = []
    left = len(items)
    try:
        for _ in range(min(workers, len(runs))):
            pool.append(_Worker.start(ctx, fn, extra))
            pool[-1].give(todo.pop())
        while left:
            ready = wait([w.conn for w in pool] + [w.proc.sentinel for w in pool], timeout=1.0)
            for w in list(pool):
                if w.conn not in ready and w.proc.sentinel not in ready:
                    continue
                for msg in w.messages():
                    kind = msg[0]
                    if kind == "done":
                        keep(msg[2])
                        left -= 1
                    elif kind == "error":
                        raise msg[2]
                    elif kind == "abort":  # not an Exception (KeyboardInterrupt, SystemExit): the run stops
                        raise WorkerDied(f"{describe(items[msg[1]])} raised {msg[2]}")
                    elif kind == "idle":
                        w.runs_done += 1
                        w.run = None
                        if w.runs_done >= _RUNS_PER_WORKER and todo:  # a fresh process now and then
                            w.stop()
                            pool[pool.index(w)] = w = _Worker.start(ctx, fn, extra)
                        if todo:
                            w.give(todo.pop())
                if not w.proc.is_alive() and w.run is not None:
                    w.proc.join(1.0)
                    what = describe(items[w.in_hand()])
                    raise WorkerDied(
                        f"a worker process (PID {w.proc.pid}) died ({_exit_name(w.proc.exitcode)}) while running {what}"
                    )
    finally:
        for w in pool:
            w.stop()


_RUNS_PER_WORKER = 200  # a worker is replaced after this many runs (what a long run leaks, it frees)


class _Worker:
    """One worker process, its end of a pipe, the run it was given and the item in hand."""

    def __init__(self, proc, conn) -> None:
        self.proc, self.conn = proc, conn
        self.run: list | None = None
        self.finished = 0  # items of ``run`` done
        self.current: int | None = None
        self.runs_done = 0

    @classmethod
    def start(cls, ctx, fn, extra) -> _Worker:
        mine, theirs = ctx.Pipe()
        proc = ctx.Process(target=_worker_main, args=(theirs, fn, extra), daemon=True)
        proc.start()
        theirs.close()
        return cls(proc, mine)

    def give(self, run: list) -> None:
        self.run, self.finished = run, 0
        self.conn.send(run)

    def in_hand(self) -> int:
        """The index of the item the worker runs (or was about to start): its last ``start``,
        else the first of its run not finished."""
        return self.current if self.current is not None else self.run[min(self.finished, len(self.run) - 1)][0]

    def messages(self) -> list[tuple]:
        """What the worker has sent so far (all of it, once it has ended)."""
        out = []
        try:
            while self.conn.poll():
                msg = self.conn.recv()
                if msg[0] == "start":
                    self.current = msg[1]
                else:
                    if msg[0] == "done":
                        self.current = None
                        self.finished += 1
                    out.append(msg)
        except (EOFError, OSError):  # the worker is gone; its sentinel says so
            pass
        return out

    def stop(self) -> None:
        if self.proc.is_alive():
            try:
                self.conn.send(None)
            except OSError:
                pass
            self.proc.join(0.2)
        if self.proc.is_alive():
            self.proc.terminate()  # SIGTERM: a worker dies at once (``_worker_signals``)
            self.proc.join(2.0)
        if self.proc.is_alive():
            self.proc.kill()
            self.proc.join(2.0)
        self.conn.close()


def _exit_name(code: int | None) -> str:
    if code is not None and code < 0:
        try:
            return signal.Signals(-code).name
        except ValueError:
            return f"signal {-code}"
    return f"exit code {code}"


def _worker_main(conn, fn, extra: dict) -> None:
    """A worker: runs of (index, item) in, ``start``/``done`` per item and ``idle`` per run out."""
    _init_worker(extra)
    while True:
        try:
            run = conn.recv()
        except EOFError:
            return
        if run is None:
            return
        for idx, item in run:
            conn.send(("start", idx))
            try:
                out = fn(item)
            except Exception as err:  # noqa: BLE001 - sent to the parent, which raises it
                conn.send(("error", idx, _sendable(err)))
                return
            except BaseException as err:  # noqa: BLE001 - SIGINT is the parent's: the item raised it itself
                conn.send(("abort", idx, f"{type(err).__name__}: {err}"))
                return
            conn.send(("done", idx, out))
        conn.send(("idle",))


def _sendable(err: Exception) -> Exception:
    """``err`` as the parent can raise it: itself where it pickles, else a ``RuntimeError``."""
    try:
        pickle.loads(pickle.dumps(err))
        return err
    except Exception:  # noqa: BLE001
        return RuntimeError(f"{type(err).__name__}: {err}")


def batches(items: list, group: Callable[[Any], Hashable] | None = None, batch: int = 8) -> list[list]:
    """``items`` in order, cut into runs of one group each (``group(item)``; None: one run
    per item), none longer than ``batch``."""
    if batch < 1:
        raise ValueError(f"batch: must be >= 1, got {batch}")
    if group is None:
        return [[item] for item in items]
    runs: list[list] = []
    last = object()
    for item in items:
        key = group(item)
        if not runs or key != last or len(runs[-1]) >= batch:
            runs.append([])
        runs[-1].append(item)
        last = key
    return runs


def _pool_context():
    """The start method for worker processes, and the planners the workers must be told of.

    ``fork`` is cheap and keeps planners registered at run time (a script's or a notebook's
    own), but a fork copies every lock as it was: one held by another thread of the parent
    (an I/O thread, a progress bar's, a thread pool's) stays held in the child for good, and the
    worker hangs. So fork only a single-threaded process; otherwise start the workers from a
    fresh ``forkserver`` and pass them the planners registered at run time by reference.
    """

    extra = {k: f for k, f in registry.PLANNERS.items() if registry.BUILTIN.get(k) is not f}
    if not hasattr(os, "fork"):
        return mp.get_context("spawn"), extra
    if _native_threads() == 1 or any(getattr(f, "__module__", None) == "__main__" for f in extra.values()):
        # A planner defined in __main__ (``python -c``, a notebook) exists only in a fork.
        return mp.get_context("fork"), {}
    ctx = mp.get_context("forkserver")
    ctx.set_forkserver_preload(["evaluation.runner", "evaluation.pool", "evaluation.registry", "mirrorpark_env"])
    return ctx, extra


def _native_threads() -> int:
    try:
        return len(os.listdir("/proc/self/task"))  # every thread, those of C libraries too
    except OSError:
        import threading

        return threading.active_count()


def _init_worker(extra: dict) -> None:
    """Workers leave Ctrl-C to the parent and know the planners registered at run time."""

    _worker_signals()
    registry.PLANNERS.update(extra)
