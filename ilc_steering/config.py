"""Scenario configs: frozen dataclasses loaded from YAML.

Every key is checked: an unknown key, a wrong type, a missing field or an out-of-range value
raises :class:`ConfigError` naming the key and the file. Units are in the field comments and in
the packaged YAML files (``configs/``).

The YAML is read strictly where YAML 1.1 (PyYAML) and a reader disagree: a number with a leading
zero (``010``, octal 8 to YAML 1.1, 10 to YAML 1.2), a sexagesimal one (``1:30``, 90 to YAML
1.1) and one with an underscore (``0.0_2``, 0.002 to YAML 1.1, text to YAML 1.2) are refused for
a numeric key, naming the key and both readings; the same text under a string key stays text.
``1e-3`` is the number it looks like; merge keys (``<<: *defaults``) are
honoured. A file is read through :mod:`ilc_steering.readers`: its size checked before it is read
(:data:`MAX_FILE_BYTES`), its nesting after (:data:`~ilc_steering.readers.MAX_DEPTH`).
"""

from __future__ import annotations

import dataclasses
import re
import reprlib
import types
import typing
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from importlib import resources
from math import isfinite
from pathlib import Path
from typing import Any, Literal

import numpy as np

from ilc_steering.core import robots
from ilc_steering.core.checks import check_gains, check_jitter, check_noise
from ilc_steering.core.grid import check_grid
from ilc_steering.core.plants import PlantConfig
from ilc_steering.core.profiles import PiecewiseProfile
from ilc_steering.core.robots.car import frame_angle, rotate
from ilc_steering.core.trapezoid import TrapezoidProfile
from ilc_steering.entries import CONFIG_FOLDERS
from ilc_steering.errors import ConfigError, ParameterError
from ilc_steering.readers import MAX_DEPTH, check_depth, read_text

__all__ = [
    "CyclicTaskConfig",
    "LearningConfig",
    "SegmentConfig",
    "SimulationConfig",
    "SteeringConfig",
    "TaskConfig",
    "ToleranceConfig",
    "load_config",
    "packaged_configs",
]


_FOLDERS = CONFIG_FOLDERS
"""The folder of the config being loaded, searched for a robot's module it names."""


def _require(ok: bool, key: str, message: str) -> None:
    if not ok:
        raise ConfigError(f"{key}: {message}")


def _positive(value: float) -> bool:
    return isfinite(value) and value > 0


@contextmanager
def _domain(key: str = "", names: dict[str, str] | None = None, prefix: str = "") -> Iterator[None]:
    """Build a domain object, its range rules reported as config errors: a
    :class:`ParameterError` names the key (its parameter, renamed by ``names``, after ``prefix``);
    any other ``ValueError`` is put under ``key``."""
    try:
        yield
    except ConfigError:
        raise
    except ParameterError as error:
        raise ConfigError(f"{prefix}{(names or {}).get(error.name, error.name)}: {error.problem}") from None
    except ValueError as error:
        raise ConfigError(f"{key}: {error}") from None


def _profile(leg: SegmentConfig | TaskConfig) -> PiecewiseProfile | TrapezoidProfile:
    if leg.v1_shape == "constant":
        _require(leg.ramp is None, "ramp", "is for v1_shape: trapezoid; with v1_shape: constant leave it out")
        with _domain():
            return PiecewiseProfile(leg.pieces, leg.v1_fixed, leg.v2_terms)
    _require(leg.ramp is not None, "ramp", "v1_shape: trapezoid needs the ramp time [s] at both ends of every piece")
    with _domain():
        return TrapezoidProfile(leg.pieces, leg.v1_fixed, leg.v2_terms, float(leg.ramp or 0.0))


def _check_bound(bound: tuple[float, ...] | None, size: int) -> None:
    if bound is not None:
        _require(len(bound) == size, "action_bound", f"needs 1 + v2_terms = {size} values, got {len(bound)}")
        _require(
            all(_positive(b) and b <= MAX_ACTION_BOUND for b in bound),
            "action_bound",
            f"values must be > 0 and at most {MAX_ACTION_BOUND:g} (the action space is float32)",
        )


