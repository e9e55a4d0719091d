"""The envs' ``rgb_array`` frames, drawn with the numpy rasterizer (:mod:`ilc_steering.envs.raster`).

A frame shows what the paper's trajectory figures show, laid out as matplotlib laid out the
frames before it: equal axes with a light grid, tick labels and the axes' names, the start
(grey) and the goal or waypoints (green, dashed), each named below it, the paths of the last
trials (blue), the robot at :data:`SNAPSHOTS` instants along the last of them (light blue), and a
title above. The robots' outlines are :func:`~ilc_steering.envs.rendering.robot_outline`'s, the
ones the figures draw; the widths are the figures' line widths at their 80 dots per inch.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from ilc_steering.core.nominal import ChainedMap
from ilc_steering.core.trajectory import Trajectory
from ilc_steering.envs.raster import RGB, Layer, Pen, Raster, WorldToPixels
from ilc_steering.envs.rendering import plane, robot_outline, snapshot_indices

if TYPE_CHECKING:
    from ilc_steering.envs.scenario import Scenario

__all__ = ["GOAL", "HEIGHT", "PATH", "SNAPSHOTS", "START", "WIDTH", "Scene", "TrialView", "draw_scene", "view"]

Array = npt.NDArray[np.float64]

WIDTH, HEIGHT = 480, 480
"""Pixels of a frame."""
PLOT = (64, 40, 468, 432)
"""The axes' rectangle (left, top, right, bottom) [px]: room for the tick labels and a two-line title."""
MARGIN = 0.05
"""Room around what is drawn, as a fraction of its extent on each axis (matplotlib's default)."""
SNAPSHOTS = 8
"""Instants of the last path at which the robot is drawn."""
# The figures' colours (rendering.START, GOAL, PATH: "0.45", "tab:green", "tab:blue") in RGB.
START, GOAL, PATH = (115, 115, 115), (44, 160, 44), (31, 119, 180)
INK, GRID = (0, 0, 0), (231, 231, 231)  # GRID: matplotlib's grey grid, its alpha over white
# Pens: matplotlib's 1, 3 and 1.5 points at 80 dpi, its ``--`` at 1 point; its "o" marker, 6 points across [px].
OUTLINE, DASHED, WHEEL, TRAIL = Pen(1.1), Pen(1.1, (4.1, 1.8)), Pen(3.3), Pen(1.7)
MARKER = 6.7
CIRCLE = np.linspace(0.0, 2 * np.pi, 25)
"""Angles [rad] of a ring's vertices."""
STROBE_ALPHA = 0.35
"""Opacity of the robot drawn along the last path (the figures' ``alpha``)."""


@dataclass(frozen=True)
class Scene:
    """What an env's frame shows: the waypoints ``(r, nx)`` (world configurations, start first),
    named ``names``; the ``paths`` ``(S, nx)`` of the last trials, the last drawn stroboscopic;
    the ``robot`` they are drawn as (its nominal map; a chained plant's, without an outline, as a
    point in the plane ``(z1, zn)``); and the ``title`` (lines split by ``\\n``)."""

    waypoints: Array
    robot: ChainedMap
    names: Sequence[str]
    paths: Sequence[Array]
    title: str


Shapes = list[tuple[Array, bool]]
"""A robot's polylines [m] at one configuration, each flagged a wheel (see :func:`robot_outline`)."""


def view(scene: Scene) -> WorldToPixels:
    """The map of the scene's plane [m] (``(x, y)``, or ``(z1, zn)`` for a chained plant) onto the
    frame's axes [px]: all the frame draws, with :data:`MARGIN` around it, on equal axes."""
    return _layout(scene)[0]


