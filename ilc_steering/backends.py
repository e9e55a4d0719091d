"""Where the cells of a comparison or the rows of a sweep run: local processes, or Ray tasks.

:func:`run_calls` calls ``function(*calls[key])`` for every key and hands each result to
``finish(key, result)`` in this process as it arrives, so the caller writes it at once and a run
resumes from what was written. The backend changes where the calls run, never what they return:
``compare --backend ray`` writes the same cell files as the local backend (``tests/test_backends.py``).

- ``local``: in this process (one worker), or in spawned worker processes;
- ``ray``: each call a Ray task on ``ray.init()``: a local Ray by default, the cluster at
  ``RAY_ADDRESS`` when it is set (``pip install "ilc-steering[ray]"``). The function and its
  arguments go to the workers by pickling, so they must be importable there (the package
  installed on every node).
"""

from __future__ import annotations

import logging
import multiprocessing
import os
import pickle
from collections.abc import Callable, Mapping
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from pathlib import Path
from typing import Any

__all__ = ["BACKENDS", "run_calls"]

BACKENDS = ("local", "ray")

Finish = Callable[[Any, Any], None]


def run_calls(
    function: Callable[..., Any],
    calls: Mapping[Any, tuple[Any, ...]],
    finish: Finish,
    backend: str = "local",
    workers: int = 0,
) -> None:
    """``finish(key, function(*calls[key]))`` for every key, on ``backend`` (``workers`` local
    processes, 0 for one per core). An error or an interrupt cancels what has not started and is raised."""
    if backend not in BACKENDS:
        raise ValueError(f"--backend must be one of {list(BACKENDS)}, got {backend!r}")
    if not calls:
        return
    if backend == "ray":
        _ray_map(function, calls, finish)
        return
    count = min(workers or os.cpu_count() or 1, len(calls))
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


def _ray_map(function: Callable[..., Any], calls: Mapping[Any, tuple[Any, ...]], finish: Finish) -> None:
    try:
        import ray
    except ImportError:
        raise ValueError('--backend ray needs Ray: pip install "ilc-steering[ray]"') from None
    if not ray.is_initialized():
        ray.init(logging_level=logging.WARNING, log_to_driver=False)  # RAY_ADDRESS, if set, names the cluster

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

    task = ray.remote(on_worker)
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
                finish(pending.pop(ref), ray.get(ref))
    except BaseException:
        for ref in pending:
            ray.cancel(ref)
        raise
