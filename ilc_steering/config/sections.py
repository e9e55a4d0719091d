"""The sections of a scenario config (``task``, ``learning``, ``simulation``) as frozen dataclasses,
each its own schema (:mod:`ilc_steering.schema`), with the range rules of each section's keys.
Units are in the field comments and in the packaged YAML files (``configs/``)."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from math import isfinite
from typing import Annotated, Any, Literal

from pydantic import Discriminator, Tag

from ilc_steering.core.checks import check_gains, check_jitter, check_noise
from ilc_steering.core.profiles import PiecewiseProfile
from ilc_steering.core.trapezoid import TrapezoidProfile
from ilc_steering.errors import ConfigError, ParameterError

__all__ = [
    "MAX_ACTION_BOUND",
    "MAX_TRIALS",
    "CyclicTaskConfig",
    "LearningConfig",
    "LegConfig",
    "SegmentConfig",
    "SegmentedTaskConfig",
    "SimulationConfig",
    "Task",
    "TaskConfig",
    "ToleranceConfig",
    "domain",
    "require",
]

MAX_ACTION_BOUND = 1e12
"""The largest ``task.action_bound`` entry."""
MAX_TRIALS = 100_000
"""The largest ``learning.trials`` (and ``run --trials``): every trial's record is kept in memory."""


def require(ok: bool, key: str, message: str) -> None:
    if not ok:
        raise ConfigError(f"{key}: {message}")


def _positive(value: float) -> bool:
    return isfinite(value) and value > 0


@contextmanager
def domain(key: str = "", names: dict[str, str] | None = None, prefix: str = "") -> Iterator[None]:
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
        require(leg.ramp is None, "ramp", "is for v1_shape: trapezoid; with v1_shape: constant leave it out")
        with domain():
            return PiecewiseProfile(leg.pieces, leg.v1_fixed, leg.v2_terms)
    require(leg.ramp is not None, "ramp", "v1_shape: trapezoid needs the ramp time [s] at both ends of every piece")
    with domain():
        return TrapezoidProfile(leg.pieces, leg.v1_fixed, leg.v2_terms, float(leg.ramp or 0.0))


