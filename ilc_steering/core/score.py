"""How a trial is scored, from its ``info``: the cost a learner sees, the true errors the
benchmark counts, and the tolerance test.

A trial of a robot with a planar pose reports ``cartesian_error`` [m] and ``orientation_error``
[rad]; every trial reports ``error_norm``, ``||z^d - z(T)||``. These are *measured* (with the
env's ``measurement_noise``, if any): they are what a learner may use. The same errors of the
true final configuration are under ``true_cartesian_error``, ``true_orientation_error`` and
``true_error_norm``: the comparison and the runner count trials to tolerance with those, and the
trial loop keeps them from the learner (:data:`TRUE_KEYS`).

A trial that leaves the chart of eqs. 4-5 halts where it left, often near its start. Scored by
its error there alone it would beat nearly every trial that ran to the end (a random action in
the default box ends hundreds of metres off), a trap for any learner that searches by the cost.
So :func:`trial_cost` adds :data:`OFF_CHART_PENALTY` to it.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Protocol

import numpy as np

__all__ = [
    "OFF_CHART_PENALTY",
    "TRUE_KEYS",
    "Tolerance",
    "trial_cost",
    "true_cost",
    "within_tolerance",
]

OFF_CHART_PENALTY = 1000.0
"""[m + rad, or units of ``||z^d - z(T)||``] added to the cost of a trial that left the chart: more
than the median error of a uniformly random action in the default action box (747 m on forward
parking, 207 m on parallel parking), so leaving the chart never pays."""

TRUE_KEYS = ("true_cartesian_error", "true_orientation_error", "true_error_norm")
"""``info`` keys of the true errors: for scoring only, never handed to a learner."""


class Tolerance(Protocol):
    """Bounds on a trial's errors; ``None`` leaves an error unbounded (``ToleranceConfig`` meets it)."""

    @property
    def cartesian(self) -> float | None: ...  # [m]

    @property
    def orientation(self) -> float | None: ...  # [rad]

    @property
    def error(self) -> float | None: ...  # on ||z^d - z(T)||


def _cost(info: Mapping[str, Any], prefix: str) -> Any:
    if "cartesian_error" in info:
        error = info[prefix + "cartesian_error"] + info[prefix + "orientation_error"]
    else:
        error = info[prefix + "error_norm"]
    return error + OFF_CHART_PENALTY * np.asarray(info["left_chart"], dtype=np.float64)


def trial_cost(info: Mapping[str, Any]) -> Any:
    """The measured cost of a trial (the env's reward is its negative): Cartesian error / 1 m +
    orientation error / 1 rad for a robot with a pose, else ``||z^d - z(T)||``, plus
    :data:`OFF_CHART_PENALTY` if the trial left the chart; for one ``info`` or a batch's (arrays)."""
    return _cost(info, "")


def true_cost(info: Mapping[str, Any]) -> Any:
    """:func:`trial_cost` of the true final configuration, what the benchmark scores."""
    return _cost(info, "true_")


def within_tolerance(tolerance: Tolerance, info: Mapping[str, Any]) -> bool:
    """Whether a trial's *true* errors meet every bound of ``tolerance`` (a trial that left the
    chart never does)."""
    bounds = [
        ("true_error_norm", tolerance.error),
        ("true_cartesian_error", tolerance.cartesian),
        ("true_orientation_error", tolerance.orientation),
    ]
    if info["left_chart"]:
        return False
    return all(bound is None or float(info[key]) <= bound for key, bound in bounds)