@dataclass(frozen=True)
class TaskConfig:
    # car: x [m], y [m], theta [rad], phi [rad]; unicycle: x, y, theta; car_trailer: the trailer's x1 [m],
    # y1 [m], theta1 [rad], then the car's phi [rad] and the hitch angle delta [rad]; chained: z
    start: tuple[float, ...]
    goal: tuple[float, ...]
    pieces: tuple[float, ...]  # Delta_i [s]; T is their sum
    v1_fixed: tuple[float, ...]  # c12..c1p: v1 on pieces 2..p [m/s for the car]
    v2_terms: int  # q, the number of basis functions of v2
    action_bound: tuple[float, ...] | None = None  # |c_i| bounds; None: 10x NominalModel.action_scale()
    v1_shape: Literal["constant", "trapezoid"] = "constant"  # v1 on each piece: a level, or section 5's trapezoid
    ramp: float | None = None  # [s] trapezoid only: the ramp at both ends of every piece, < half the shortest
    frame: float | None = None  # [rad] rotation of the task frame; None: frame_angle's (the orientations' middle)

    def __post_init__(self) -> None:
        _require(self.frame is None or isfinite(self.frame), "frame", f"must be a finite angle [rad], got {self.frame}")
        for key in ("start", "goal"):
            _require(all(isfinite(v) for v in getattr(self, key)), key, "values must be finite")
        _profile(self)
        _check_bound(self.action_bound, 1 + self.v2_terms)

    def profile(self) -> PiecewiseProfile | TrapezoidProfile:
        """The input profile of eqs. 15-17 (section 5's with ``v1_shape: trapezoid``)."""
        return _profile(self)


@dataclass(frozen=True)
class SegmentConfig:
    pieces: tuple[float, ...]  # Delta_i [s] of the segment
    v1_fixed: tuple[float, ...]  # v1 on pieces 2..p [m/s for the car]
    v2_terms: int  # q
    v1_shape: Literal["constant", "trapezoid"] = "constant"  # as task.v1_shape
    ramp: float | None = None  # [s] as task.ramp

    def __post_init__(self) -> None:
        _profile(self)

    def profile(self) -> PiecewiseProfile | TrapezoidProfile:
        """The input profile of eqs. 15-17 (section 5's with ``v1_shape: trapezoid``)."""
        return _profile(self)


@dataclass(frozen=True)
class CyclicTaskConfig:
    waypoints: tuple[tuple[float, ...], ...]  # q_0^d (home), q_1^d, ...; the cycle ends back at home
    segments: tuple[SegmentConfig, ...]  # one per segment (waypoint l-1 -> l), or one for all
    action_bound: tuple[float, ...] | None = None  # |c_i| bounds; None: 10x the largest action_scale()

    def __post_init__(self) -> None:
        count = len(self.waypoints)
        _require(count >= 2, "waypoints", f"a cycle needs at least 2 waypoints, got {count}")
        _require(all(isfinite(v) for w in self.waypoints for v in w), "waypoints", "values must be finite")
        _require(
            len(self.segments) in (1, count),
            "segments",
            f"needs 1 entry or one per segment ({count}), got {len(self.segments)}",
        )
        terms = sorted({s.v2_terms for s in self.segments})
        _require(len(terms) == 1, "segments", f"every segment needs the same v2_terms (one action space), got {terms}")
        _check_bound(self.action_bound, 1 + terms[0])

    def segment(self, index: int) -> SegmentConfig:
        """The segment from waypoint ``index`` to waypoint ``index + 1`` (mod the cycle)."""
        return self.segments[0] if len(self.segments) == 1 else self.segments[index]


@dataclass(frozen=True)
class ToleranceConfig:
    cartesian: float | None = None  # [m], car
    orientation: float | None = None  # [rad], car
    error: float | None = None  # Euclidean norm of the chained-coordinate error, chained plant

    def __post_init__(self) -> None:
        for key in ("cartesian", "orientation", "error"):
            value = getattr(self, key)
            _require(value is None or _positive(value), key, f"must be > 0, got {value}")


