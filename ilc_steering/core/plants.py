"""Simulated plants: the *true* systems a learner drives, behind one :class:`Plant` protocol.

A plant holds its true parameters; the learner never sees it (it gets a
:class:`~ilc_steering.core.nominal.NominalModel`). It is driven by the chained inputs ``v(t)`` of
an input profile: a robot converts them with the controller's *nominal* transform (for the car,
eqs. 4-5) from its measured configuration at every instant.

Each robot is one module of :mod:`ilc_steering.core.robots` (its maths, its plant class, its
config keys, its compiled field and its drawing), named by one line of that package's registry.
This module holds what every robot shares: the :class:`Plant` protocol, :class:`PlantKind` (the
one answer to "what kind of robot is this": does it have a planar pose, what are its coordinates
called), the :class:`Kernel` a plant hands the simulator with the named :class:`KernelLayout` of
the arrays its compiled field reads, and the range checks of configurations.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from math import isfinite, pi
from typing import Any, ClassVar, Protocol, runtime_checkable

import numpy as np
import numpy.typing as npt

from ilc_steering.core.checks import require
from ilc_steering.errors import BadInput

__all__ = [
    "CHART_MARGIN",
    "MAX_COORDINATE",
    "ConfigurationState",
    "FactorFamily",
    "Kernel",
    "KernelLayout",
    "Plant",
    "PlantBatch",
    "PlantConfig",
    "PlantKind",
    "check_angles",
    "check_limit",
    "check_magnitude",
    "check_steered",
    "check_steering_limit",
    "heading_curvature_cost",
]

Array = npt.NDArray[np.float64]

CHART_MARGIN = 1e-3
"""[rad] the closest ``|theta|``, ``|phi|`` may come to ``pi/2`` (task frame) before a trial stops."""
MAX_COORDINATE = 1e6
"""The largest magnitude of a configuration's entry a task may use [m, rad, or chained units]."""


@dataclass(frozen=True)
class PlantKind:
    """What kind of robot a plant is, for everything that reports or draws it."""

    name: str
    """``plant.model`` in a config."""
    has_pose: bool
    """The configuration starts with ``x`` [m], ``y`` [m], ``theta`` [rad]: the task has a Cartesian and an
    orientation error, and its frame may be rotated (end of section 4)."""
    coordinates: tuple[str, ...]
    """Labels of the configuration's entries, with units (empty: ``z1..zn``)."""
    inputs: tuple[str, str]
    """Labels of the robot's two inputs, with units."""

    def coordinate_labels(self, size: int) -> list[str]:
        """Labels of a configuration of ``size`` entries."""
        return list(self.coordinates) if self.coordinates else [f"z{i + 1}" for i in range(size)]


@dataclass(frozen=True)
class KernelLayout:
    """The arrays a compiled field reads, by name: the entries of its state and of its parameter row.

    The compiled code reads both by position and checks nothing (numba does no bounds checking),
    so :func:`~ilc_steering.core.integrate.integrate` checks every array it hands over against the
    layout of its kernel, and a plant builds its row with :meth:`row`, by name.
    """

    state: tuple[str, ...]
    """The state's entries; empty for a state of as many entries as the parameter ``dimension`` says
    (the chained form's)."""
    params: tuple[str, ...]
    """The parameter row's entries."""

    def row(self, **values: float) -> Array:
        """The parameter row of ``values`` (every name of :attr:`params`, no other)."""
        if set(values) != set(self.params):
            raise BadInput(f"a parameter row needs {list(self.params)}, got {sorted(values)}")
        return np.array([float(values[name]) for name in self.params])

    def index(self, name: str) -> int:
        """The position of parameter ``name`` in a row (the compiled field reads it there)."""
        return self.params.index(name)


@dataclass(frozen=True, eq=False)
class Kernel:
    """A robot's compiled field: the layout of the arrays it reads and its two batch runners, each
    ``(params, x0, durations, steps, v1, v2, out, status, traj)`` (see
    :func:`~ilc_steering.core.integrate.integrate`), one over the trials in turn and one sharing
    them among numba's threads. Built once in the robot's module, where its field is."""

    name: str
    """What the simulator is called in messages ("unicycle", "car-lab", ...)."""
    layout: KernelLayout
    serial: Callable[..., Any]
    parallel: Callable[..., Any]
    dispatchers: tuple[Any, ...] = ()
    """The compiled functions the runners call first, when they are not themselves compiled (the
    batched car's blocks): what a first call may have to compile."""


