"""Pictures of a steering task: the robot's outline, and the paper's figures' drawing on matplotlib axes.

The paper's figures (:mod:`ilc_steering.plots`) draw with the helpers here, on matplotlib's Agg
canvas, which needs no display; the envs' frames (:mod:`ilc_steering.envs.frames`) draw the same
outlines with the numpy rasterizer. Importing this module does not import matplotlib: the helpers
draw on the ``Axes`` they are handed. A robot is drawn with its *nominal* map's geometry
(``robot``, the map, or ``None`` for a chained plant, drawn in the plane ``(z1, zn)`` as a point):

- the car is the bicycle model of Fig. 1: a body, the rear wheel at ``(x, y)`` and the front
  wheel one wheelbase ahead, turned by ``phi``;
- the unicycle is a round body on its axle, two wheels and a heading mark;
- the car towing a trailer is the car at the hitch, the trailer's body and axle at ``(x1, y1)``,
  and the drawbar between them.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from ilc_steering.core.car import CarModel
from ilc_steering.core.trailer import TrailerModel, car_position
from ilc_steering.core.unicycle import UnicycleModel

if TYPE_CHECKING:
    from matplotlib.axes import Axes

__all__ = [
    "car_outline",
    "draw_pose",
    "draw_trial",
    "draw_waypoints",
    "plane",
    "robot_outline",
    "setup_workspace",
    "snapshot_indices",
]

Array = npt.NDArray[np.float64]

# Proportions of the drawn car, in wheelbases (the paper's car: 0.2 m between the axles).
BODY_REAR, BODY_FRONT, BODY_HALF_WIDTH, WHEEL_HALF_LENGTH = -0.3, 1.3, 0.35, 0.2
START, GOAL, PATH, STROBE = "0.45", "tab:green", "tab:blue", "tab:blue"


def _box(origin: Array, heading: Array, normal: Array, size: float, back: float, ahead: float) -> Array:
    """The closed rectangle ``(..., 5, 2)`` [m] from ``back`` to ``ahead`` along ``heading`` and
    ``BODY_HALF_WIDTH`` to each side, in units of ``size`` [m] from ``origin`` (each ``(..., 2)``)."""
    along = np.array([back, ahead, ahead, back, back])[:, None]
    side = (np.array([-1.0, -1.0, 1.0, 1.0, -1.0]) * BODY_HALF_WIDTH)[:, None]
    return origin[..., None, :] + size * (along * heading[..., None, :] + side * normal[..., None, :])


def _direction(angle: Array) -> tuple[Array, Array]:
    """The unit vector ``(..., 2)`` at ``angle`` [rad] and the one a quarter turn left of it."""
    heading = np.stack([np.cos(angle), np.sin(angle)], axis=-1)
    return heading, np.stack([-heading[..., 1], heading[..., 0]], axis=-1)


def _segment(middle: Array, half: Array) -> Array:
    """The segment ``(..., 2, 2)`` from ``middle - half`` to ``middle + half``."""
    return np.stack([middle - half, middle + half], axis=-2)


def car_outline(q: Array, wheelbase: float) -> tuple[Array, Array, Array]:
    """The body polygon ``(..., 5, 2)``, rear wheel ``(..., 2, 2)`` and front wheel ``(..., 2, 2)`` [m]
    of a car at ``q = (x, y, theta, phi)`` (or configurations ``(..., 4)``) with the given
    ``wheelbase`` [m]."""
    q = np.asarray(q, dtype=np.float64)
    theta, phi = q[..., 2], q[..., 3]
    heading, normal = _direction(theta)
    rear = q[..., :2]
    body = _box(rear, heading, normal, wheelbase, BODY_REAR, BODY_FRONT)
    half = WHEEL_HALF_LENGTH * wheelbase
    front = rear + wheelbase * heading
    steered, _ = _direction(theta + phi)
    return body, _segment(rear, half * heading), _segment(front, half * steered)


def robot_outline(robot: object, q: Array) -> list[tuple[Array, bool]]:
    """The polylines ``(k, 2)`` [m] that draw ``robot`` (a nominal map) at configuration ``q``, each
    with whether it is a wheel (drawn thick) rather than an outline; for configurations ``(..., nx)``,
    polylines ``(..., k, 2)``, one per configuration."""
    q = np.asarray(q, dtype=np.float64)
    if isinstance(robot, CarModel):
        body, rear, front = car_outline(q, robot.wheelbase)
        return [(body, False), (rear, True), (front, True)]
    if isinstance(robot, UnicycleModel):
        centre, b, rho = q[..., :2], robot.axle_width, robot.wheel_radius
        heading, normal = _direction(q[..., 2])
        angles = np.linspace(0.0, 2.0 * np.pi, 33)
        body = centre[..., None, :] + 0.6 * b * np.stack([np.cos(angles), np.sin(angles)], axis=-1)
        wheels = [_segment(c, rho * heading) for c in (centre + 0.5 * b * normal, centre - 0.5 * b * normal)]
        mark = np.stack([centre, centre + 0.6 * b * heading], axis=-2)
        return [(body, False), (mark, False), *((w, True) for w in wheels)]
    if isinstance(robot, TrailerModel):
        rear, theta0 = car_position(q[..., :5], robot.hitch_length)
        car_q = np.concatenate([rear, theta0[..., None], q[..., 3:4]], axis=-1)
        car = robot_outline(CarModel(robot.wheelbase, robot.wheel_radius), car_q)
        axle = q[..., :2]
        heading, normal = _direction(q[..., 2])
        size = robot.wheelbase
        box = _box(axle, heading, normal, size, -0.35, 0.45)
        wheel = _segment(axle, WHEEL_HALF_LENGTH * size * heading)
        return [*car, (box, False), (np.stack([axle, rear], axis=-2), False), (wheel, True)]
    raise ValueError(f"no drawing for a robot mapped by {type(robot).__name__}")


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
    robot: object,
    color: str,
    linestyle: str = "-",
    alpha: float = 1.0,
    label: str | None = None,
) -> None:
    """One configuration: the robot's outline and wheels, or a marker for a chained plant (``robot`` ``None``)."""
    if robot is None:
        point = plane(q, False)
        ax.plot(*point, "o", color=color, alpha=alpha, label=label, fillstyle="none" if linestyle != "-" else "full")
        return
    for i, (line, wheel) in enumerate(robot_outline(robot, q)):
        if wheel:
            ax.plot(*line.T, color=color, alpha=alpha, linewidth=3.0, solid_capstyle="butt")
        else:
            ax.plot(
                *line.T, color=color, linestyle=linestyle, alpha=alpha, linewidth=1.0, label=label if i == 0 else None
            )


def draw_waypoints(ax: Axes, waypoints: Array, robot: object, names: Sequence[str]) -> None:
    """Start (grey) and goal or waypoint (green, dashed) configurations, each named beside it."""
    for i, (q, name) in enumerate(zip(waypoints, names)):
        color = START if i == 0 else GOAL
        draw_pose(ax, q, robot, color, linestyle="-" if i == 0 else "--", label=name)
        x, y = plane(q, robot is not None)
        ax.annotate(name, (x, y), xytext=(-8, -24), textcoords="offset points", color=color, fontsize=8)


def draw_trial(
    ax: Axes, q: Array, robot: object, snapshots: int = 8, color: str = PATH, label: str | None = None
) -> None:
    """A trial's path (the robot's reference point: a car's rear-axle midpoint, a trailer's axle
    midpoint) with the robot drawn at ``snapshots`` evenly spaced instants, the stroboscopic view
    of the paper's Figs. 3, 7 and 11."""
    path = plane(q, robot is not None)
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