@dataclass(frozen=True)
class LearningConfig:
    nu_a: float  # gain of eq. 33, in (0, 2)
    nu_b: float  # gain of eq. 34, in (0, 2)
    trials: int  # how many trials (for a cyclic task: cycles) a run makes
    tolerance: ToleranceConfig
    # section 7: a cost the spare coefficients of v2 (v2_terms > n - 1) minimize in the null space of W
    cost: Literal["none", "path_length", "curvature", "steering_margin"] = "none"

    def __post_init__(self) -> None:
        with _domain():
            check_gains(self.nu_a, self.nu_b)
        _require(
            1 <= self.trials <= MAX_TRIALS, "trials", f"must be a whole number in [1, {MAX_TRIALS}], got {self.trials}"
        )


@dataclass(frozen=True)
class SimulationConfig:
    max_step: float = 1.0 / 32.0  # longest integrator step [s]
    # sigma of the final configuration's measurement, one per coordinate (car: x [m], y [m], theta [rad],
    # phi [rad]; chained: z); None: measured exactly
    measurement_noise: tuple[float, ...] | None = None
    # sigma of the start configuration, drawn for every trial (imperfect homing), one per coordinate as
    # measurement_noise; None: the exact start
    start_error: tuple[float, ...] | None = None
    parameter_jitter: float = 0.0  # relative sigma of the true geometry (car) or gains (chained), per trial

    def __post_init__(self) -> None:
        _require(_positive(self.max_step), "max_step", f"must be > 0 s, got {self.max_step}")
        for key in ("measurement_noise", "start_error"):
            value = getattr(self, key)
            if value is not None:
                with _domain(key):
                    check_noise(value, len(value), key)
        with _domain():
            check_jitter(self.parameter_jitter)


