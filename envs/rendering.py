"""Pictures of a steering task: the robot's outline, the workspace scene and an off-screen canvas.

The envs' ``render`` and the paper's figures (:mod:`ilc_steering.plots`) draw with these, on
matplotlib's Agg canvas, which needs no display. A robot is drawn with its *nominal* map's
geometry (``robot``, the map; its ``outline`` is the drawing, see :mod:`ilc_steering.core.robots`;
a chained plant has none and is drawn in the plane ``(z1, zn)`` as a point):

- the car is the bicycle model of Fig. 1: a body, the rear wheel at ``(x, y)`` and the front
  wheel one wheelbase ahead, turned by ``phi``;
- the unicycle is a round body on its axle, two wheels and a heading mark;
- the car towing a trailer is the car at the hitch, the trailer's body and axle at ``(x1, y1)``,
  and the drawbar between them.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import numpy.typing as npt
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from ilc_steering.core.nominal import ChainedMap

__all__ = [
    "Canvas",
    "draw_pose",
    "draw_trial",
    "draw_waypoints",
    "plane",
    "render_scene",
    "robot_outline",
    "setup_workspace",
]

Array = npt.NDArray[np.float64]

START, GOAL, PATH, STROBE = "0.45", "tab:green", "tab:blue", "tab:blue"


def robot_outline(robot: ChainedMap, q: Array) -> list[tuple[Array, bool]]:
    """The polylines ``(k, 2)`` [m] that draw ``robot`` (a nominal map) at configuration ``q``, each
    with whether it is a wheel (drawn thick) rather than an outline: the map's own drawing."""
    return robot.outline(q)


def plane(q: Array, has_pose: bool) -> Array:
    """The drawn coordinates of configurations ``(..., nx)``: ``(x, y)`` for a car, ``(z1, zn)`` otherwise."""
    q = np.asarray(q)
    return q[..., :2] if has_pose else q[..., [0, -1]]


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
        for i in np.unique(np.linspace(0, len(q) - 1, snapshots).round().astype(int)):
            draw_pose(ax, q[i], robot, STROBE, alpha=0.35)


def setup_workspace(ax: Axes, dimension: int | None, title: str) -> None:
    """Equal axes with units (``dimension``: ``None`` for a car, else the chained form's ``n``),
    a grid and the title."""
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x [m]" if dimension is None else "z1")
    ax.set_ylabel("y [m]" if dimension is None else f"z{dimension}")
    ax.grid(True, linewidth=0.4, alpha=0.5)
    ax.set_title(title, fontsize=9)


class Canvas:
    """An off-screen figure of ``width`` x ``height`` pixels whose ``frame`` is an RGB array."""

    def __init__(self, width: int = 480, height: int = 480, dpi: int = 80) -> None:
        self.figure = Figure(figsize=(width / dpi, height / dpi), dpi=dpi)
        FigureCanvasAgg(self.figure)
        self.ax = self.figure.add_subplot()
        # Fixed margins (room for the tick labels and a two-line title): tight_layout would
        # double the time per frame.
        self.figure.subplots_adjust(left=0.15, right=0.96, bottom=0.11, top=0.9)

    def clear(self) -> Axes:
        self.ax.clear()
        return self.ax

    def frame(self) -> npt.NDArray[np.uint8]:
        """The figure as a ``(height, width, 3)`` uint8 array."""
        canvas: Any = self.figure.canvas
        canvas.draw()
        return np.array(canvas.buffer_rgba())[..., :3]


def render_scene(
    canvas: Canvas, waypoints: Array, robot: ChainedMap, names: Sequence[str], paths: Sequence[Array], title: str
) -> npt.NDArray[np.uint8]:
    """An env's frame: the waypoints, the ``paths`` ``(S, nx)`` of the last trials, the last of
    them stroboscopic (``robot``: the nominal map it is drawn with)."""
    ax = canvas.clear()
    draw_waypoints(ax, waypoints, robot, names)
    for i, q in enumerate(paths):
        draw_trial(ax, q, robot, snapshots=8 if i == len(paths) - 1 else 0)
    setup_workspace(ax, None if robot.has_pose else waypoints.shape[1], title)
    return canvas.frame()
