"""Scenario configs: frozen dataclasses loaded from YAML.

Every key is checked: an unknown key, a wrong type, a missing field or an out-of-range value
raises :class:`ConfigError` naming the key and the file. Units are in the field comments and in
the packaged YAML files (``configs/``).
"""

from __future__ import annotations

import dataclasses
import types
import typing
from dataclasses import dataclass, field
from importlib import resources
from math import isfinite, pi
from pathlib import Path
from typing import Any, Literal

import yaml

__all__ = [
    "CarPlantConfig",
    "ChainedPlantConfig",
    "ConfigError",
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


class ConfigError(ValueError):
    """A config that cannot be used, with the file and key at fault in its message."""


def _require(ok: bool, key: str, message: str) -> None:
    if not ok:
        raise ConfigError(f"{key}: {message}")


def _positive(value: float) -> bool:
    return isfinite(value) and value > 0


def _check_pieces(pieces: tuple[float, ...], v1_fixed: tuple[float, ...]) -> None:
    """The input profile's keys (eqs. 15-17): positive durations, a fixed v1 for each later piece."""
    _require(len(pieces) >= 1 and all(map(_positive, pieces)), "pieces", f"durations must be > 0 s, got {list(pieces)}")
    _require(len(v1_fixed) == len(pieces) - 1, "v1_fixed", f"needs one value per piece after the first ({len(pieces) - 1}), got {len(v1_fixed)}")
    _require(all(isfinite(v) for v in v1_fixed), "v1_fixed", "values must be finite")


@dataclass(frozen=True)
class CarPlantConfig:
    model: Literal["car"]
    wheelbase: float  # nominal ell [m], known to the controller
    wheel_radius: float  # nominal rho [m]
    true_wheelbase: float  # the simulated robot's ell [m]
    true_wheel_radius: float  # the simulated robot's rho [m]
    steering_limit: float | None = None  # bound on |phi| [rad]; None for none

    def __post_init__(self) -> None:
        for key in ("wheelbase", "wheel_radius", "true_wheelbase", "true_wheel_radius"):
            _require(_positive(getattr(self, key)), key, f"must be finite and > 0 m, got {getattr(self, key)}")
        limit = self.steering_limit
        _require(limit is None or 0 < limit < pi / 2, "steering_limit", f"must be in (0, pi/2) rad or null, got {limit}")

    @property
    def dimension(self) -> int:
        return 4


@dataclass(frozen=True)
class ChainedPlantConfig:
    model: Literal["chained"]
    dimension: int  # n, the chained-form dimension (>= 3)
    v1_gain: float = 1.0  # true gain on v1 [-]; 1.0 unperturbed
    v2_gain: float = 1.0  # true gain on v2 [-]; 1.0 unperturbed

    def __post_init__(self) -> None:
        _require(self.dimension >= 3, "dimension", f"must be >= 3, got {self.dimension}")
        for key in ("v1_gain", "v2_gain"):
            value = getattr(self, key)
            _require(isfinite(value) and value != 0, key, f"must be finite and nonzero, got {value}")


@dataclass(frozen=True)
class TaskConfig:
    start: tuple[float, ...]  # car: x [m], y [m], theta [rad], phi [rad]; chained: z
    goal: tuple[float, ...]
    pieces: tuple[float, ...]  # Delta_i [s]; T is their sum
    v1_fixed: tuple[float, ...]  # c12..c1p: v1 on pieces 2..p [m/s for the car]
    v2_terms: int  # q, the number of basis functions of v2
    action_bound: tuple[float, ...] | None = None  # |c_i| bounds of the action box; None: 10x NominalModel.action_scale()

    def __post_init__(self) -> None:
        for key in ("start", "goal"):
            _require(all(isfinite(v) for v in getattr(self, key)), key, "values must be finite")
        _check_pieces(self.pieces, self.v1_fixed)
        if self.action_bound is not None:
            _require(len(self.action_bound) == 1 + self.v2_terms, "action_bound", f"needs 1 + v2_terms = {1 + self.v2_terms} values, got {len(self.action_bound)}")
            _require(all(map(_positive, self.action_bound)), "action_bound", "values must be finite and > 0")


@dataclass(frozen=True)
class SegmentConfig:
    pieces: tuple[float, ...]  # Delta_i [s] of the segment
    v1_fixed: tuple[float, ...]  # v1 on pieces 2..p [m/s for the car]
    v2_terms: int  # q

    def __post_init__(self) -> None:
        _check_pieces(self.pieces, self.v1_fixed)


@dataclass(frozen=True)
class CyclicTaskConfig:
    waypoints: tuple[tuple[float, ...], ...]  # q_0^d (home), q_1^d, ...; the cycle ends back at home
    segments: tuple[SegmentConfig, ...]  # one per segment (waypoint l-1 -> l), or one for all
    action_bound: tuple[float, ...] | None = None  # |c_i| bounds of the action box; None: 10x the largest action_scale()

    def __post_init__(self) -> None:
        if self.action_bound is not None:
            _require(all(map(_positive, self.action_bound)), "action_bound", "values must be finite and > 0")
        _require(len(self.waypoints) >= 2, "waypoints", f"a cycle needs at least 2 waypoints, got {len(self.waypoints)}")
        _require(all(isfinite(v) for w in self.waypoints for v in w), "waypoints", "values must be finite")
        _require(len(self.segments) in (1, len(self.waypoints)), "segments", f"needs 1 entry or one per segment ({len(self.waypoints)}), got {len(self.segments)}")

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

    def __post_init__(self) -> None:
        for key in ("nu_a", "nu_b"):
            value = getattr(self, key)
            _require(0 < value < 2, key, f"must be in (0, 2), got {value}")
        _require(self.trials >= 1, "trials", f"must be >= 1, got {self.trials}")


@dataclass(frozen=True)
class SimulationConfig:
    max_step: float = 1.0 / 32.0  # longest integrator step [s]

    def __post_init__(self) -> None:
        _require(_positive(self.max_step), "max_step", f"must be > 0 s, got {self.max_step}")


@dataclass(frozen=True)
class SteeringConfig:
    name: str
    plant: CarPlantConfig | ChainedPlantConfig
    task: TaskConfig | CyclicTaskConfig
    learning: LearningConfig
    simulation: SimulationConfig = field(default_factory=SimulationConfig)

    @property
    def is_cyclic(self) -> bool:
        return isinstance(self.task, CyclicTaskConfig)

    def __post_init__(self) -> None:
        n = self.plant.dimension
        if isinstance(self.task, CyclicTaskConfig):
            points = [(f"task.waypoints[{i}]", w) for i, w in enumerate(self.task.waypoints)]
            r = len(points)
            legs = [(f"task.segments[{i if len(self.task.segments) > 1 else 0}]", self.task.segment(i), points[i][1], points[(i + 1) % r][1]) for i in range(r)]
        else:
            points = [("task.start", self.task.start), ("task.goal", self.task.goal)]
            legs = [("task", self.task, self.task.start, self.task.goal)]
        for key, point in points:
            _require(len(point) == n, key, f"needs {n} values for plant.model {self.plant.model}, got {len(point)}")
        for key, leg, start, goal in legs:
            _require(leg.v2_terms >= n - 1, f"{key}.v2_terms", f"needs q >= n - 1 = {n - 1} to reach every z_b (section 3), got {leg.v2_terms}")
            _require(
                goal[0] != start[0] or any(v != 0 for v in leg.v1_fixed),
                f"{key}.v1_fixed",
                "the start and goal share z1, so v1 on the learned piece goes to zero and W is singular (eq. 11): "
                "add a piece with a nonzero fixed v1, as in the paper's parallel parking",
            )
        tolerance = self.learning.tolerance
        if self.plant.model == "car":
            _require(tolerance.cartesian is not None and tolerance.orientation is not None, "learning.tolerance", "a car needs {cartesian: [m], orientation: [rad]}")
            limit = self.plant.steering_limit
            for key, point in points:
                phi = point[3]
                _require(abs(phi) < pi / 2, key, f"phi = {phi} rad: the chained form needs |phi| < pi/2")
                _require(limit is None or abs(phi) <= limit, key, f"phi = {phi} rad exceeds plant.steering_limit = {limit} rad")
            from ilc_steering.envs.car import frame_angle  # here: envs imports this module

            try:
                frame_angle(*(point[2] for _, point in points))
            except ValueError as error:
                raise ConfigError(f"{points[-1][0]}: {error}") from None
        else:
            _require(tolerance.error is not None, "learning.tolerance", "a chained plant needs {error: ...}")


def _is_optional(hint: Any) -> bool:
    return isinstance(hint, types.UnionType) and type(None) in typing.get_args(hint)


def _coerce(hint: Any, value: Any, key: str) -> Any:
    """Check ``value`` against the type hint ``hint`` and convert lists to tuples."""
    origin = typing.get_origin(hint)
    if isinstance(hint, types.UnionType):
        options = [a for a in typing.get_args(hint) if a is not type(None)]
        if value is None:
            _require(_is_optional(hint), key, "must not be null")
            return None
        if all(dataclasses.is_dataclass(a) for a in options):
            return _build_tagged(options, value, key)
        return _coerce(options[0], value, key)
    if dataclasses.is_dataclass(hint):
        return _build(hint, value, key)
    if origin is tuple:
        _require(isinstance(value, (list, tuple)), key, f"must be a list, got {value!r}")
        return tuple(_coerce(typing.get_args(hint)[0], v, f"{key}[{i}]") for i, v in enumerate(value))
    if origin is Literal:
        allowed = typing.get_args(hint)
        _require(value in allowed, key, f"must be one of {list(allowed)}, got {value!r}")
        return value
    if hint is float:
        _require(isinstance(value, (int, float)) and not isinstance(value, bool), key, f"must be a number, got {value!r}")
        return float(value)
    if hint is int:
        _require(isinstance(value, int) and not isinstance(value, bool), key, f"must be an integer, got {value!r}")
        return value
    if hint is str:
        _require(isinstance(value, str), key, f"must be a string, got {value!r}")
        return value
    raise TypeError(f"no rule for type {hint} at {key}")


def _build_tagged(options: list[Any], value: Any, key: str) -> Any:
    """Pick the dataclass whose ``model`` literal matches ``value['model']`` or, without a
    ``model`` field, the one whose first field is a key of ``value`` (``start`` or ``waypoints``)."""
    _require(isinstance(value, dict), key, f"must be a mapping, got {value!r}")
    if not all("model" in typing.get_type_hints(o) for o in options):
        markers = {dataclasses.fields(o)[0].name: o for o in options}
        found = [m for m in markers if m in value]
        _require(len(found) == 1, key, f"needs exactly one of the keys {list(markers)}, got {sorted(value)}")
        return _build(markers[found[0]], value, key)
    tags = {typing.get_args(typing.get_type_hints(o)["model"])[0]: o for o in options}
    _require(value.get("model") in tags, f"{key}.model", f"must be one of {list(tags)}, got {value.get('model')!r}")
    return _build(tags[value["model"]], value, key)


def _build(cls: Any, value: Any, key: str) -> Any:
    _require(isinstance(value, dict), key or "config", f"must be a mapping, got {value!r}")
    hints = typing.get_type_hints(cls)
    fields = {f.name: f for f in dataclasses.fields(cls)}
    prefix = f"{key}." if key else ""
    unknown = sorted(set(value) - set(fields))
    _require(not unknown, prefix + str(unknown[0]) if unknown else key, f"unknown key; allowed keys here: {sorted(fields)}")
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


def packaged_configs() -> list[str]:
    """Names of the configs shipped in ``ilc_steering.configs``."""
    root = resources.files("ilc_steering.configs")
    return sorted(p.name.removesuffix(".yaml") for p in root.iterdir() if p.name.endswith(".yaml"))


def _read(source: str | Path) -> tuple[Any, str]:
    path = Path(source)
    if path.suffix in (".yaml", ".yml") or path.exists():
        if not path.is_file():
            raise ConfigError(f"{path}: no such config file")
        return yaml.safe_load(path.read_text()), str(path)
    resource = resources.files("ilc_steering.configs") / f"{source}.yaml"
    if not resource.is_file():
        raise ConfigError(f"{source!r} is neither a YAML file nor a packaged config; packaged: {packaged_configs()}")
    return yaml.safe_load(resource.read_text()), f"{source}.yaml (packaged)"


def load_config(source: str | Path | SteeringConfig | dict[str, Any]) -> SteeringConfig:
    """A scenario from a YAML path, a packaged config name (``"forward_parking"``), a mapping,
    or an already built config (returned as is)."""
    if isinstance(source, SteeringConfig):
        return source
    data, origin = (source, "<mapping>") if isinstance(source, dict) else _read(source)
    try:
        return _build(SteeringConfig, data, "")
    except ConfigError as error:
        raise ConfigError(f"{origin}: {error}") from None