@dataclass(frozen=True)
class SteeringConfig:
    name: str
    plant: PlantConfig  # plant.model names a robot of ilc_steering.core.robots, whose config class has the rest
    task: TaskConfig | CyclicTaskConfig
    learning: LearningConfig
    simulation: SimulationConfig = field(default_factory=SimulationConfig)

    @property
    def is_cyclic(self) -> bool:
        return isinstance(self.task, CyclicTaskConfig)

    def points(self) -> list[tuple[str, tuple[float, ...]]]:
        """The task's configurations with their keys: start and goal, or the waypoints."""
        if isinstance(self.task, CyclicTaskConfig):
            return [(f"task.waypoints[{i}]", w) for i, w in enumerate(self.task.waypoints)]
        return [("task.start", self.task.start), ("task.goal", self.task.goal)]

    def legs(self) -> list[tuple[str, TaskConfig | SegmentConfig]]:
        """One (key, segment) per trial of a cycle: the task itself for a one-trial task."""
        if isinstance(self.task, CyclicTaskConfig):
            many = len(self.task.segments) > 1
            return [
                (f"task.segments[{i if many else 0}]", self.task.segment(i)) for i in range(len(self.task.waypoints))
            ]
        return [("task", self.task)]

    def frame(self) -> float:
        """The rotation [rad] of the task frame (:func:`~ilc_steering.core.robots.car.frame_angle`, computed once,
        on loading); 0 without a pose."""
        frame: float = self.__dict__["_frame"]
        return frame

    def __post_init__(self) -> None:
        _require(
            bool(_NAME.fullmatch(self.name)),
            "name",
            f"must be 1-100 letters, digits, '_', '-' or '.', starting with a letter or digit (it names output files), "
            f"got {_show(self.name)}",
        )
        n = self.plant.dimension
        for key in ("measurement_noise", "start_error"):
            noise = getattr(self.simulation, key)
            _require(
                noise is None or len(noise) == n,
                f"simulation.{key}",
                f"needs one sigma per coordinate ({n} for plant.model {self.plant.model}), got {len(noise or ())}",
            )
        points = self.points()
        for key, point in points:
            _require(len(point) == n, key, f"needs {n} values for plant.model {self.plant.model}, got {len(point)}")
        tolerance = self.learning.tolerance
        if self.plant.kind.has_pose:
            _require(
                tolerance.cartesian is not None and tolerance.orientation is not None and tolerance.error is None,
                "learning.tolerance",
                f"a {self.plant.model} needs {{cartesian: [m], orientation: [rad]}} "
                "and no error (that is for chained plants)",
            )
        else:
            _require(
                tolerance.error is not None and tolerance.cartesian is None and tolerance.orientation is None,
                "learning.tolerance",
                "a chained plant needs {error: ...} alone (it has no Cartesian or orientation error)",
            )
        frame = 0.0
        if self.plant.kind.has_pose:
            with _domain(points[-1][0]):
                frame = frame_angle(*(point[2] for _, point in points))
            if isinstance(self.task, TaskConfig) and self.task.frame is not None:
                frame = self.task.frame  # the points' chart is checked in it below
        object.__setattr__(self, "_frame", frame)  # derived, not a field: asdict and == ignore it
        plant = self.plant.plant()
        with _domain("plant", prefix="plant."):
            self.plant.check_task(self.simulation.max_step, self.is_cyclic)
        task_points = []
        for key, point in points:
            with _domain(key, {"phi": key, "configuration": key}):
                q = np.array(point, dtype=np.float64)
                task_points.append(rotate(q, frame) if self.plant.kind.has_pose else q)
                plant.check_configuration(task_points[-1])
        cost = self.learning.cost
        if cost != "none":
            _require(not self.is_cyclic, "learning.cost", "is for one-trial tasks (the cyclic law has none)")
            _require(
                cost != "steering_margin" or self.plant.steering_limit is not None,
                "learning.cost",
                "steering_margin needs a robot with plant.steering_limit (a car, a car_trailer)",
            )
            _require(
                self.legs()[0][1].v2_terms > n - 1,
                "learning.cost",
                f"{cost} needs task.v2_terms > n - 1 = {n - 1}, spare coefficients for a null space of W",
            )
        chained_map = self.plant.nominal_map()
        z1 = []
        for (key, _), q in zip(points, task_points):
            with _domain(key):
                z1.append(float(np.asarray(chained_map.to_chained(q), dtype=np.float64)[..., 0]))
        for i, (key, leg) in enumerate(self.legs()):
            _require(
                leg.v2_terms >= n - 1,
                f"{key}.v2_terms",
                f"needs q >= n - 1 = {n - 1} to reach every z_b (section 3), got {leg.v2_terms}",
            )
            with _domain(f"{key}.pieces", {"max_step": "simulation.max_step"}):
                check_grid(leg.pieces, self.simulation.max_step)
            _require(  # a step across a switch of the inputs would blur the switch the learning law relies on
                self.simulation.max_step <= min(leg.pieces),
                "simulation.max_step",
                f"{self.simulation.max_step} s is longer than the shortest piece of {key} ({min(leg.pieces)} s); "
                "give a step at most as long as every piece",
            )
            # eq. 12 sets the learned v1 from the change of z1 (x in the task frame for the car, section
            # 2.1; whatever the robot's chained map makes it for another robot)
            z1_change = z1[(i + 1) % len(points)] - z1[i]
            ramp = leg.ramp or 0.0  # a trapezoid's area is its plateau times (Delta - ramp)
            fixed = sum(v * (d - ramp) for v, d in zip(leg.v1_fixed, leg.pieces[1:]))
            travel = abs(z1_change - fixed) + sum(abs(v) * (d - ramp) for v, d in zip(leg.v1_fixed, leg.pieces[1:]))
            _require(
                travel > MIN_TRAVEL,
                f"{key}.v1_fixed",
                f"the start and goal share z1 (the chained form's first coordinate; x in the task frame for a car): "
                f"v1 covers only {travel:.3g} along z1, so W is singular (eq. 11); add a piece with a nonzero "
                "fixed v1, as in the paper's parallel parking",
            )