@runtime_checkable
class Plant(Protocol):
    """What a simulated robot provides (``tests/test_protocols.py`` checks every registered robot)."""

    kind: ClassVar[PlantKind]
    factor_names: ClassVar[tuple[str, str]]
    """The two true parameters :meth:`with_true_factors` scales (the names of a model family's ratios)."""

    @property
    def state_dim(self) -> int:
        """Entries of the simulated state ``x``."""
        ...

    @property
    def steering_limit(self) -> float | None:
        """The bound on ``|phi|`` [rad] of a steered robot, a specification the controller knows (``None``: none)."""
        ...

    def configuration(self, x: Array) -> Array:
        """The measured configurations of states ``x`` ``(..., state_dim)``."""
        ...

    def estimate(self, x: Array) -> Array:
        """The configurations the controller's eqs. 4-5 act on at states ``x``: the measured ones,
        or a lab robot's dead-reckoned estimate."""
        ...

    def check_configuration(self, q: Array) -> None:
        """``ValueError`` unless ``q`` is a configuration a trial may start from (finite, in the chart,
        within the plant's limits)."""
        ...

    def initial_state(self, q: Array) -> Array:
        """The state ``x`` of a plant at rest at configuration ``q`` (``(..., nq)`` -> ``(..., state_dim)``)."""
        ...

    def kernel(self) -> tuple[Kernel, Array]:
        """The compiled vector field and its parameter row (true parameters included), laid out as
        the kernel's :class:`KernelLayout` names."""
        ...

    def with_true_factors(self, factors: Array) -> Plant:
        """The plant with its two true parameters multiplied by ``factors`` (those named by
        ``factor_names``): a trial's ``parameter_jitter``, and a model family's hypotheses."""
        ...

    def true_factors(self) -> Array:
        """The two true parameters of ``factor_names`` over their nominal values."""
        ...

    def family_names(self) -> tuple[str, ...]:
        """The parameters a learner's model family (:class:`~ilc_steering.core.family.ModelFamily`)
        leaves free: ``factor_names``, or more where the robot has more lengths it may be wrong about."""
        ...

    def with_family(self, ratios: Array) -> Plant:
        """The plant with the true parameters of ``family_names`` multiplied by ``ratios``."""
        ...

    def reference_field(self, profile: Any, c: Array) -> tuple[Callable[[float, Array], Array], float, Any]:
        """For :mod:`ilc_steering.core.reference`: the closed-loop field ``f(t, x)`` of one trial with
        coefficients ``c``, written from the robot's equations (not from the compiled field), the
        steering limit where it has a kink (``inf``: none), and a chart function ``g(t, x)`` that
        falls to 0 where the trial stops (or ``None``)."""
        ...


class ConfigurationState:
    """:class:`Plant`'s state methods for a plant whose state is its configuration, measured
    exactly: a base class (a plant with more state, the car's servos say, writes its own)."""

    def initial_state(self, q: Array) -> Array:
        """The state is the configuration."""
        return np.array(q, dtype=np.float64)

    def configuration(self, x: Array) -> Array:
        """The state is the configuration."""
        return np.asarray(x, dtype=np.float64)

    def estimate(self, x: Array) -> Array:
        """The configuration, measured exactly."""
        return np.asarray(x, dtype=np.float64)


class FactorFamily:
    """:class:`Plant`'s model family where it is the plant's two true factors (``factor_names``,
    scaled by ``with_true_factors``): a base class (the trailer, with a third length, writes its own)."""

    factor_names: ClassVar[tuple[str, str]]

    def with_true_factors(self, factors: Array) -> Any:
        raise NotImplementedError

    def family_names(self) -> tuple[str, ...]:
        """The true factors' names."""
        return self.factor_names

    def with_family(self, ratios: Array) -> Any:
        """The plant with its true factors multiplied by ``ratios``."""
        return self.with_true_factors(ratios)


@runtime_checkable
class PlantConfig(Protocol):
    """A robot's config keys (``plant:`` in a config): a frozen dataclass whose ``model`` field is a
    ``Literal`` of the robot's registered name, each other field a key with its unit in a comment.
    Its ``__post_init__`` checks every key's range (a :class:`~ilc_steering.errors.ParameterError`
    names the key); the config loader reports it with the file."""

    model: str
    kind: ClassVar[PlantKind]
    plant_class: ClassVar[type]
    """The plant class, whose ``nominal_plant(chained_map, dimension, steering_limit)`` builds the plant
    the controller assumes (a model family's, section 7's cost's)."""

    @property
    def dimension(self) -> int:
        """The chained-form dimension ``n`` (the configuration's size)."""
        ...

    @property
    def steering_limit(self) -> float | None:
        """The bound on ``|phi|`` [rad] the controller knows, or ``None``."""
        ...

    def plant(self) -> Plant:
        """The true plant."""
        ...

    def nominal_map(self) -> Any:
        """The nominal :class:`~ilc_steering.core.nominal.ChainedMap` the controller uses."""
        ...

    def check_task(self, max_step: float, cyclic: bool) -> None:
        """The rules between these keys and the rest of the config: the integrator's ``max_step`` [s]
        and whether the task is a cycle (a :class:`~ilc_steering.errors.ParameterError` names the
        key; a ``ValueError``, the plant)."""
        ...