def draw_scene(scene: Scene) -> npt.NDArray[np.uint8]:
    """The frame of ``scene``: a ``(480, 480, 3)`` uint8 RGB image."""
    has_pose = scene.robot.has_pose
    to_pixels, waypoints, snapshots, paths = _layout(scene)
    raster = Raster(WIDTH, HEIGHT)
    ticks = _ticks(to_pixels, 0), _ticks(to_pixels, 1)
    _grid(raster, ticks)
    colours = [START, *[GOAL] * (len(waypoints) - 1)]
    if has_pose:  # one pass over every line: the cars, the paths, the cars along the last path
        layers = [_outlines([shapes], colour, 1.0, i > 0) for i, (shapes, colour) in enumerate(zip(waypoints, colours))]
        raster.draw([*layers, Layer(paths, TRAIL, PATH), _outlines(snapshots, PATH, STROBE_ALPHA, False)], to_pixels)
    else:  # a chained plant's point: filled at the start and along the path, a ring at the goal
        (start,), *goals = waypoints
        raster.dots(start[0], MARKER + OUTLINE.width, START, transform=to_pixels)
        ring = (MARKER / 2 / to_pixels.scale) * np.stack([np.cos(CIRCLE), np.sin(CIRCLE)], axis=-1)
        rings = [Layer([point + ring for ((point, _),) in goals], OUTLINE, GOAL)] if goals else []
        raster.draw([*rings, Layer(paths, TRAIL, PATH)], to_pixels)
        if snapshots:
            centres = np.concatenate([point for ((point, _),) in snapshots])
            raster.dots(centres, MARKER + OUTLINE.width, PATH, STROBE_ALPHA, to_pixels)
    _axes(raster, ticks, has_pose, scene.waypoints.shape[1])
    for i, (q, name) in enumerate(zip(scene.waypoints, scene.names)):
        column, row = to_pixels(plane(q, has_pose))
        raster.text(name, column - 9, row + 27, START if i == 0 else GOAL)  # matplotlib's (-8, -24) points
    lines = scene.title.split("\n")
    for i, line in enumerate(lines):
        raster.text(line, (PLOT[0] + PLOT[2]) / 2, PLOT[1] - 8 - 12 * (len(lines) - 1 - i), INK, align="centre")
    return raster.image


def _layout(scene: Scene) -> tuple[WorldToPixels, list[Shapes], list[Shapes], list[Array]]:
    """The scene's :func:`view`, the robot's shapes at the waypoints and at the snapshots along the
    last path, and the paths in the plane [m]."""
    has_pose = scene.robot.has_pose
    last = scene.paths[-1] if scene.paths else scene.waypoints[:0]
    strobes = last[snapshot_indices(len(last), SNAPSHOTS)] if len(last) else last
    waypoints, snapshots = _shapes(scene.robot, scene.waypoints), _shapes(scene.robot, strobes)
    paths = [plane(q, has_pose) for q in scene.paths]
    points = np.concatenate([line for shapes in (*waypoints, *snapshots) for line, _ in shapes] + paths)
    lower, upper = points.min(axis=0), points.max(axis=0)
    span = upper - lower
    room = np.where(span > 0, MARGIN * span, 0.5 * max(float(span.max()), 1.0))
    return WorldToPixels(lower - room, upper + room, PLOT), waypoints, snapshots, paths


def _shapes(robot: ChainedMap, poses: Array) -> list[Shapes]:
    """The robot's :data:`Shapes` at each configuration of ``poses`` ``(k, nx)``; a robot without an
    outline (a chained plant) is its point ``(1, 2)``."""
    lines = robot_outline(robot, poses)  # all configurations at once
    if not lines:
        return [[(point[None], False)] for point in plane(poses, robot.has_pose)]
    return [[(line[i], wheel) for line, wheel in lines] for i in range(len(poses))]


def _outlines(poses: Sequence[Shapes], colour: RGB, alpha: float, dashed: bool) -> Layer:
    """The robot's :data:`Shapes` at some configurations, as one layer: outlines (dashed or solid) and wheels."""
    lines = [(line, wheel) for shapes in poses for line, wheel in shapes]
    pens = [WHEEL if wheel else DASHED if dashed else OUTLINE for _, wheel in lines]
    return Layer([line for line, _ in lines], pens, colour, alpha)


Ticks = list[tuple[str, int]]