_EXPONENT_NUMBER = re.compile(r"[-+]?(\d+\.?\d*|\.\d+)[eE][-+]?\d+")
_REPR = reprlib.Repr()
_REPR.maxstring, _REPR.maxother, _REPR.maxlist, _REPR.maxdict, _REPR.maxlevel = 60, 60, 6, 4, 3
_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.\-]{0,99}")
MIN_TRAVEL = 1e-3
"""[m for a car] the least distance ``sum_i |v1_i| Delta_i`` the nominal ``v1`` must cover along ``z1``:
below it ``W`` is all but singular and the ``c11`` box all but zero wide."""
MAX_ACTION_BOUND = 1e12
"""The largest ``task.action_bound`` entry."""
MAX_FILE_BYTES = 1 << 20
"""Largest config file read [bytes]."""
MAX_VALUES = 100_000
"""Most values (mapping entries and list items, aliases expanded) a config may hold."""
MAX_TRIALS = 100_000
"""The largest ``learning.trials`` (and ``run --trials``): every trial's record is kept in memory."""


class _Ambiguous(str):
    """A YAML scalar that YAML 1.1 reads as a number other than the one its text shows (``010``,
    ``1:30``) or that YAML 1.2 reads as text (``1_0``, ``0.0_2``): kept as its text, refused by
    :func:`_coerce` under a numeric key, with both readings."""

    reading: str = ""


_LEADING_ZERO = re.compile(r"[-+]?0[0-9_]+")


def _show(value: Any) -> str:
    """A bounded ``repr`` for messages: a huge value (an alias bomb) must not cost its size."""
    return _REPR.repr(value)


def _is_optional(hint: Any) -> bool:
    return isinstance(hint, types.UnionType) and type(None) in typing.get_args(hint)


def _coerce(hint: Any, value: Any, key: str) -> Any:
    """Check ``value`` against the type hint ``hint`` and convert lists to tuples."""
    if isinstance(value, _Ambiguous):
        if hint is str or typing.get_origin(hint) is Literal or (_is_optional(hint) and str in typing.get_args(hint)):
            value = str(value)
        else:
            raise ConfigError(
                f"{key}: {str(value)!r} is ambiguous: YAML 1.1 reads it as {value.reading}; "
                "write the number without a leading zero, colon or underscore (e.g. 10, 90, 0.002)"
            )
    origin = typing.get_origin(hint)
    if isinstance(hint, types.UnionType):
        options = [a for a in typing.get_args(hint) if a is not type(None)]
        if value is None:
            _require(_is_optional(hint), key, "must not be null")
            return None
        if all(dataclasses.is_dataclass(a) for a in options):
            return _build_tagged(options, value, key)
        return _coerce(options[0], value, key)
    if hint is PlantConfig:
        _require(isinstance(value, dict), key, f"must be a mapping, got {_show(value)}")
        model = value.get("model")
        if isinstance(model, str) and robots.ENTRY.fullmatch(model):  # "package.module:ConfigClass", as --learner
            with _domain(f"{key}.model"):
                cls = robots.config_class(model, _FOLDERS.get())
            return _build(cls, {**value, "model": robots.model_name(cls)}, key)
        known = robots.names()
        _require(
            isinstance(model, str) and model in known,
            f"{key}.model",
            f"must be one of {known} or 'package.module:ConfigClass', got {_show(model)}",
        )
        with _domain(f"{key}.model"):  # a plugin that cannot load is named, with its package
            cls = robots.config_class(model)
        return _build(cls, value, key)
    if dataclasses.is_dataclass(hint):
        return _build(hint, value, key)
    if origin is tuple:
        _require(isinstance(value, (list, tuple)), key, f"must be a list, got {_show(value)}")
        return tuple(_coerce(typing.get_args(hint)[0], v, f"{key}[{i}]") for i, v in enumerate(value))
    if origin is Literal:
        allowed = typing.get_args(hint)
        _require(
            isinstance(value, str) and value in allowed, key, f"must be one of {list(allowed)}, got {_show(value)}"
        )
        return value
    if hint is float:
        if isinstance(value, str) and _EXPONENT_NUMBER.fullmatch(value.strip()):
            value = float(value)  # YAML 1.1 (PyYAML) reads 1e-3 as a string; users mean the number
        _require(
            isinstance(value, (int, float)) and not isinstance(value, bool),
            key,
            f"must be a number, got {_show(value)}",
        )
        try:
            return float(value)
        except OverflowError:  # an integer beyond the largest float
            raise ConfigError(f"{key}: must be a number a float can hold, got {_show(value)}") from None
    if hint is int:
        _require(isinstance(value, int) and not isinstance(value, bool), key, f"must be an integer, got {_show(value)}")
        return value
    if hint is str:
        _require(isinstance(value, str), key, f"must be a string, got {_show(value)}")
        return value
    raise TypeError(f"no rule for type {hint} at {key}")


