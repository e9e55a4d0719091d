r"""The nominal paths of parking-v0's tasks: the input profiles a task may take, and the task frame
and profile :func:`choose_frame` picks for a segment from its nominal path (within the chart, the
``±45°`` stop and the lot's walls with :data:`PATH_MARGIN`). :mod:`~ilc_steering.envs.highway` and
:mod:`~ilc_steering.envs.highway_segments` both build on it.
"""

from __future__ import annotations

from math import pi
from typing import Any

import numpy as np
import numpy.typing as npt

from ilc_steering.config.steering import MIN_TRAVEL, v1_travel
from ilc_steering.core.integrate import OK
from ilc_steering.core.nominal import MAX_NOMINAL_MISS, NominalModel
from ilc_steering.core.profiles import InputProfile
from ilc_steering.core.robots.car import CarPlant, rotate
from ilc_steering.core.simulate import simulate
from ilc_steering.core.trapezoid import TrapezoidProfile
from ilc_steering.envs.highway_lot import inside_lot
from ilc_steering.envs.highway_plant import STEERING, nominal_map

__all__ = [
    "PATH_MARGIN",
    "PROFILES",
    "STEERING_USE",
    "choose_frame",
    "nominal_path",
    "task_profile",
]

Array = npt.NDArray[np.float64]

PROFILES: tuple[tuple[tuple[float, ...], tuple[float, ...]], ...] = (
    ((15.0,), ()),
    ((10.0, 10.0), (2.0,)),
    ((10.0, 15.0), (2.0,)),
    ((10.0, 10.0), (4.0,)),
    ((8.0, 8.0, 8.0), (-2.0, 2.0)),
)
"""The input profiles a task may take, as ``(pieces [s], v1_fixed [m/s])`` (whole 0.2 s action steps):
one stroke whose speed is learned, or that stroke followed by fixed ones (forward at 2 or 4 m/s, or
back and forth at 2 m/s); :func:`choose_frame` takes the one whose nominal path steers least."""
RAMP = 3.0
"""[s] the trapezoid's ramp: the speed rises from rest and falls back to it at both ends of each piece."""
V2_TERMS = 4
"""``q``: one spare coefficient of ``v2`` beyond ``n - 1 = 3``."""
FRAME_GRID = np.radians(1.0)
"""[rad] the spacing of the task frames :func:`choose_frame` tries."""
CHART_SLACK = np.radians(10.0)
"""[rad] how far inside the chart's edge (``|theta| = pi/2``, task frame) the nominal path must stay."""
STEERING_USE = 1.0
"""The largest fraction of the ±45° stop the nominal path may use."""
STEERING_SPARE = 0.1
"""The fraction of the stop a profile's path leaves spare for :func:`choose_frame` to take it before
the later (longer) profiles."""
PATH_MARGIN = 1.5
"""[m] how far inside the lot's walls the car's outline must stay along a task's nominal path: the
learned paths stray from it, and a trial whose outline comes within
:data:`~ilc_steering.envs.highway_plant.WALL_MARGIN` of a wall is a failed one."""


def task_profile(pieces: tuple[float, ...], v1_fixed: tuple[float, ...]) -> Any:
    """The trapezoidal profile of ``(pieces [s], v1_fixed [m/s])`` (an entry of :data:`PROFILES`)."""
    return TrapezoidProfile(pieces, v1_fixed, V2_TERMS, RAMP)


def nominal_path(start: Array, goal: Array, frame: float, profile: InputProfile) -> Array:
    """The nominal car's path (world configurations ``(S, 4)``) of the nominal solution from ``start`` to
    ``goal`` with ``profile`` in the task frame rotated by ``frame`` [rad], without a steering stop
    (``inf`` where that solution is not exact: an ill-posed task, which ``run`` refuses)."""
    model = nominal_map()
    q0, q1 = rotate(start, frame), rotate(goal, frame)
    nominal = NominalModel(4, profile, model.to_chained(q0), model.to_chained(q1), model, STEERING)
    c = nominal.solve()
    if nominal.miss(c) > MAX_NOMINAL_MISS:  # W singular (eq. 23): run refuses the task as ill-posed
        return np.full((1, 4), np.inf)
    trials = simulate(CarPlant(model, model), profile, q0[None], c[None], 1 / 32, record=True)
    if trials.states is None or trials.status[0] != OK:
        return np.full((1, 4), np.inf)
    return rotate(trials.states[0], -frame)


def choose_frame(
    start: Array, goal: Array, grid: float = FRAME_GRID, profiles: int = len(PROFILES)
) -> tuple[float, int, float]:
    """The task frame [rad] and the profile (an index of :data:`PROFILES`) for a task, and the
    steering angle [rad] its nominal path (:func:`nominal_path`) needs: for each profile in turn,
    the frame whose path needs the least steering while it stays :data:`CHART_SLACK` inside the
    chart and the car's outline :data:`PATH_MARGIN` inside the lot's walls; the first profile whose
    path keeps :data:`STEERING_SPARE` of the stop spare, else the one that steers least (``inf``: no
    frame keeps any path in). A frame in which ``v1`` would cover no distance along ``z1``
    (:func:`~ilc_steering.config.steering.v1_travel`, the loader's check) is not tried. ``grid``
    [rad] spaces the frames tried, ``profiles`` tries the first few only."""
    edge, model = pi / 2 - CHART_SLACK, nominal_map()
    low, high = max(start[2], goal[2]) - edge, min(start[2], goal[2]) + edge
    best = (0.5 * (start[2] + goal[2]), 0, np.inf)
    with np.errstate(all="ignore"):  # a path that blows up is left out below
        for index, (pieces, v1_fixed) in enumerate(PROFILES[:profiles]):
            candidate = task_profile(pieces, v1_fixed)
            mine = (best[0], index, np.inf)
            for frame in np.arange(low, high + 1e-12, grid):
                z1 = [model.to_chained(rotate(q, float(frame)))[0] for q in (start, goal)]
                if v1_travel(float(z1[1] - z1[0]), pieces, v1_fixed, RAMP) <= MIN_TRAVEL:
                    continue  # W singular (eq. 11): the loader refuses this frame's task
                path = nominal_path(start, goal, float(frame), candidate)
                theta = path[:, 2] - frame
                inside = bool(np.all(np.abs(theta) < edge) and np.all(inside_lot(path, PATH_MARGIN)))
                steering = float(np.max(np.abs(path[:, 3])))
                if inside and steering < mine[2]:
                    mine = (float(frame), index, steering)
            if mine[2] <= (1 - STEERING_SPARE) * STEERING:
                return mine  # the simplest profile that steers well inside the stop
            if mine[2] < best[2]:
                best = mine
    return best