def _axes(raster: Raster, ticks: tuple[Ticks, Ticks], has_pose: bool, size: int) -> None:
    """The axes' frame, tick marks and labels (``ticks`` of x and y), and the axes' names."""
    left, top, right, bottom = PLOT
    raster.hlines([top, bottom], left, right, INK)
    raster.vlines([left, right], top, bottom, INK)
    columns, rows = ticks
    raster.vlines([column for _, column in columns], bottom + 1, bottom + 4, INK)
    raster.hlines([row for _, row in rows], left - 4, left - 1, INK)
    for label, column in columns:
        raster.text(label, column, bottom + 15, INK, align="centre")
    for label, row in rows:
        raster.text(label, left - 7, row + 3, INK, align="right")
    raster.text("x [m]" if has_pose else "z1", (left + right) / 2, bottom + 32, INK, align="centre")
    raster.text("y [m]" if has_pose else f"z{size}", 12, (top + bottom) / 2, INK, upright=False)


def _grid(raster: Raster, ticks: tuple[Ticks, Ticks]) -> None:
    """Light lines at the ``ticks`` of x and y, under everything else."""
    left, top, right, bottom = PLOT
    raster.vlines([column for _, column in ticks[0]], top, bottom, GRID)
    raster.hlines([row for _, row in ticks[1]], left, right, GRID)


def _ticks(to_pixels: WorldToPixels, axis: int) -> Ticks:
    """The ticks of ``axis`` (0: x, 1: y), a round distance apart (1, 2, 2.5 or 5 times a power of
    ten [m], at most eight steps across the axis): their labels, with as many decimals as that
    distance needs, and pixel columns (x) or rows (y)."""
    raw = float(to_pixels.upper[axis] - to_pixels.lower[axis]) / 8
    power = np.floor(np.log10(raw))
    mantissa = next(m for m in (1.0, 2.0, 2.5, 5.0, 10.0) if m * 10.0**power >= raw * (1 - 1e-9))
    step = mantissa * 10.0**power
    decimals = max(0, -int(power) - (mantissa == 10.0)) + (mantissa == 2.5)
    values = np.arange(np.ceil(to_pixels.lower[axis] / step), np.floor(to_pixels.upper[axis] / step) + 1) * step
    points = np.zeros((len(values), 2))
    points[:, axis] = values
    pixels = np.floor(to_pixels(points)[:, axis]).astype(int)
    labels = [f"{v:.{decimals}f}" for v in values]
    return [(text[1:] if text.startswith("-") and float(text) == 0 else text, p) for text, p in zip(labels, pixels)]


class TrialView:
    """What the envs draw: the waypoints (world frame; ``robot`` the nominal map the robot is
    drawn with, ``None`` for a chained plant, drawn as a point) and the paths of the last trials, with a title line of
    the last trial's errors (Cartesian and orientation where the robot has a pose), as a
    :class:`~ilc_steering.envs.frames.Scene`."""

    def __init__(self, waypoints: Array, robot: ChainedMap, names: list[str], has_pose: bool) -> None:
        self._waypoints = waypoints
        self._robot = robot
        self._names = names
        self._has_pose = has_pose
        self._paths: list[Array] = []
        self._errors = ""
        self.count = 0

    @classmethod
    def of(cls, scenario: Scenario, names: list[str]) -> TrialView:
        """The view of a scenario's waypoints, the robot drawn with its nominal geometry."""
        return cls(scenario.waypoints, scenario.nominal.chained_map, names, scenario.kind.has_pose)

    def clear(self) -> None:
        """Forget the trials."""
        self._paths, self._errors, self.count = [], "", 0

    def add(self, trajectory: Trajectory, info: dict[str, Any], keep: int) -> None:
        """Remember a trial's path (the last ``keep`` of them are drawn) and its errors."""
        self._paths = [*self._paths, trajectory.q][-keep:]
        self.count += 1
        if self._has_pose:
            self._errors = f"error {info['cartesian_error']:.2e} m, {info['orientation_error']:.2e} rad"
        else:
            self._errors = f"error {info['error_norm']:.2e}"
        if info["left_chart"]:
            self._errors += ", left the chart"

    def scene(self, label: str) -> Scene:
        """What the frame shows, titled ``label`` and the last trial's errors."""
        title = label + (f"\n{self._errors}" if self.count else "")
        return Scene(self._waypoints, self._robot, self._names, self._paths, title)
