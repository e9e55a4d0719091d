"""Pictures of a steering task: the robot's outline, and the paper's figures' drawing on matplotlib axes.

The paper's figures (:mod:`ilc_steering.plots`) draw with the helpers here, on matplotlib's Agg
canvas, which needs no display; the envs' frames (:mod:`ilc_steering.envs.frames`) draw the same
outlines with the numpy rasterizer. Importing this module does not import matplotlib: the helpers
draw on the ``Axes`` they are handed. A robot is drawn with its *nominal* map's geometry
(``robot``, the map), by the outline its module gives it (:mod:`ilc_steering.core.robots`); a
chained plant has none and is drawn in the plane ``(z1, zn)`` as a point.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from ilc_steering.core.nominal import ChainedMap

if TYPE_CHECKING:
    from matplotlib.axes import Axes

__all__ = [
    "draw_pose",
    "draw_trial",
    "draw_waypoints",
    "plane",
    "robot_outline",
    "setup_workspace",
    "snapshot_indices",
]

Array = npt.NDArray[np.float64]

START, GOAL, PATH, STROBE = "0.45", "tab:green", "tab:blue", "tab:blue"


def robot_outline(robot: ChainedMap, q: Array) -> list[tuple[Array, bool]]:
    """The polylines ``(k, 2)`` [m] that draw ``robot`` (a nominal map) at configuration ``q``, each
    with whether it is a wheel (drawn thick) rather than an outline; for configurations ``(..., nx)``,
    polylines ``(..., k, 2)``, one per configuration. The robot's module draws it (its map's
    ``outline``); a robot without an outline (a chained plant) is drawn as a point."""
    return robot.outline(np.asarray(q, dtype=np.float64))


def plane(q: Array, has_pose: bool) -> Array:
    """The drawn coordinates of configurations ``(..., nx)``: ``(x, y)`` for a car, ``(z1, zn)`` otherwise."""
    q = np.asarray(q)
    return q[..., :2] if has_pose else q[..., [0, -1]]


def snapshot_indices(samples: int, snapshots: int) -> npt.NDArray[np.intp]:
    """The indices of ``snapshots`` evenly spaced instants among a path's ``samples``, first and last included."""
    return np.unique(np.linspace(0, samples - 1, snapshots).round().astype(np.intp))


def draw_pose(
    ax: Axes,
    q: Array,
    robot: ChainedMap,
    color: str,
    linestyle: str = "-",
    alpha: float = 1.0,
    label: str | None = None,
) -> None:
    """One configuration: the robot's outline and wheels, or a marker for a robot without one (a chained plant)."""
    lines = robot_outline(robot, q)
    if not lines:
        point = plane(q, robot.has_pose)
        ax.plot(*point, "o", color=color, alpha=alpha, label=label, fillstyle="none" if linestyle != "-" else "full")
        return
    for i, (line, wheel) in enumerate(lines):
        if wheel:
            ax.plot(*line.T, color=color, alpha=alpha, linewidth=3.0, solid_capstyle="butt")
        else:
            ax.plot(
                *line.T, color=color, linestyle=linestyle, alpha=alpha, linewidth=1.0, label=label if i == 0 else None
            )


def draw_waypoints(ax: Axes, waypoints: Array, robot: ChainedMap, names: Sequence[str]) -> None:
    """Start (grey) and goal or waypoint (green, dashed) configurations, each named beside it."""
    for i, (q, name) in enumerate(zip(waypoints, names)):
        color = START if i == 0 else GOAL
        draw_pose(ax, q, robot, color, linestyle="-" if i == 0 else "--", label=name)
        x, y = plane(q, robot.has_pose)
        ax.annotate(name, (x, y), xytext=(-8, -24), textcoords="offset points", color=color, fontsize=8)


def draw_trial(
    ax: Axes, q: Array, robot: ChainedMap, snapshots: int = 8, color: str = PATH, label: str | None = None
) -> None:
    """A trial's path (the robot's reference point: a car's rear-axle midpoint, a trailer's axle
    midpoint) with the robot drawn at ``snapshots`` evenly spaced instants, the stroboscopic view
    of the paper's Figs. 3, 7 and 11."""
    path = plane(q, robot.has_pose)
    ax.plot(*path.T, color=color, linewidth=1.5, label=label)
    if snapshots > 0 and len(q) > 1:
        for i in snapshot_indices(len(q), snapshots):
            draw_pose(ax, q[i], robot, STROBE, alpha=0.35)


def setup_workspace(ax: Axes, dimension: int | None, title: str) -> None:
    """Equal axes with units (``dimension``: ``None`` for a car, else the chained form's ``n``),
    a grid and the title."""
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x [m]" if dimension is None else "z1")
    ax.set_ylabel("y [m]" if dimension is None else f"z{dimension}")
    ax.grid(True, linewidth=0.4, alpha=0.5)
    ax.set_title(title, fontsize=9)
