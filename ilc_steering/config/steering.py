"""A whole scenario: :class:`SteeringConfig`, its sections and the robot's config keys, with the
checks that span keys (dimensions, tolerances, the task's chart, the time grid, eq. 12's travel)."""

from __future__ import annotations

import re
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any

import numpy as np

from ilc_steering.config.sections import (
    CyclicTaskConfig,
    LearningConfig,
    SegmentConfig,
    SegmentedTaskConfig,
    SimulationConfig,
    TaskConfig,
    domain,
    require,
)
from ilc_steering.core import robots
from ilc_steering.core.grid import check_grid
from ilc_steering.core.plants import PlantConfig
from ilc_steering.core.robots.car import frame_angle, rotate
from ilc_steering.errors import INTERRUPTS, ConfigError, described
from ilc_steering.schema import NAME_PATTERN, show

__all__ = ["MIN_TRAVEL", "SteeringConfig", "check_name", "robots_code", "v1_travel"]

_NAME = re.compile(NAME_PATTERN)
MIN_TRAVEL = 1e-3
"""[m for a car] the least distance ``sum_i |v1_i| Delta_i`` the nominal ``v1`` must cover along ``z1``:
below it ``W`` is all but singular and the ``c11`` box all but zero wide."""


@contextmanager
def robots_code(owner: Any, what: str, model: str, values: bool = False, key: str = "plant") -> Iterator[None]:
    """A call into a robot's own code while its config loads: ``owner`` (its config class or
    object, or its plant) runs ``what`` (``"plant()"``; ``""`` for the class's construction and
    ``__post_init__``). What a user's robot raises (``sys.exit()`` included; an interrupt passes) is
    a :class:`ConfigError` naming ``key.model`` (``model``, as loaded from ``module:ConfigClass``
    when it was), the class and what raised: the user's robot cannot take this config, bad input of
    theirs (exit 2; ``docs/robots.md``), never the library's bug. A ``ValueError`` passes to the
    caller that puts it under its key, unless ``values`` (where no key of the config is at fault).
    The library's own robots' other errors pass too: those are its bugs (exit 3)."""
    try:
        yield
    except (ConfigError, *INTERRUPTS):
        raise
    except BaseException as error:
        cls = owner if isinstance(owner, type) else type(owner)
        if (isinstance(error, ValueError) and not values) or (
            not isinstance(error, ValueError) and cls.__module__.startswith("ilc_steering.")
        ):
            raise
        entry = robots.saved_name(model)
        label = f"{key + '.' if key else ''}model {model!r}" + (f" ({entry})" if entry != model else "")
        raise ConfigError(
            f"{label}: {cls.__qualname__}{'.' + what if what else ''} raised {described(error)}"
        ) from None


def v1_travel(z1_change: float, pieces: Sequence[float], v1_fixed: Sequence[float], ramp: float | None) -> float:
    """The distance ``sum_i |v1_i| Delta_i`` the nominal ``v1`` covers along ``z1`` for a change of
    ``z1_change`` (eq. 12: the learned first piece covers what the fixed ones leave; a trapezoid's
    area is its plateau times ``Delta - ramp``); the loader refuses a task whose travel is within
    :data:`MIN_TRAVEL`, and a generator of tasks must too."""
    ramp = ramp or 0.0
    fixed = sum(v * (d - ramp) for v, d in zip(v1_fixed, pieces[1:]))
    return abs(z1_change - fixed) + sum(abs(v) * (d - ramp) for v, d in zip(v1_fixed, pieces[1:]))