def _build_tagged(options: list[Any], value: Any, key: str) -> Any:
    """Pick the dataclass whose ``model`` literal matches ``value['model']`` or, without a
    ``model`` field, the one whose first field is a key of ``value`` (``start`` or ``waypoints``)."""
    _require(isinstance(value, dict), key, f"must be a mapping, got {_show(value)}")
    if not all("model" in typing.get_type_hints(o) for o in options):
        markers = {dataclasses.fields(o)[0].name: o for o in options}
        found = [m for m in markers if m in value]
        _require(len(found) == 1, key, f"needs exactly one of the keys {list(markers)}, got {sorted(map(str, value))}")
        return _build(markers[found[0]], value, key)
    tags = {typing.get_args(typing.get_type_hints(o)["model"])[0]: o for o in options}
    model = value.get("model")
    _require(
        isinstance(model, str) and model in tags, f"{key}.model", f"must be one of {list(tags)}, got {_show(model)}"
    )
    return _build(tags[value["model"]], value, key)


def _build(cls: Any, value: Any, key: str) -> Any:
    _require(isinstance(value, dict), key or "config", f"must be a mapping, got {_show(value)}")
    hints = typing.get_type_hints(cls)
    fields = {f.name: f for f in dataclasses.fields(cls)}
    prefix = f"{key}." if key else ""
    unknown = sorted(map(str, set(value) - set(fields)))
    _require(
        not unknown, prefix + str(unknown[0]) if unknown else key, f"unknown key; allowed keys here: {sorted(fields)}"
    )
    kwargs = {}
    for name, f in fields.items():
        if name in value:
            kwargs[name] = _coerce(hints[name], value[name], prefix + name)
        else:
            has_default = f.default is not dataclasses.MISSING or f.default_factory is not dataclasses.MISSING
            _require(has_default, prefix + name, "missing required key")
    try:
        return cls(**kwargs)
    except ConfigError as error:
        raise ConfigError(f"{prefix}{error}") from None
    except ParameterError as error:  # a robot's config keys check their ranges with the core's rules
        raise ConfigError(f"{prefix}{error.name}: {error.problem}") from None


def packaged_configs() -> list[str]:
    """Names of the configs shipped in ``ilc_steering.configs``."""
    root = resources.files("ilc_steering.configs")
    return sorted(p.name.removesuffix(".yaml") for p in root.iterdir() if p.name.endswith(".yaml"))


def _count_values(data: Any) -> int:
    """The number of values in ``data`` with aliases expanded, counting no further than :data:`MAX_VALUES`."""
    count, todo = 0, [data]
    while todo and count <= MAX_VALUES:
        item = todo.pop()
        if isinstance(item, dict):
            count += len(item)
            todo.extend(item.values())
        elif isinstance(item, list):
            count += len(item)
            todo.extend(item)
    return count


def _strict_number(kind: str) -> Any:
    """A constructor of YAML 1.1 ``int`` or ``float`` scalars that keeps a leading-zero or
    sexagesimal one as :class:`_Ambiguous` text."""
    import yaml

    base = yaml.SafeLoader.yaml_constructors[f"tag:yaml.org,2002:{kind}"]

    def construct(loader: Any, node: Any) -> Any:
        text = str(node.value)
        number = base(loader, node)
        if ":" in text or "_" in text or _LEADING_ZERO.fullmatch(text):  # YAML 1.2 reads 1_0 and 0.0_2 as text
            marked = _Ambiguous(text)
            marked.reading = f"{number:g}" if isinstance(number, float) else str(number)
            return marked
        return number

    return construct


def _depth(data: Any, origin: str) -> None:
    try:
        check_depth(data, origin)
    except ValueError as error:
        raise ConfigError(f"{error}; not a config") from None