class PlantBatch:
    """Plants of one kind, one per trial of a batch: their kernel parameters stacked once, so a
    batch of different robots (a vector env's ``true_factors``, a robustness map's row) costs one
    compiled call per step and nothing per plant."""

    def __init__(self, plants: Sequence[Plant]) -> None:
        kernels = [plant.kernel() for plant in plants]
        fields = {id(kernel) for kernel, _ in kernels}
        if len(fields) != 1:
            raise BadInput(f"a batch of plants must be all of one kind; got {len(plants)} of {len(fields)} kinds")
        self.field = kernels[0][0]
        self.params = np.array([row for _, row in kernels])
        self.size = len(kernels)

    @classmethod
    def from_rows(cls, field: Kernel, params: Array) -> PlantBatch:
        """A batch of the kernel ``field`` with parameter rows ``params`` ``(B, P)`` already stacked
        (checked against the kernel's layout by ``integrate``)."""
        batch = cls.__new__(cls)
        batch.field, batch.params, batch.size = field, np.ascontiguousarray(params, dtype=np.float64), len(params)
        return batch

    def kernel(self) -> tuple[Kernel, Array]:
        """The kernel and the parameters ``(B, P)``, a row per trial."""
        return self.field, self.params


def check_magnitude(q: Array) -> None:
    """Every entry of ``q`` within ``+-MAX_COORDINATE``."""
    largest = float(np.max(np.abs(q)))
    require(largest <= MAX_COORDINATE, "configuration", f"entries must be within +-{MAX_COORDINATE:g}, got {largest:g}")


def check_angles(q: Array, names: str) -> None:
    """The angles ``q[..., 2:]`` (task frame) ``CHART_MARGIN`` inside ``pi/2``, where a trial stops."""
    angles = np.abs(np.asarray(q, dtype=np.float64)[..., 2:])
    require(
        bool(np.all(angles < pi / 2 - CHART_MARGIN)),
        "configuration",
        f"{names} must stay {CHART_MARGIN} rad inside pi/2 (where a trial stops), got {np.max(angles):.6g} rad",
    )


def check_limit(phi: Array, limit: float | None) -> None:
    """The steering angles ``phi`` within the steering limit."""
    require(
        limit is None or bool(np.all(np.abs(phi) <= limit)),
        "phi",
        f"{np.asarray(phi).tolist()} rad exceeds the steering limit of {limit} rad",
    )


def check_steered(q: Array, chart: Callable[[Array], None], angles: str, limit: float | None) -> None:
    """A steered robot's configurations ``q`` (its steering angle ``q[..., 3]``): in the robot's
    ``chart`` (a check), of a plausible magnitude, the ``angles`` named within their range, and the
    steering angle within the steering ``limit``."""
    chart(q)
    check_magnitude(q)
    check_angles(q, angles)
    check_limit(np.asarray(q, dtype=np.float64)[..., 3], limit)


def check_steering_limit(limit: float | None) -> None:
    """A steering limit in ``(0, pi/2)`` rad, or ``None``."""
    require(
        limit is None or (isfinite(limit) and 0 < limit < pi / 2),
        "steering_limit",
        f"must be in (0, pi/2) rad or null, got {limit}",
    )


def heading_curvature_cost(q: Array) -> Array:
    """``int kappa^2 ds`` [1/m] of recorded paths ``q`` ``(B, S, nq)`` whose ``(x, y, theta)`` come
    first, from the heading's turn over each step: ``kappa^2 ds = (dtheta / ds)^2 ds``."""
    ds = np.linalg.norm(np.diff(q[..., :2], axis=1), axis=-1)
    turn = np.diff(q[..., 2], axis=1)
    squared = np.divide(turn**2, ds, out=np.zeros_like(ds), where=ds > 1e-12)
    return np.asarray(np.sum(squared, axis=1), dtype=np.float64)