@dataclass(frozen=True)
class SteeringConfig:
    name: str
    plant: PlantConfig  # plant.model names a robot of ilc_steering.core.robots, whose config class has the rest
    task: TaskConfig | CyclicTaskConfig | SegmentedTaskConfig
    learning: LearningConfig
    simulation: SimulationConfig = field(default_factory=SimulationConfig)

    @property
    def is_cyclic(self) -> bool:
        return isinstance(self.task, CyclicTaskConfig)

    @property
    def is_segmented(self) -> bool:
        """A manoeuvre of several segments in one trial (``task.segments`` beside ``task.start``)."""
        return isinstance(self.task, SegmentedTaskConfig)

    def points(self) -> list[tuple[str, tuple[float, ...]]]:
        """The task's configurations with their keys: start and goal, the waypoints of a cycle, or start,
        the via points and goal of a manoeuvre."""
        if isinstance(self.task, CyclicTaskConfig):
            return [(f"task.waypoints[{i}]", w) for i, w in enumerate(self.task.waypoints)]
        if isinstance(self.task, SegmentedTaskConfig):
            via = [(f"task.via[{i}]", w) for i, w in enumerate(self.task.via)]
            return [("task.start", self.task.start), *via, ("task.goal", self.task.goal)]
        return [("task.start", self.task.start), ("task.goal", self.task.goal)]

    def segment_configs(self) -> list[SteeringConfig]:
        """A manoeuvre's segments, each the one-trial task from its waypoint to the next (checked as
        one when the config loaded); ``[self]`` for a one-trial task. Not for a cycle."""
        if isinstance(self.task, SegmentedTaskConfig):
            return list(self._segments)
        return [self]

    def legs(self) -> list[tuple[str, TaskConfig | SegmentConfig]]:
        """One (key, segment) per trial of a cycle, or per segment of a manoeuvre: the task itself for a
        one-trial task."""
        if isinstance(self.task, SegmentedTaskConfig):
            return [(f"task.segments[{i}]", leg) for i, leg in enumerate(self.task.segments)]
        if isinstance(self.task, CyclicTaskConfig):
            many = len(self.task.segments) > 1
            return [
                (f"task.segments[{i if many else 0}]", self.task.segment(i)) for i in range(len(self.task.waypoints))
            ]
        return [("task", self.task)]

    def frame(self) -> float:
        """The rotation [rad] of the task frame (:func:`~ilc_steering.core.robots.car.frame_angle`, computed once,
        on loading; a manoeuvre's first segment's); 0 without a pose."""
        if isinstance(self.task, SegmentedTaskConfig):
            return self._segments[0].frame()
        return self._frame

    @cached_property
    def _frame(self) -> float:
        """The task frame of a one-trial task or a cycle: ``task.frame``, else ``frame_angle`` of the
        points' headings (a cached property: derived, not a field, so ``asdict`` and ``==`` ignore it)."""
        if not self.plant.kind.has_pose:
            return 0.0
        if isinstance(self.task, TaskConfig) and self.task.frame is not None:
            return self.task.frame
        points = self.points()
        with domain(points[-1][0]):
            return frame_angle(*(point[2] for _, point in points))

    def __post_init__(self) -> None:
        check_name(self.name)
        n = self.plant.dimension
        for key in ("measurement_noise", "start_error"):
            noise = getattr(self.simulation, key)
            require(
                noise is None or len(noise) == n,
                f"simulation.{key}",
                f"needs one sigma per coordinate ({n} for plant.model {self.plant.model}), got {len(noise or ())}",
            )
        points = self.points()
        for key, point in points:
            require(len(point) == n, key, f"needs {n} values for plant.model {self.plant.model}, got {len(point)}")
        tolerance = self.learning.tolerance
        if self.plant.kind.has_pose:
            require(
                tolerance.cartesian is not None and tolerance.orientation is not None and tolerance.error is None,
                "learning.tolerance",
                f"a {self.plant.model} needs {{cartesian: [m], orientation: [rad]}} "
                "and no error (that is for chained plants)",
            )
        else:
            require(
                tolerance.error is not None and tolerance.cartesian is None and tolerance.orientation is None,
                "learning.tolerance",
                "a chained plant needs {error: ...} alone (it has no Cartesian or orientation error)",
            )
        if isinstance(self.task, SegmentedTaskConfig):
            self._segments  # noqa: B018 (each segment checked as the one-trial task it is)
            return
        frame = self._frame
        if self.plant.kind.has_pose and isinstance(self.task, TaskConfig) and self.task.frame is not None:
            for key, point in points:  # the points' chart is checked in it below; a heading off it is the frame's
                turned = point[2] - frame
                require(
                    abs(turned) < np.pi / 2,
                    "task.frame",
                    f"{frame} rad puts {key} at a heading of {turned:.6g} rad in the task frame ({point[2]:.6g} "
                    "rad in the world's), outside the chart's (-pi/2, pi/2); leave it out for frame_angle's",
                )
        model = self.plant.model
        with robots_code(self.plant, "plant()", model, values=True):
            plant = self.plant.plant()
        with domain("plant", prefix="plant."), robots_code(self.plant, "check_task()", model):
            self.plant.check_task(self.simulation.max_step, self.is_cyclic)
        task_points = []
        for key, point in points:
            with domain(key, {"phi": key, "configuration": key}):
                q = np.array(point, dtype=np.float64)
                task_points.append(rotate(q, frame) if self.plant.kind.has_pose else q)
                with robots_code(plant, "check_configuration()", model):
                    plant.check_configuration(task_points[-1])
        cost = self.learning.cost
        if cost != "none":
            require(not self.is_cyclic, "learning.cost", "is for one-trial tasks (the cyclic law has none)")
            require(
                cost != "steering_margin" or self.plant.steering_limit is not None,
                "learning.cost",
                "steering_margin needs a robot with plant.steering_limit (a car, a car_trailer)",
            )
            require(
                self.legs()[0][1].v2_terms > n - 1,
                "learning.cost",
                f"{cost} needs task.v2_terms > n - 1 = {n - 1}, spare coefficients for a null space of W",
            )
        with robots_code(self.plant, "nominal_map()", model, values=True):
            chained_map = self.plant.nominal_map()
        z1 = []
        for (key, _), q in zip(points, task_points):
            with domain(key), robots_code(chained_map, "to_chained()", model):
                z1.append(float(np.asarray(chained_map.to_chained(q), dtype=np.float64)[..., 0]))
        for i, (key, leg) in enumerate(self.legs()):
            require(
                leg.v2_terms >= n - 1,
                f"{key}.v2_terms",
                f"needs q >= n - 1 = {n - 1} to reach every z_b (section 3), got {leg.v2_terms}",
            )
            with domain(f"{key}.pieces", {"max_step": "simulation.max_step"}):
                check_grid(leg.pieces, self.simulation.max_step)
            require(  # a step across a switch of the inputs would blur the switch the learning law relies on
                self.simulation.max_step <= min(leg.pieces),
                "simulation.max_step",
                f"{self.simulation.max_step} s is longer than the shortest piece of {key} ({min(leg.pieces)} s); "
                "give a step at most as long as every piece",
            )
            # eq. 12 sets the learned v1 from the change of z1 (x in the task frame for the car, section
            # 2.1; whatever the robot's chained map makes it for another robot)
            travel = v1_travel(z1[(i + 1) % len(points)] - z1[i], leg.pieces, leg.v1_fixed, leg.ramp)
            require(
                travel > MIN_TRAVEL,
                f"{key}.v1_fixed",
                f"the start and goal share z1 (the chained form's first coordinate; x in the task frame for a car): "
                f"v1 covers only {travel:.3g} along z1, so W is singular (eq. 11); add a piece with a nonzero "
                "fixed v1, as in the paper's parallel parking",
            )

    @cached_property
    def _segments(self) -> tuple[SteeringConfig, ...]:
        """A manoeuvre's segments, each checked as the one-trial task it is (a waypoint's fault named by
        its own key, ``task.start``, ``task.via[i]`` or ``task.goal``; the segment's by
        ``task.segments[k]``), and its direction against the nominal solution's: the sign of ``c11``
        (eq. 12). A cached property: derived, not a field, so ``asdict`` and ``==`` ignore it."""
        task = self.task
        assert isinstance(task, SegmentedTaskConfig)
        points, segments = self.points(), []
        for k, leg in enumerate(task.segments):
            key = f"task.segments[{k}]"
            (start_key, start), (goal_key, goal) = points[k], points[k + 1]
            one = TaskConfig(
                start=start,
                goal=goal,
                pieces=leg.pieces,
                v1_fixed=leg.v1_fixed,
                v2_terms=leg.v2_terms,
                action_bound=leg.action_bound,
                v1_shape=leg.v1_shape,
                ramp=leg.ramp,
                frame=leg.frame,
            )
            try:
                segment = SteeringConfig(f"{self.name[:96]}.{k}", self.plant, one, self.learning, self.simulation)
            except ConfigError as error:
                message = str(error).replace("task.", "task.segments[#].")  # the segment's own keys
                for end, name in (("start", start_key), ("goal", goal_key)):  # a waypoint's, by its own key
                    message = re.sub(rf"task\.segments\[#\]\.{end}\b", f"{name} (in {key}'s frame)", message)
                raise ConfigError(message.replace("task.segments[#]", key)) from None
            if leg.direction is not None:
                ends = [
                    rotate(np.array(q), segment.frame()) if self.plant.kind.has_pose else np.array(q)
                    for q in (start, goal)
                ]
                chained_map = self.plant.nominal_map()
                z1 = [float(np.asarray(chained_map.to_chained(q), dtype=np.float64)[..., 0]) for q in ends]
                learned = z1[1] - z1[0] - leg.profile().fixed_displacement  # eq. 12: learned_area * c11
                sign = 1.0 if leg.direction == "forward" else -1.0
                require(
                    sign * learned > 0,
                    f"{key}.direction",
                    f"{leg.direction} disagrees with the segment's nominal c11 (eq. 12: it moves "
                    f"{learned:+.3g} along z1 on the learned piece, x in frame {segment.frame():.4g} rad)",
                )
            segments.append(segment)
        return tuple(segments)


def check_name(name: str) -> None:
    """A config's ``name``: it names output files (``ConfigError`` naming the key otherwise)."""
    require(
        isinstance(name, str) and bool(_NAME.fullmatch(name)),
        "name",
        f"must be 1-100 letters, digits, '_', '-' or '.', starting with a letter or digit (it names output files), "
        f"got {show(name)}",
    )
