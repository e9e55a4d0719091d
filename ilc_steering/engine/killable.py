"""Calls in worker processes that this process can kill: the local backend's way to run cells with
a time limit and a failure each (:func:`~ilc_steering.engine.backends.run_calls` with ``failed``).

Each worker is a spawned process serving one call at a time over a pipe (:func:`_serve`). A call
past its time limit is ended with its process (a learner that swallows the exception, an optimizer
that never returns, a ``nogil`` compiled loop) and a worker that dies (``os._exit``, a crash) is
that call's failure; either way a fresh worker takes the next call. A call's clock starts when its
worker holds it, imports done (:data:`STARTED`), and a worker that has not said so by the limit
plus :data:`STARTUP_ALLOWANCE` is stopped too.
"""

from __future__ import annotations

import multiprocessing
import multiprocessing.connection
import time
from collections.abc import Callable, Mapping
from typing import Any

from ilc_steering.core.cable import owned, stop_group, watch

__all__ = ["GROUP", "STARTED", "STARTUP_ALLOWANCE", "Failed", "Finish", "killable_map"]

Finish = Callable[[Any, Any], None]
"""``finish(key, result)``: a call's result, handed over in the calling process as it arrives."""
Failed = Callable[[Any, str], None]
"""``failed(key, message)``: a call that raised, outlived its time limit or lost its worker."""

STARTUP_ALLOWANCE = 60.0
"""[s] a fresh worker's imports before its call starts, on top of the call's time limit."""
STARTED = "started"
"""What a killable worker sends once it holds its call, imports done: the call's clock starts then."""
GROUP = "group"
"""What a killable worker sends, with a process group and whether it started, of each robot program it runs."""


def _serve(connection: Any) -> None:
    """A killable worker's loop: run each ``(function, args)`` it is sent and send back ``(True,
    result)`` or ``(False, message)``, until it is sent None or its parent goes. A robot program a
    call starts is stopped when the call ends (:func:`~ilc_steering.core.cable.owned`), and its
    process group is told to the parent as it starts and stops (``(GROUP, group, started)``), so
    that the parent stops it when it kills this worker."""
    watch(lambda group, started: connection.send((GROUP, group, started)))
    while True:
        try:
            task = connection.recv()
        except (EOFError, OSError):
            return
        if task is None:
            return
        function, args = task  # unpickled: the function's modules are imported by now
        connection.send(STARTED)  # the cell's time limit starts here, not at the worker's imports
        try:
            with owned():
                outcome: tuple[bool, Any] = (True, function(*args))
        except Exception as error:
            outcome = (False, f"{type(error).__name__}: {error}")
        try:
            connection.send(outcome)
        except Exception as error:  # a result that cannot be pickled
            connection.send((False, f"its result cannot be sent back: {type(error).__name__}: {error}"))


class _Worker:
    """A spawned worker process and its end of the pipe, with the call it runs and its deadline."""

    def __init__(self) -> None:
        context = multiprocessing.get_context("spawn")
        self.connection, theirs = context.Pipe()
        self.process = context.Process(target=_serve, args=(theirs,), daemon=True)
        self.process.start()
        theirs.close()
        self.key: Any = None
        self.deadline: float | None = None
        self.groups: set[int] = set()  # the process groups of the robot programs its call runs

    def stop(self, kill: bool = False) -> None:
        if kill:
            self.process.kill()
            for group in self.groups:  # its robot programs, which it can no longer stop itself
                stop_group(group)
            self.groups.clear()
        else:
            try:
                self.connection.send(None)
            except OSError:
                self.process.kill()
        self.process.join(5)
        if self.process.is_alive():
            self.process.kill()
            self.process.join()
        self.connection.close()


def killable_map(
    function: Callable[..., Any],
    calls: Mapping[Any, tuple[Any, ...]],
    count: int,
    finish: Finish,
    failed: Failed,
    timeout: float | None,
) -> None:
    """Every call in ``count`` spawned worker processes, each call's process killed when it
    outlives ``timeout`` [s] and replaced, as is one that dies; each is that call's failure."""
    queue = list(calls)
    idle: list[_Worker] = []
    busy: dict[Any, _Worker] = {}
    try:
        while queue or busy:
            while queue and len(busy) < count:
                worker = idle.pop() if idle else _Worker()
                worker.key = queue.pop(0)
                worker.deadline = None if timeout is None else time.monotonic() + timeout + STARTUP_ALLOWANCE
                worker.connection.send((function, calls[worker.key]))
                busy[worker.connection] = worker
            deadlines = [w.deadline for w in busy.values() if w.deadline is not None]
            wait_for = None if not deadlines else max(0.0, min(deadlines) - time.monotonic())
            waitables = [*busy, *(w.process.sentinel for w in busy.values())]
            multiprocessing.connection.wait(waitables, timeout=wait_for)
            for connection, worker in list(busy.items()):
                if connection.poll():
                    try:
                        message = connection.recv()
                    except (EOFError, OSError):
                        message = (None, None)
                    if message == STARTED:
                        worker.deadline = None if timeout is None else time.monotonic() + timeout
                        continue
                    if isinstance(message, tuple) and len(message) == 3 and message[0] == GROUP:
                        (worker.groups.add if message[2] else worker.groups.discard)(message[1])
                        continue
                    ok, value = message
                    if ok is not None:
                        del busy[connection]
                        idle.append(worker)
                        (finish if ok else failed)(worker.key, value)
                        continue
                if not worker.process.is_alive():
                    del busy[connection]
                    worker.process.join()
                    code = worker.process.exitcode
                    worker.stop(kill=True)
                    failed(worker.key, f"WorkerDied: its worker process ended (exit code {code}) before returning")
                elif worker.deadline is not None and time.monotonic() >= worker.deadline:
                    del busy[connection]
                    worker.stop(kill=True)
                    failed(
                        worker.key,
                        f"CallTimeout: took longer than the time limit of {timeout:g} s (--cell-timeout); its worker "
                        "process was stopped",
                    )
    finally:
        for worker in [*idle, *busy.values()]:
            worker.stop(kill=worker in busy.values())
