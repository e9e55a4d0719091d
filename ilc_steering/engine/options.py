"""The options every command over cells shares: ``--backend``, ``--workers`` and ``--cell-timeout``.

Declared once (:func:`add_cell_options`, one help each), checked once when a command makes its plan
(:func:`check_cell_options`, which only refuses), and the cell timeout's default,
:data:`DEFAULT_CELL_TIMEOUT`, applied once, by the engine that keeps the time
(:func:`~ilc_steering.engine.runs.compute_cells`). A walk of ``--cell-timeout`` from the command
line goes one way, down, and returns nowhere: ``cli`` parses it, the command's ``from_namespace``
puts it in its arguments (None when it is not given), its plan checks it here, and its
``execute`` hands it down to the engine, which applies the default, then to the backend and the
worker's deadline.
"""

from __future__ import annotations

import argparse
import math

from ilc_steering.errors import BadInput

__all__ = [
    "DEFAULT_CELL_TIMEOUT",
    "MAX_CELL_TIMEOUT",
    "add_cell_options",
    "cell_bound",
    "check_cell_options",
    "check_timeout",
    "timeout_help",
]

MAX_CELL_TIMEOUT = 7 * 24 * 3600.0
"""The longest ``--cell-timeout`` [s]: a week. A longer one is no bound a timer can hold."""
DEFAULT_CELL_TIMEOUT = 6 * 3600.0
"""[s] the bound on a cell when ``--cell-timeout`` is not given: six hours, far above any cell of the
packaged comparison, so that a learner that never returns fails its cell instead of hanging the run.
This is where the default is stated; ``--cell-timeout``'s help (:func:`timeout_help`) reads it."""


def timeout_help(what: str) -> str:
    """The help of ``--cell-timeout`` for a command whose unit of work is ``what`` (a cell, a row)."""
    return (
        f"stop a {what} still running after this, its worker process ended, and record it as failed "
        f"(default: {DEFAULT_CELL_TIMEOUT / 3600:g} h; at most {MAX_CELL_TIMEOUT / 86400:g} days)"
    )


def add_cell_options(parser: argparse.ArgumentParser, what: str) -> None:
    """The options every command over a grid of cells shares, with one help each: ``--backend``,
    ``--workers``, ``--cell-timeout`` and ``--dry-run`` (``what``: the command's unit of work, a
    cell or a row)."""
    from ilc_steering.engine.backends import MAX_WORKERS

    parser.add_argument(
        "--backend",
        default="local",
        help="local worker processes, or Ray tasks on ray.init() (a local Ray; a cluster through RAY_ADDRESS)",
    )
    parser.add_argument(
        "--workers", type=int, default=0, help=f"local worker processes (0: one per core; at most {MAX_WORKERS})"
    )
    parser.add_argument(
        "--cell-timeout",
        type=float,
        default=argparse.SUPPRESS,  # the engine's bound, DEFAULT_CELL_TIMEOUT, stated in the help
        metavar="SECONDS",
        help=timeout_help(what),
    )
    parser.add_argument(
        "--dry-run",
        action="store_true",
        help=f"compute nothing, write nothing: print which {what}s a run would compute (missing, or stale: made by "
        "other code or another config) and its estimated cost",
    )


def check_cell_options(backend: str, workers: int, timeout: float | None) -> None:
    """The shared options' rules, checked once, before any cell: ``ValueError`` naming the option.
    Nothing is returned: the options go on as given (``timeout`` None: the engine's default)."""
    from ilc_steering.engine.backends import check_backend, check_workers

    check_backend(backend)
    check_workers(workers)
    check_timeout(timeout)


def cell_bound(timeout: float | None) -> float:
    """The bound on each cell [s]: ``timeout``, or :data:`DEFAULT_CELL_TIMEOUT` (read when called)
    when it is None; the engine's, which keeps the time."""
    return DEFAULT_CELL_TIMEOUT if timeout is None else float(timeout)


def check_timeout(timeout: float | None, option: str = "--cell-timeout") -> float | None:
    """``timeout`` if it is None or a time in ``(0, MAX_CELL_TIMEOUT]`` seconds; ``ValueError`` otherwise."""
    if timeout is None:
        return None
    number = isinstance(timeout, (int, float)) and not isinstance(timeout, bool)
    if not (number and math.isfinite(timeout) and 0 < timeout <= MAX_CELL_TIMEOUT):
        raise BadInput(f"{option}: a time limit in (0, {MAX_CELL_TIMEOUT:g}] s (a week), got {timeout!r}")
    return float(timeout)
