"""Where the cells of a comparison or the rows of a sweep run: local processes, or Ray tasks.

:func:`run_calls` calls ``function(*calls[key])`` for every key and hands each result to
``finish(key, result)`` in this process as it arrives, so the caller writes it at once and a run
resumes from what was written. The backend changes where the calls run, never what they return:
``compare --backend ray`` writes the same cell files as the local backend (``tests/test_backends.py``).

- ``local``: in spawned worker processes (in this process, one worker and no ``failed``);
- ``ray``: each call a Ray task on ``ray.init()``: a local Ray by default, the cluster at
  ``RAY_ADDRESS`` when it is set (``pip install "ilc-steering[ray]"``). The function and its
  arguments go to the workers by pickling, so they must be importable there (the package
  installed on every node). A ``RAY_ADDRESS`` that does not answer within
  :data:`RAY_CONNECT_TIMEOUT` is refused, not retried for minutes.

With ``failed`` given, a call that raises (or outlives ``timeout`` seconds) is handed to
``failed(key, message)`` and the others go on: a failing cell never takes a finished one with
it. Local calls with ``failed`` always run in worker processes that this process can kill
(:mod:`ilc_steering.engine.killable`), one worker included: a call past its time limit is ended with its
process (a learner that swallows the exception, an optimizer that never returns, a ``nogil``
compiled loop), and a worker that dies (``os._exit``, a crash) is that call's failure, the
others going on in a fresh worker. In a Ray task the limit is a ``SIGALRM``, which stops Python
code only, and a task whose worker dies is its call's failure too. Local workers are capped at
:data:`MAX_WORKERS`.
"""

from __future__ import annotations

import copyreg
import logging
import multiprocessing
import os
import pickle
import signal
import socket
import tempfile
import threading
import time
from collections.abc import Callable, Iterator, Mapping
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from ilc_steering.engine.killable import Failed, Finish, killable_map
from ilc_steering.errors import BadInput, ParameterError

__all__ = [
    "BACKENDS",
    "MAX_WORKERS",
    "RAY_CONNECT_TIMEOUT",
    "CallTimeout",
    "check_backend",
    "check_workers",
    "run_calls",
]

BACKENDS = ("local", "ray")
MAX_WORKERS = 2 * (os.cpu_count() or 1)
"""The most local worker processes (``--workers``): twice the cores; more only share the cores
and each holds its own interpreter, numba and torch (about 160 MB)."""
RAY_CONNECT_TIMEOUT = 10.0
"""[s] how long the Ray cluster at ``RAY_ADDRESS`` has to answer."""


def _reduce_parameter_error(error: ParameterError) -> tuple[type[ParameterError], tuple[str, str]]:
    return type(error), (error.name, error.problem)


# ParameterError(name, problem) keeps only its message in ``args``, which pickle would hand back to
# __init__ as its one argument: registered here, it crosses a process boundary as itself.
copyreg.pickle(ParameterError, _reduce_parameter_error)


class CallTimeout(Exception):
    """A call outlived its time limit."""


def check_workers(workers: int, option: str = "--workers") -> int:
    """``workers`` if it is a whole number in ``[0, MAX_WORKERS]`` (0: one per core); ``ValueError`` otherwise."""
    if isinstance(workers, bool) or not isinstance(workers, int) or not 0 <= workers <= MAX_WORKERS:
        raise BadInput(
            f"{option}: a whole number in [0, {MAX_WORKERS}] (0: one per core; at most twice the "
            f"{os.cpu_count() or 1} cores), got {workers!r}"
        )
    return workers


@contextmanager
def _time_limit(seconds: float | None) -> Iterator[None]:
    if seconds is None or threading.current_thread() is not threading.main_thread():
        yield
        return

    def expired(signum: int, frame: Any) -> None:
        raise CallTimeout(f"took longer than the time limit of {seconds:g} s (--cell-timeout)")

    previous = signal.signal(signal.SIGALRM, expired)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


def _guarded(function: Callable[..., Any], timeout: float | None, args: tuple[Any, ...]) -> tuple[bool, Any]:
    """``(True, function(*args))``, or ``(False, message)`` if it raised or outlived ``timeout``:
    a message crosses a process boundary where an exception may not (one whose ``__init__``
    takes other arguments than its ``args`` cannot be unpickled)."""
    try:
        with _time_limit(timeout):
            return True, function(*args)
    except Exception as error:
        return False, f"{type(error).__name__}: {error}"


