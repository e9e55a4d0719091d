"""A robot's limits: what a trial may ask of it, checked before it leaves the library, and what it
may report back, checked as it arrives.

A process plant (:mod:`ilc_steering.core.robots.process`) may have a real robot on the other end:
a trial whose nominal path leaves the workspace, or needs more speed, steering angle or steering
rate than the robot has, is refused with a :class:`~ilc_steering.errors.LimitError`, never
clipped and never sent. A pose it reports (:func:`reported_pose`) must lie in the workspace, and
its angles are taken as a robot reports them: a heading unwrapped by whole turns (odometry that
counts them, ``[0, 2π)``) is wrapped into the chart's range and the wrap stated; an angle too large
to be radians (degrees, a unit error) is refused, saying so.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass
from math import isfinite, pi
from typing import Any

import numpy as np
import numpy.typing as npt

from ilc_steering.core.checks import require
from ilc_steering.core.plants import CHART_MARGIN, PlantKind
from ilc_steering.core.robots.chart import rotate
from ilc_steering.errors import LimitError

__all__ = [
    "LIMIT_RTOL",
    "MAX_LOG_BYTES",
    "MAX_SAMPLES",
    "MAX_TURNS",
    "WRAPPED",
    "ProcessLimits",
    "brief",
    "check_path",
    "kept_log",
    "number_list",
    "reported_pose",
    "reported_trajectory",
    "steering_index",
]

Array = npt.NDArray[np.float64]

LIMIT_RTOL = 1e-9
"""[-] how far past a limit a nominal path may computably be and still be within it: a fraction of
the limit (of the workspace's width for its walls). A path that meets a limit exactly (a task
driven at the robot's top speed) is computed with last bits that differ from one CPU to another;
this tolerance, far below anything a robot could tell apart, makes the refusal the same on all."""
MAX_TURNS = 2
"""[-] the most whole turns either way a heading (an angle that is not a steering angle) may be
reported at: odometry that counts turns, or ``[0, 2π)``, is within; ``45`` (degrees) or ``1e9`` is not
an angle in radians, and is refused. A steering angle may be at most π [rad] (a half turn)."""
MAX_LOG_BYTES = 64 << 10
"""[bytes] the largest log of a trial kept in its record (``run --json``'s ``plant``); a longer one is
kept as a note of its size. With :data:`MAX_SAMPLES`, what a robot sends cannot make a run's record
larger than ``plot`` reads (``plots.MAX_RUN_BYTES``) before some 300 trials."""
MAX_SAMPLES = 1000
"""The most samples kept of a trajectory a robot sends (evenly spaced, its first and last among
them): a figure's worth (the library's own trajectories have some 400)."""
WRAPPED = "angles_wrapped"
"""The key of a trial's log that states each angle wrapped: ``{"θ": [reported, read as]}`` [rad, world frame]."""


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


def number_list(value: Any, size: int | None) -> list[float] | None:
    """``value`` as finite floats (``size`` of them, when given), or ``None``."""
    if not isinstance(value, list) or (size is not None and len(value) != size):
        return None
    if not all(isinstance(v, (int, float)) and not isinstance(v, bool) and isfinite(v) for v in value):
        return None
    return [float(v) for v in value]


def brief(value: Any) -> str:
    """``repr(value)`` for a message: at most 80 characters."""
    text = repr(value)
    return text if len(text) <= 80 else text[:80] + "..."


def reported_pose(
    limits: ProcessLimits,
    kind: PlantKind,
    final: list[float],
    frame: float,
    what: str,
    fail: Callable[[str], Exception],
) -> tuple[Array, bool, dict[str, list[float]]]:
    """The pose ``final`` (world frame) a robot of ``kind`` reported for ``what`` (``trial k``), in the
    task frame (the world rotated by ``frame`` [rad]): its position inside ``limits.workspace``, each
    heading wrapped by whole turns into ``[-π, π]`` of the task frame, and each angle at the chart's
    edge if it stopped beyond (then it left the chart: the second value). The third is every angle
    wrapped, ``{name: [reported, read as]}`` [rad, world frame]. ``fail(problem)`` is raised for a
    pose that cannot be taken (outside the workspace; an angle too large to be radians)."""
    x_min, x_max, y_min, y_max = limits.workspace
    if not (x_min <= final[0] <= x_max and y_min <= final[1] <= y_max):
        raise fail(
            f"reported {what}'s final pose at (x, y) = ({final[0]:.6g}, {final[1]:.6g}) m, outside "
            f"plant.limits.workspace x in [{x_min:g}, {x_max:g}], y in [{y_min:g}, {y_max:g}] m"
        )
    q = rotate(np.array(final, dtype=np.float64), frame) if frame else np.array(final, dtype=np.float64)
    wrapped: dict[str, list[float]] = {}
    for i, label in enumerate(kind.coordinates):
        if not label.endswith("[rad]"):
            continue
        name, steering = label.split()[0], label.startswith("φ")
        bound, words = (pi, "a half turn (π rad)") if steering else (2 * pi * MAX_TURNS, f"{MAX_TURNS} turns")
        if abs(final[i]) > bound:
            raise fail(
                f"reported {what}'s {name} as {final[i]:.6g} rad, more than {words}: not an angle in radians "
                "(in degrees? the protocol's angles are radians: 45 degrees is 0.785398 rad)"
            )
        turns = 0 if steering else round(q[i] / (2 * pi))
        if turns:
            q[i] -= 2 * pi * turns
            wrapped[name] = [final[i], final[i] - 2 * pi * turns]
    edge = pi / 2 - CHART_MARGIN
    left = bool(np.any(np.abs(q[2:]) > edge))  # stopped out of the chart of eqs. 4-5: measured at its edge
    q[2:] = np.clip(q[2:], -edge, edge)
    return q, left, wrapped


def reported_trajectory(
    value: Any, dimension: int, what: str, fail: Callable[[str], Exception]
) -> tuple[Array, Array] | None:
    """The trajectory a robot sent with ``what`` (``{"t": [...], "q": [[...], ...]}``, world frame):
    its times [s], increasing, and a configuration of ``dimension`` finite numbers per time; ``None``
    if it sent none. ``fail(problem)`` is raised for anything else."""
    if value is None:
        return None
    bad = f"answered {what} with a trajectory that is not {{'t': [...], 'q': [[...], ...]}}"
    if not isinstance(value, dict) or set(value) != {"t", "q"}:
        raise fail(bad)
    t = number_list(value["t"], None)
    rows = value["q"] if isinstance(value["q"], list) else None
    if t is None or rows is None or len(rows) != len(t) or len(t) < 2 or np.any(np.diff(t) <= 0):
        raise fail(bad + " (t increasing, as many q as t)")
    q = [number_list(row, dimension) for row in rows]
    if any(row is None for row in q):
        raise fail(bad + f" ({dimension} finite numbers per q)")
    kept = np.unique(np.linspace(0, len(t) - 1, min(len(t), MAX_SAMPLES)).round().astype(np.int64))
    return np.array(t)[kept], np.array(q)[kept]


def kept_log(log: dict[str, Any]) -> dict[str, Any]:
    """``log`` as a trial's record keeps it: itself, or a note of its size if over :data:`MAX_LOG_BYTES`."""
    size = len(json.dumps(log))
    return log if size <= MAX_LOG_BYTES else {"dropped": f"a log of {size} bytes, over the {MAX_LOG_BYTES} kept"}