def _yaml(text: str, origin: str) -> Any:
    """Parse a config's YAML: safe types only, merge keys, no duplicate keys, integers read strictly,
    at most :data:`MAX_VALUES` values and :data:`~ilc_steering.readers.MAX_DEPTH` levels."""
    import yaml

    merge = "tag:yaml.org,2002:merge"

    class Loader(yaml.SafeLoader):
        def construct_mapping(self, node: Any, deep: bool = False) -> Any:
            # a key given twice is a typo; a key a merge (<<) brings and the mapping overrides is not
            keys = [self.construct_object(k, deep=deep) for k, _ in node.value if k.tag != merge]
            duplicated = sorted({str(k) for k in keys if keys.count(k) > 1})
            if duplicated:
                line = node.start_mark.line + 1
                raise ConfigError(f"{origin}: duplicate key {duplicated[0]!r} in the mapping at line {line}")
            return super().construct_mapping(node, deep=deep)

    Loader.add_constructor("tag:yaml.org,2002:int", _strict_number("int"))
    Loader.add_constructor("tag:yaml.org,2002:float", _strict_number("float"))
    try:
        data = yaml.load(text, Loader=Loader)
    except RecursionError:
        raise ConfigError(f"{origin}: nested deeper than {MAX_DEPTH} levels; not a config") from None
    except yaml.YAMLError as error:
        mark = getattr(error, "problem_mark", None)
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark is not None else ""
        problem = getattr(error, "problem", None) or str(error).splitlines()[0]
        raise ConfigError(f"{origin}: not valid YAML{where}: {problem}") from None
    if _count_values(data) > MAX_VALUES:
        raise ConfigError(f"{origin}: more than {MAX_VALUES} values (anchors and aliases expanded); not a config")
    _depth(data, origin)
    return data


def _read(source: str | Path) -> tuple[Any, str]:
    path = Path(source)
    if path.suffix in (".yaml", ".yml") or path.exists():
        if not path.is_file():
            raise ConfigError(f"{path}: no such config file")
        try:
            text = read_text(path, MAX_FILE_BYTES)
        except ValueError as error:
            raise ConfigError(str(error)) from None
        return _yaml(text, str(path)), str(path)
    if not isinstance(source, str) or not re.fullmatch(r"[A-Za-z0-9_\-]+", source):
        raise ConfigError(f"{source!r} is neither a YAML file nor a packaged config; packaged: {packaged_configs()}")
    resource = resources.files("ilc_steering.configs") / f"{source}.yaml"
    if not resource.is_file():
        raise ConfigError(f"{source!r} is neither a YAML file nor a packaged config; packaged: {packaged_configs()}")
    origin = f"{source}.yaml (packaged)"
    return _yaml(resource.read_text(encoding="utf-8"), origin), origin  # the package's own: small, UTF-8


def load_config(source: str | Path | SteeringConfig | dict[str, Any]) -> SteeringConfig:
    """A scenario from a YAML path, a packaged config name (``"forward_parking"``), a mapping,
    or an already built config (returned as is)."""
    if isinstance(source, SteeringConfig):
        return source
    if not isinstance(source, (str, Path, dict)):
        raise ConfigError(
            f"config must be a YAML path, a packaged config name, a mapping or a SteeringConfig, got {_show(source)}"
        )
    data, origin = (source, "<mapping>") if isinstance(source, dict) else _read(source)
    if isinstance(source, dict) and _count_values(data) > MAX_VALUES:
        raise ConfigError(f"{origin}: more than {MAX_VALUES} values; not a config")
    if isinstance(source, dict):
        _depth(data, origin)
    folders = (str(Path(source).parent),) if isinstance(source, (str, Path)) and Path(source).is_file() else ()
    token = _FOLDERS.set(folders)  # a robot's module beside its config is found (entries.load_entry)
    try:
        config: SteeringConfig = _build(SteeringConfig, data, "")
        return config
    except ConfigError as error:
        raise ConfigError(f"{origin}: {error}") from None
    finally:
        _FOLDERS.reset(token)
