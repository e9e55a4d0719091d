"""How a trial is scored, from its ``info``: the cost every learner sees and the tolerance test.

A trial of a robot with a planar pose reports ``cartesian_error`` [m] and ``orientation_error``
[rad]; every trial reports ``error_norm``, ``||z^d - z(T)||``. The env's reward is minus
:func:`trial_cost`; the runner and the comparison count trials to tolerance with
:func:`within_tolerance`.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Protocol

__all__ = ["Tolerance", "trial_cost", "within_tolerance"]


class Tolerance(Protocol):
    """Bounds on a trial's errors; ``None`` leaves an error unbounded (``ToleranceConfig`` meets it)."""

    @property
    def cartesian(self) -> float | None: ...  # [m]

    @property
    def orientation(self) -> float | None: ...  # [rad]

    @property
    def error(self) -> float | None: ...  # on ||z^d - z(T)||


def trial_cost(info: Mapping[str, Any]) -> Any:
    """Cartesian error / 1 m + orientation error / 1 rad for a robot with a pose, else
    ``||z^d - z(T)||``: for one trial's ``info`` or a batch's (arrays)."""
    if "cartesian_error" in info:
        return info["cartesian_error"] + info["orientation_error"]
    return info["error_norm"]


def within_tolerance(tolerance: Tolerance, info: Mapping[str, Any]) -> bool:
    """Whether a trial's ``info`` meets every bound of ``tolerance``."""
    bounds = [
        ("error_norm", tolerance.error),
        ("cartesian_error", tolerance.cartesian),
        ("orientation_error", tolerance.orientation),
    ]
    return all(bound is None or float(info[key]) <= bound for key, bound in bounds)