def _check_bound(bound: tuple[float, ...] | None, size: int) -> None:
    if bound is not None:
        require(len(bound) == size, "action_bound", f"needs 1 + v2_terms = {size} values, got {len(bound)}")
        require(
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
        require(self.frame is None or isfinite(self.frame), "frame", f"must be a finite angle [rad], got {self.frame}")
        for key in ("start", "goal"):
            require(all(isfinite(v) for v in getattr(self, key)), key, "values must be finite")
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
class LegConfig(SegmentConfig):
    """A segment of a manoeuvre (:class:`SegmentedTaskConfig`): a segment's profile, its chart and its direction."""

    frame: float | None = None  # [rad] this segment's task frame; None: frame_angle of its two ends
    action_bound: tuple[float, ...] | None = None  # |c_i| bounds of this segment; None: 10x its action_scale()
    # the sign of v1 on the learned piece (of c11): forward (> 0), reverse (< 0), checked against the nominal
    # solution and kept by the env's box; None: whichever the nominal solution takes, either sign learned
    direction: Literal["forward", "reverse"] | None = None

    def __post_init__(self) -> None:
        require(self.frame is None or isfinite(self.frame), "frame", f"must be a finite angle [rad], got {self.frame}")
        super().__post_init__()
        _check_bound(self.action_bound, 1 + self.v2_terms)


@dataclass(frozen=True)
class SegmentedTaskConfig:
    """A manoeuvre: ``start -> via[0] -> ... -> goal``, one :class:`LegConfig` per segment, each
    checked as the one-trial task from its waypoint to the next (``SteeringConfig.segment_configs``).
    Each segment's action box is its own (``segments[k].action_bound``, else 10 times its own
    nominal scale); there is no ``task.action_bound`` for the whole."""

    start: tuple[float, ...]  # as task.start of a one-trial task
    goal: tuple[float, ...]  # as task.goal
    via: tuple[tuple[float, ...], ...]  # the waypoints between, in order, as start and goal
    segments: tuple[LegConfig, ...]  # one per segment: start -> via[0] -> ... -> goal

    def __post_init__(self) -> None:
        points = (self.start, *self.via, self.goal)
        require(all(isfinite(v) for w in points for v in w), "start, via, goal", "values must be finite")
        require(
            len(self.segments) == len(self.via) + 1,
            "segments",
            f"needs one entry per segment, len(via) + 1 = {len(self.via) + 1}, got {len(self.segments)}",
        )

    @property
    def action_bound(self) -> None:
        """None: each segment has its own box (``segments[k].action_bound``, else 10x its ``action_scale()``)."""
        return None

    @property
    def waypoints(self) -> tuple[tuple[float, ...], ...]:
        """Start, the via points and goal: segment ``k`` runs from ``waypoints[k]`` to ``waypoints[k + 1]``."""
        return (self.start, *self.via, self.goal)


@dataclass(frozen=True)
class CyclicTaskConfig:
    waypoints: tuple[tuple[float, ...], ...]  # q_0^d (home), q_1^d, ...; the cycle ends back at home
    segments: tuple[SegmentConfig, ...]  # one per segment (waypoint l-1 -> l), or one for all
    action_bound: tuple[float, ...] | None = None  # |c_i| bounds; None: 10x the largest action_scale()

    def __post_init__(self) -> None:
        count = len(self.waypoints)
        require(count >= 2, "waypoints", f"a cycle needs at least 2 waypoints, got {count}")
        require(all(isfinite(v) for w in self.waypoints for v in w), "waypoints", "values must be finite")
        require(
            len(self.segments) in (1, count),
            "segments",
            f"needs 1 entry or one per segment ({count}), got {len(self.segments)}",
        )
        terms = sorted({s.v2_terms for s in self.segments})
        require(len(terms) == 1, "segments", f"every segment needs the same v2_terms (one action space), got {terms}")
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
            require(value is None or _positive(value), key, f"must be > 0, got {value}")


@dataclass(frozen=True)
class LearningConfig:
    nu_a: float  # gain of eq. 33, in (0, 2)
    nu_b: float  # gain of eq. 34, in (0, 2)
    trials: int  # how many trials (for a cyclic task: cycles) a run makes
    tolerance: ToleranceConfig
    # section 7: a cost the spare coefficients of v2 (v2_terms > n - 1) minimize in the null space of W
    cost: Literal["none", "path_length", "curvature", "steering_margin"] = "none"

    def __post_init__(self) -> None:
        with domain():
            check_gains(self.nu_a, self.nu_b)
        require(
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
        require(_positive(self.max_step), "max_step", f"must be > 0 s, got {self.max_step}")
        for key in ("measurement_noise", "start_error"):
            value = getattr(self, key)
            if value is not None:
                with domain(key):
                    check_noise(value, len(value), key)
        with domain():
            check_jitter(self.parameter_jitter)


def _task_kind(value: Any) -> str | None:
    """The tag of a task: a one-trial task has ``start``, a cycle ``waypoints`` (exactly one of the two),
    a manoeuvre ``start`` and ``segments``."""
    found = {"start", "waypoints"} & set(value) if isinstance(value, dict) else set()
    if len(found) != 1:
        return None
    if "waypoints" in found:
        return "cyclic"
    return "segmented" if "segments" in value else "one-trial"


Task = Annotated[
    Annotated[TaskConfig, Tag("one-trial")]
    | Annotated[CyclicTaskConfig, Tag("cyclic")]
    | Annotated[SegmentedTaskConfig, Tag("segmented")],
    Discriminator(_task_kind),
]
"""The schema of ``task``: a one-trial task, a cycle or a manoeuvre, told apart by ``start``,
``waypoints`` or ``start`` with ``segments``."""