def run_calls(
    function: Callable[..., Any],
    calls: Mapping[Any, tuple[Any, ...]],
    finish: Finish,
    backend: str = "local",
    workers: int = 0,
    failed: Failed | None = None,
    timeout: float | None = None,
) -> None:
    """``finish(key, function(*calls[key]))`` for every key, on ``backend`` (``workers`` local
    processes, 0 for one per core). Without ``failed``, an error or an interrupt cancels what has
    not started and is raised; with it, a call that raises or outlives ``timeout`` [s] goes to
    ``failed(key, message)`` and the rest run, locally in killable worker processes (see the
    module). An interrupt is always raised."""
    if backend not in BACKENDS:
        raise BadInput(f"--backend must be one of {list(BACKENDS)}, got {backend!r}")
    check_workers(workers)
    if not calls:
        return
    count = min(workers or os.cpu_count() or 1, len(calls))
    if backend == "local" and failed is not None:
        killable_map(function, calls, count, finish, failed, timeout)
        return
    if failed is not None or timeout is not None:
        guarded = {key: (function, timeout, args) for key, args in calls.items()}
        done = finish

        def settle(key: Any, outcome: tuple[bool, Any]) -> None:
            ok, value = outcome
            if ok:
                done(key, value)
            elif failed is not None:
                failed(key, value)
            else:
                raise RuntimeError(value)

        function, calls, finish = _guarded, guarded, settle
    if backend == "ray":
        _ray_map(function, calls, finish, failed)
        return
    if count <= 1:
        for key, args in calls.items():
            finish(key, function(*args))
        return
    _process_map(function, calls, count, finish)


def _process_map(
    function: Callable[..., Any], calls: Mapping[Any, tuple[Any, ...]], count: int, finish: Finish
) -> None:
    with ProcessPoolExecutor(count, mp_context=multiprocessing.get_context("spawn")) as pool:
        pending: dict[Future[Any], Any] = {}
        queue = list(calls)
        try:
            while queue or pending:
                while queue and len(pending) < 2 * count:
                    key = queue.pop(0)
                    pending[pool.submit(function, *calls[key])] = key
                finished, _ = wait(pending, return_when=FIRST_COMPLETED)
                for future in finished:
                    finish(pending.pop(future), future.result())
        except BaseException:
            for future in pending:
                future.cancel()
            raise


HTTP2_PREFACE = b"PRI * HTTP/2.0\r\n\r\nSM\r\n\r\n" + bytes([0, 0, 0, 4, 0, 0, 0, 0, 0])
"""What an HTTP/2 client sends first (the connection preface and an empty SETTINGS frame): a Ray
cluster's gRPC server answers it with a SETTINGS frame of its own (type 4)."""


def _check_ray_address(address: str) -> None:
    """``ValueError`` unless the cluster at ``address`` (``host:port`` or ``ray://host:port``;
    empty, ``auto`` or ``local``: nothing to reach) accepts a connection and answers as a gRPC
    server (an HTTP/2 SETTINGS frame) within :data:`RAY_CONNECT_TIMEOUT` in all: a port that
    accepts and never answers, or answers something else, is refused, not waited on."""
    if address in ("", "auto", "local"):
        return
    host, _, port = address.removeprefix("ray://").rpartition(":")
    if not host or not port.isdigit():
        raise BadInput(f"RAY_ADDRESS {address!r}: give host:port (or ray://host:port), or unset it for a local Ray")
    deadline = time.monotonic() + RAY_CONNECT_TIMEOUT
    problem = None
    try:
        with socket.create_connection((host.strip("[]"), int(port)), timeout=RAY_CONNECT_TIMEOUT) as connection:
            connection.settimeout(max(0.01, deadline - time.monotonic()))
            connection.sendall(HTTP2_PREFACE)
            reply = b""
            while len(reply) < 9:
                connection.settimeout(max(0.01, deadline - time.monotonic()))
                chunk = connection.recv(9 - len(reply))
                if not chunk:
                    break
                reply += chunk
            if len(reply) < 9 or reply[3] != 4:
                problem = "it accepted the connection but did not answer as a Ray cluster (a gRPC server)"
    except TimeoutError:
        problem = f"it accepted the connection but sent nothing within {RAY_CONNECT_TIMEOUT:g} s"
    except OSError as error:
        raise BadInput(
            f"RAY_ADDRESS {address}: no Ray cluster answers there within {RAY_CONNECT_TIMEOUT:g} s "
            f"({error.strerror or error}); start it, or unset RAY_ADDRESS for a local Ray"
        ) from None
    if problem is not None:
        raise BadInput(f"RAY_ADDRESS {address}: {problem}; give a Ray cluster's address, or unset RAY_ADDRESS")


