"""A robot's limits, and the check of a trial's nominal path against them before it leaves the library.

A process plant (:mod:`ilc_steering.core.robots.process`) may have a real robot on the other end:
a trial whose nominal path leaves the workspace, or needs more speed, steering angle or steering
rate than the robot has, is refused with a :class:`~ilc_steering.errors.LimitError`, never
clipped and never sent.
"""

from __future__ import annotations

from dataclasses import dataclass
from math import isfinite
from typing import Any

import numpy as np
import numpy.typing as npt

from ilc_steering.core.checks import require
from ilc_steering.core.plants import PlantKind
from ilc_steering.errors import LimitError

__all__ = ["LIMIT_RTOL", "ProcessLimits", "check_path", "steering_index"]

Array = npt.NDArray[np.float64]

LIMIT_RTOL = 1e-9
"""[-] how far past a limit a nominal path may computably be and still be within it: a fraction of
the limit (of the workspace's width for its walls). A path that meets a limit exactly (a task
driven at the robot's top speed) is computed with last bits that differ from one CPU to another;
this tolerance, far below anything a robot could tell apart, makes the refusal the same on all."""


@dataclass(frozen=True)
class ProcessLimits:
    """The robot's limits, checked on a trial's nominal path before it is sent (world frame)."""

    workspace: tuple[float, ...]  # [x_min, x_max, y_min, y_max] [m]: the nominal path and every measured pose
    speed: float  # top speed of the reference point (a car's rear axle) [m/s]
    steering: float | None = None  # the largest |phi| [rad]; needed by a robot with a steering angle, else null
    steering_rate: float | None = None  # the largest |dphi/dt| [rad/s]; as steering

    def __post_init__(self) -> None:
        w = self.workspace
        require(
            len(w) == 4 and all(isfinite(v) for v in w) and w[0] < w[1] and w[2] < w[3],
            "workspace",
            f"needs [x_min, x_max, y_min, y_max] [m], finite, each min below its max, got {list(w)}",
        )
        for name in ("speed", "steering", "steering_rate"):
            value = getattr(self, name)
            require(value is None or (isfinite(value) and value > 0), name, f"must be > 0, got {value}")

    def to_json(self) -> dict[str, Any]:
        return {
            "workspace": list(self.workspace),
            "speed": self.speed,
            "steering": self.steering,
            "steering_rate": self.steering_rate,
        }


def steering_index(kind: PlantKind) -> int | None:
    """The entry of the configuration that is a steering angle (labelled ``φ``), or ``None``."""
    return next((i for i, label in enumerate(kind.coordinates) if label.startswith("φ")), None)


def check_path(limits: ProcessLimits, kind: PlantKind, times: Array, world: Array, what: str, who: str) -> None:
    """A :class:`~ilc_steering.errors.LimitError` naming the first of ``limits`` that the path
    ``world`` (a configuration per time of ``times`` [s], world frame) of ``what`` (``trial k``)
    passes, before it is sent to ``who``: the workspace, the top speed, and for a robot of
    ``kind`` that steers, its steering angle and rate."""
    h = np.diff(times)
    x_min, x_max, y_min, y_max = limits.workspace
    x_tol, y_tol = LIMIT_RTOL * (x_max - x_min), LIMIT_RTOL * (y_max - y_min)

    def refuse(key: str, needs: str, where: int, limit: str) -> None:
        raise LimitError(
            f"plant.limits.{key}: {what}'s nominal path needs {needs} at t = {times[where]:.3g} s, beyond the "
            f"robot's {limit}; refused before sending it to {who} (a learner's step too large, or limits too "
            "tight for the task)"
        )

    outside = np.flatnonzero(
        (world[:, 0] < x_min - x_tol)
        | (world[:, 0] > x_max + x_tol)
        | (world[:, 1] < y_min - y_tol)
        | (world[:, 1] > y_max + y_tol)
    )
    if outside.size:
        i = int(outside[0])
        refuse(
            "workspace", f"(x, y) = ({world[i, 0]:.4g}, {world[i, 1]:.4g}) m", i,
            f"workspace x in [{x_min:g}, {x_max:g}] m, y in [{y_min:g}, {y_max:g}] m",
        )  # fmt: skip
    speed = np.hypot(np.diff(world[:, 0]), np.diff(world[:, 1])) / h
    if speed.size and float(speed.max()) > limits.speed * (1 + LIMIT_RTOL):
        i = int(np.argmax(speed))
        refuse("speed", f"{speed[i]:.4g} m/s", i, f"top speed {limits.speed:g} m/s")
    index = steering_index(kind)
    if index is None or limits.steering is None or limits.steering_rate is None:
        return
    phi = world[:, index]
    if float(np.abs(phi).max()) > limits.steering * (1 + LIMIT_RTOL):
        i = int(np.argmax(np.abs(phi)))
        refuse("steering", f"|phi| = {abs(phi[i]):.4g} rad", i, f"steering angle {limits.steering:g} rad")
    rate = np.abs(np.diff(phi)) / h
    if rate.size and float(rate.max()) > limits.steering_rate * (1 + LIMIT_RTOL):
        i = int(np.argmax(rate))
        refuse("steering_rate", f"{rate[i]:.4g} rad/s", i, f"steering rate {limits.steering_rate:g} rad/s")