def check_backend(backend: str) -> str:
    """``backend`` if cells can run there, checked before the first cell: ``local``, or ``ray`` with
    Ray installed and ``RAY_ADDRESS`` (if set) answering as a cluster; ``ValueError`` otherwise."""
    if backend not in BACKENDS:
        raise BadInput(f"--backend must be one of {list(BACKENDS)}, got {backend!r}")
    if backend == "ray":
        try:
            import ray  # noqa: F401
        except ImportError:
            raise BadInput('--backend ray needs Ray: pip install "ilc-steering[ray]"') from None
        _check_ray_address(os.environ.get("RAY_ADDRESS", ""))
    return backend


def _init_ray(ray: Any, address: str) -> None:
    """``ray.init()`` (``RAY_ADDRESS``, if set, names the cluster), within :data:`RAY_CONNECT_TIMEOUT`
    for a cluster: Ray itself retries an address that answers but is no Ray for minutes, logging a
    line a second from C++, so its log is held back until it has connected (and dropped if not)."""
    if address in ("", "auto", "local"):
        try:
            ray.init(logging_level=logging.WARNING, log_to_driver=False)
        except ConnectionError as error:  # RAY_ADDRESS=auto and no cluster running
            raise BadInput(
                f"RAY_ADDRESS {address}: no running Ray cluster found ({' '.join(str(error).split())[:200]}); "
                "start one (ray start --head) or unset RAY_ADDRESS for a local Ray"
            ) from None
        return
    _check_ray_address(address)
    saved = os.dup(2)
    with tempfile.TemporaryFile() as log:
        os.dup2(log.fileno(), 2)
        try:
            with _time_limit(RAY_CONNECT_TIMEOUT):
                ray.init(logging_level=logging.WARNING, log_to_driver=False)
        except CallTimeout:
            raise BadInput(
                f"RAY_ADDRESS {address}: no Ray cluster answered there within {RAY_CONNECT_TIMEOUT:g} s; "
                "start it, or unset RAY_ADDRESS for a local Ray"
            ) from None
        finally:
            os.dup2(saved, 2)
            os.close(saved)
        log.seek(0)
        os.write(2, log.read())


def _ray_map(
    function: Callable[..., Any], calls: Mapping[Any, tuple[Any, ...]], finish: Finish, failed: Failed | None = None
) -> None:
    """Every call a Ray task. With ``failed``, a task whose worker dies (``os._exit``, a crash) is
    that call's failure, never retried (a trial is never resent), and the others go on."""
    try:
        import ray
    except ImportError:
        raise BadInput('--backend ray needs Ray: pip install "ilc-steering[ray]"') from None
    if not ray.is_initialized():
        _init_ray(ray, os.environ.get("RAY_ADDRESS", ""))

    def on_worker(home: str, payload: bytes) -> Any:
        """Run a call on a Ray worker, importing the package from where the driver found it.

        Ray puts the driver's working directory first on its workers' path; run from a source
        checkout, that is the bare ``ilc_steering/`` folder, without the installed ``envs`` and
        ``agents``. So the call travels as bytes, unpickled only once ``home`` leads the path (a
        folder missing on another node changes nothing), and this function, local to
        ``_ray_map``, is pickled by value: the worker imports nothing of the package to run it."""
        import pickle
        import sys

        if sys.path[:1] != [home]:
            sys.path.insert(0, home)
        function, args = pickle.loads(payload)
        return function(*args)

    task = ray.remote(max_retries=0)(on_worker)
    home = str(Path(__file__).resolve().parents[1])  # where this process found the package
    width = 2 * max(1, int(ray.cluster_resources().get("CPU", 1)))  # type: ignore[no-untyped-call]
    pending: dict[Any, Any] = {}
    queue = list(calls)
    try:
        while queue or pending:
            while queue and len(pending) < width:
                key = queue.pop(0)
                pending[task.remote(home, pickle.dumps((function, calls[key])))] = key
            finished, _ = ray.wait(list(pending), num_returns=1)
            for ref in finished:
                key = pending.pop(ref)
                try:
                    value = ray.get(ref)
                except ray.exceptions.RayError as error:
                    if failed is None:
                        raise
                    what = " ".join(str(error).split())[:200]
                    failed(key, f"WorkerDied: its Ray task ended before returning ({type(error).__name__}: {what})")
                    continue
                finish(key, value)
    except BaseException:
        for ref in pending:
            ray.cancel(ref)
        raise
