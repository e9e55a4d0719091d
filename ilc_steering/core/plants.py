"""Simulated plants: the *true* systems a learner drives, behind one :class:`Plant` protocol.

A plant holds its true parameters; the learner never sees it (it gets a
:class:`~ilc_steering.core.nominal.NominalModel`). It is driven by the chained inputs ``v(t)`` of
an input profile: the car converts them with the controller's *nominal* transform (eqs. 4-5) from
its measured configuration at every instant.

Each plant names its :class:`PlantKind`, the one answer to "what kind of robot is this" (does it
have a planar pose, hence a Cartesian and an orientation error; how are its coordinates called).
``PLANTS`` is the table from ``plant.model`` in a config to the plant class. A new robot is a
module with its geometry and its plant class, a row here and its vector field in the compiled
kernel (:mod:`ilc_steering.core.integrate`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from math import isfinite, pi
from typing import ClassVar, Protocol, runtime_checkable

import numpy as np
import numpy.typing as npt

from ilc_steering.core.car import CarModel, check_chart
from ilc_steering.core.checks import require
from ilc_steering.core.trailer import TrailerModel, check_trailer_chart
from ilc_steering.core.unicycle import UnicycleModel, check_unicycle_chart

__all__ = [
    "CAR_FIELD",
    "CAR_LAB_FIELD",
    "CAR_SERVO_FIELD",
    "CHAINED_FIELD",
    "CHART_MARGIN",
    "KERNEL_LAYOUTS",
    "MAX_BACKLASH",
    "MAX_LAG",
    "MAX_PULSES",
    "MAX_STEERING_OFFSET",
    "PLANTS",
    "TRAILER_FIELD",
    "UNICYCLE_FIELD",
    "CarPlant",
    "ChainedPlant",
    "KernelLayout",
    "Plant",
    "PlantBatch",
    "PlantKind",
    "TrailerPlant",
    "UnicyclePlant",
    "nominal_plant",
]

Array = npt.NDArray[np.float64]

CHART_MARGIN = 1e-3
"""[rad] the closest ``|theta|``, ``|phi|`` may come to ``pi/2`` (task frame) before a trial stops."""
MAX_COORDINATE = 1e6
"""The largest magnitude of a configuration's entry a task may use [m, rad, or chained units]."""
MAX_DIMENSION = 12
"""The largest chained-form dimension ``n`` of a chained plant."""

CAR_FIELD = 0
"""Kernel id of the closed-loop car field (eq. 3 driven through eqs. 4-5)."""
CHAINED_FIELD = 1
"""Kernel id of the chained form with input gains (eq. 1, perturbed as eq. 37)."""
CAR_SERVO_FIELD = 2
"""Kernel id of the car with its unmodeled servo perturbations (a misaligned wheel, steering and
drive lags): six states ``(x, y, theta, phi_c, phi_w, omega)``."""
CAR_LAB_FIELD = 3
"""Kernel id of the lab robot (section 5): the servo perturbations, play in the steering linkage
and a heading dead-reckoned from wheel encoders: twelve states ``(x, y, theta, phi_c, phi_s,
omega, A, psi, x_hat, y_hat, theta_hat, k)`` (see :mod:`ilc_steering.core.integrate`)."""
UNICYCLE_FIELD = 4
"""Kernel id of the closed-loop unicycle (a differential drive with its true wheel radius and axle width)."""
TRAILER_FIELD = 5
"""Kernel id of the closed-loop car towing a trailer: states ``(x1, y1, theta1, phi_c, delta)``."""


@dataclass(frozen=True)
class KernelLayout:
    """The arrays a compiled field reads, by name: the entries of its state and of its parameter row.

    The compiled code reads both by position and checks nothing (numba does no bounds checking),
    so :func:`~ilc_steering.core.integrate.integrate` checks every array it hands over against the
    layout of its field, and a plant builds its row with :meth:`row`, by name.
    """

    state: tuple[str, ...]
    """The state's entries; empty for a state of as many entries as the parameter ``dimension`` says."""
    params: tuple[str, ...]
    """The parameter row's entries."""

    def row(self, **values: float) -> Array:
        """The parameter row of ``values`` (every name of :attr:`params`, no other)."""
        if set(values) != set(self.params):
            raise ValueError(f"a parameter row needs {list(self.params)}, got {sorted(values)}")
        return np.array([float(values[name]) for name in self.params])

    def state_size(self, row: Array) -> int:
        """The number of state entries of a trial with parameter row ``row``."""
        return len(self.state) if self.state else int(row[self.params.index("dimension")])


_CAR_PARAMS = ("wheelbase", "wheel_radius", "true_wheelbase", "true_wheel_radius", "steering_limit")
_SERVO_PARAMS = (*_CAR_PARAMS, "steering_offset", "steering_lag", "speed_lag")
KERNEL_LAYOUTS: dict[int, KernelLayout] = {
    CAR_FIELD: KernelLayout(("x", "y", "theta", "phi_c"), _CAR_PARAMS),
    CHAINED_FIELD: KernelLayout((), ("v1_gain", "v2_gain", "dimension")),
    CAR_SERVO_FIELD: KernelLayout(("x", "y", "theta", "phi_c", "phi_w", "omega"), _SERVO_PARAMS),
    CAR_LAB_FIELD: KernelLayout(
        ("x", "y", "theta", "phi_c", "phi_s", "omega", "A", "psi", "x_hat", "y_hat", "theta_hat", "k"),
        (*_SERVO_PARAMS, "steering_backlash", "encoder_pulses"),
    ),
    UNICYCLE_FIELD: KernelLayout(
        ("x", "y", "theta"), ("wheel_radius", "axle_width", "true_wheel_radius", "true_axle_width")
    ),
    TRAILER_FIELD: KernelLayout(
        ("x1", "y1", "theta1", "phi_c", "delta"), (*_CAR_PARAMS, "hitch_length", "true_hitch_length")
    ),
}
"""Kernel id -> the layout of its state and parameter row (the field that reads each row is in
:mod:`ilc_steering.core.integrate`, :mod:`ilc_steering.core.tangent` for the car)."""
MAX_BACKLASH = 0.2
"""[rad] the largest ``steering_backlash`` of a car plant."""
MAX_PULSES = 100_000
"""The largest ``encoder_pulses`` (per wheel turn) of a car plant."""
MAX_STEERING_OFFSET = 0.5
"""[rad] the largest ``|steering_offset|`` of a car plant."""
MAX_LAG = 10.0
"""[s] the largest servo time constant of a car plant."""


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


CAR = PlantKind("car", True, ("x [m]", "y [m]", "θ [rad]", "φ [rad]"), ("u1 [rad/s]", "u2 [rad/s]"))
CHAINED = PlantKind("chained", False, (), ("v1", "v2"))
UNICYCLE = PlantKind("unicycle", True, ("x [m]", "y [m]", "θ [rad]"), ("v [m/s]", "ω [rad/s]"))
CAR_TRAILER = PlantKind(
    "car_trailer", True, ("x1 [m]", "y1 [m]", "θ1 [rad]", "φ [rad]", "δ [rad]"), ("u1 [rad/s]", "u2 [rad/s]")
)


def _check_magnitude(q: Array) -> None:
    largest = float(np.max(np.abs(q)))
    require(largest <= MAX_COORDINATE, "configuration", f"entries must be within +-{MAX_COORDINATE:g}, got {largest:g}")


def _check_angles(q: Array, names: str) -> None:
    """The angles ``q[..., 2:]`` (task frame) ``CHART_MARGIN`` inside ``pi/2``, where a trial stops."""
    angles = np.abs(np.asarray(q, dtype=np.float64)[..., 2:])
    require(
        bool(np.all(angles < pi / 2 - CHART_MARGIN)),
        "configuration",
        f"{names} must stay {CHART_MARGIN} rad inside pi/2 (where a trial stops), got {np.max(angles):.6g} rad",
    )


def _check_limit(phi: Array, limit: float | None) -> None:
    require(
        limit is None or bool(np.all(np.abs(phi) <= limit)),
        "phi",
        f"{np.asarray(phi).tolist()} rad exceeds the steering limit of {limit} rad",
    )


def _check_steering_limit(limit: float | None) -> None:
    require(
        limit is None or (isfinite(limit) and 0 < limit < pi / 2),
        "steering_limit",
        f"must be in (0, pi/2) rad or null, got {limit}",
    )


@runtime_checkable
class Plant(Protocol):
    """What a simulated robot provides (``tests/test_protocols.py`` checks every entry of ``PLANTS``)."""

    kind: ClassVar[PlantKind]
    factor_names: ClassVar[tuple[str, str]]
    """The two true parameters :meth:`with_true_factors` scales (the names of a model family's ratios)."""

    @property
    def state_dim(self) -> int:
        """Entries of the simulated state ``x``."""
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

    def kernel(self) -> tuple[int, Array]:
        """The compiled vector field's id and its parameter vector (true parameters included)."""
        ...

    def with_true_factors(self, factors: Array) -> Plant:
        """The plant with its two true parameters multiplied by ``factors`` (those named by
        ``factor_names``): a trial's ``parameter_jitter``, and a model family's hypotheses."""
        ...

    def true_factors(self) -> Array:
        """The two true parameters of ``factor_names`` over their nominal values."""
        ...


@dataclass(frozen=True)
class CarPlant:
    """The car of eq. (3) with its true geometry, steered through the nominal eqs. (4)-(5).

    ``steering_limit`` bounds the wheel angle ``|phi|`` [rad] (``None`` for none). The state's
    fourth entry is then the servo's commanded angle, which may wind past the limit while the
    wheel rests at the stop (see :mod:`ilc_steering.core.integrate`); :meth:`configuration`
    gives the car's ``q``.

    Three perturbations outside any geometry the controller could assume, each 0 (off) by default:

    - ``steering_offset`` [rad]: a misaligned wheel; its true angle is the measured one plus this;
    - ``steering_lag`` [s]: the wheel follows the (clipped) commanded angle ``phi_c`` through a
      first-order servo, ``dphi_w/dt = (clip(phi_c) - phi_w) / steering_lag``; the controller
      measures ``phi_w``;
    - ``speed_lag`` [s]: the driving wheel's speed follows ``u1`` through a first-order servo,
      ``domega/dt = (u1 - omega) / speed_lag``, from rest at the start of a trial; the trial is
      measured at ``T``, before the wheel has spun down.

    With any of them on, the state is ``(x, y, theta, phi_c, phi_w, omega)`` (kernel
    :data:`CAR_SERVO_FIELD`); without, it is ``(x, y, theta, phi_c)``.

    Two imperfections of section 5's lab robot, each 0 (off) by default:

    - ``steering_backlash`` [rad]: play ``b`` in the steering linkage; the wheel rests while the
      servo's output ``phi_s`` moves within ``b/2`` of it and is pushed along beyond (the play
      operator); the controller measures ``phi_s``, not the wheel;
    - ``encoder_pulses``: pulses per turn of the driving wheel's encoder (0: none); the heading
      the controller uses in eqs. 4-5 is then dead-reckoned, stepping by the nominal odometry of
      one pitch of travel at each pulse, from the true one at the start of a trial.

    With either on, the state has twelve entries (kernel :data:`CAR_LAB_FIELD`); the final
    configuration is measured externally (true pose, the servo's steering angle), as in the paper.
    """

    kind: ClassVar[PlantKind] = CAR
    factor_names: ClassVar[tuple[str, str]] = ("wheelbase_ratio", "wheel_radius_ratio")
    true: CarModel
    nominal: CarModel
    steering_limit: float | None = None
    steering_offset: float = 0.0
    steering_lag: float = 0.0
    speed_lag: float = 0.0
    steering_backlash: float = 0.0
    encoder_pulses: int = 0

    def __post_init__(self) -> None:
        _check_steering_limit(self.steering_limit)
        offset = self.steering_offset
        require(
            isfinite(offset) and abs(offset) <= MAX_STEERING_OFFSET,
            "steering_offset",
            f"must be within +-{MAX_STEERING_OFFSET} rad, got {offset}",
        )
        for name in ("steering_lag", "speed_lag"):
            lag = getattr(self, name)
            require(isfinite(lag) and 0 <= lag <= MAX_LAG, name, f"must be in [0, {MAX_LAG:g}] s, got {lag}")
        backlash = self.steering_backlash
        require(
            isfinite(backlash) and 0 <= backlash <= MAX_BACKLASH,
            "steering_backlash",
            f"must be in [0, {MAX_BACKLASH}] rad, got {backlash}",
        )
        pulses = self.encoder_pulses
        require(
            isinstance(pulses, int) and not isinstance(pulses, bool) and 0 <= pulses <= MAX_PULSES,
            "encoder_pulses",
            f"must be a whole number of pulses per turn in [0, {MAX_PULSES}] (0: none), got {pulses!r}",
        )

    @property
    def lab(self) -> bool:
        """Whether a lab-robot imperfection is on (the twelve-state kernel)."""
        return bool(self.steering_backlash or self.encoder_pulses)

    @property
    def servo(self) -> bool:
        """Whether a servo perturbation is on (the six-state kernel, or the lab's)."""
        return bool(self.steering_offset or self.steering_lag or self.speed_lag) and not self.lab

    @property
    def state_dim(self) -> int:
        return 12 if self.lab else 6 if self.servo else 4

    def initial_state(self, q: Array) -> Array:
        """At rest at ``q``: the commanded and the measured wheel angles are ``phi``, the wheel speed 0;
        on the lab robot also the play's anchor, the wheel's rotation 0, the estimate ``q``, no pulses."""
        q = np.asarray(q, dtype=np.float64)
        if not self.servo and not self.lab:
            return q.copy()
        zero = np.zeros_like(q[..., :1])
        servo = [q, q[..., 3:4], zero]
        if not self.lab:
            return np.concatenate(servo, axis=-1)
        return np.concatenate([*servo, q[..., 3:4], zero, q[..., :3], zero], axis=-1)

    def configuration(self, x: Array) -> Array:
        """The measured configurations ``q`` of states ``x``: the wheel angle is the clipped command,
        or the lagging wheel's ``phi_w`` (the lab robot: its servo's output)."""
        x = np.asarray(x, dtype=np.float64)
        if self.steering_lag:
            return np.concatenate([x[..., :3], x[..., 4:5]], axis=-1)
        q = np.array(x[..., :4], dtype=np.float64)
        if self.steering_limit is not None:
            q[..., 3] = np.clip(q[..., 3], -self.steering_limit, self.steering_limit)
        return q

    def estimate(self, x: Array) -> Array:
        """The measured configurations, with the dead-reckoned pose ``(x_hat, y_hat, theta_hat)``
        in place of the true one when the heading comes from encoders."""
        q = self.configuration(x)
        if self.encoder_pulses:
            q = q.copy()
            q[..., :3] = np.asarray(x, dtype=np.float64)[..., 8:11]
        return q

    def check_configuration(self, q: Array) -> None:
        """The chart of eq. 4 (``|theta|, |phi| < pi/2`` in the task frame) and the steering limit."""
        check_chart(q)
        _check_magnitude(q)
        _check_angles(q, "|theta| and |phi|")
        _check_limit(np.asarray(q, dtype=np.float64)[..., 3], self.steering_limit)

    def true_factors(self) -> Array:
        return np.array(
            [self.true.wheelbase / self.nominal.wheelbase, self.true.wheel_radius / self.nominal.wheel_radius]
        )

    def with_true_factors(self, factors: Array) -> CarPlant:
        true = CarModel(self.true.wheelbase * float(factors[0]), self.true.wheel_radius * float(factors[1]))
        return replace(self, true=true)

    def kernel(self) -> tuple[int, Array]:
        limit = np.inf if self.steering_limit is None else self.steering_limit
        nominal, true = self.nominal, self.true
        values = dict(
            wheelbase=nominal.wheelbase,
            wheel_radius=nominal.wheel_radius,
            true_wheelbase=true.wheelbase,
            true_wheel_radius=true.wheel_radius,
            steering_limit=limit,
        )
        servo = dict(steering_offset=self.steering_offset, steering_lag=self.steering_lag, speed_lag=self.speed_lag)
        if self.lab:
            lab = dict(steering_backlash=self.steering_backlash, encoder_pulses=float(self.encoder_pulses))
            return CAR_LAB_FIELD, KERNEL_LAYOUTS[CAR_LAB_FIELD].row(**values, **servo, **lab)
        if self.servo:
            return CAR_SERVO_FIELD, KERNEL_LAYOUTS[CAR_SERVO_FIELD].row(**values, **servo)
        return CAR_FIELD, KERNEL_LAYOUTS[CAR_FIELD].row(**values)


@dataclass(frozen=True)
class ChainedPlant:
    """The chained form of eq. (1) with true input gains: ``v1_gain * v1`` drives every
    ``v1`` term and ``v2_gain * v2`` drives ``z2`` (a perturbation of the form of eq. 37)."""

    kind: ClassVar[PlantKind] = CHAINED
    factor_names: ClassVar[tuple[str, str]] = ("v1_gain", "v2_gain")
    dimension: int
    v1_gain: float = 1.0
    v2_gain: float = 1.0

    def __post_init__(self) -> None:
        require(
            3 <= self.dimension <= MAX_DIMENSION, "dimension", f"must be in [3, {MAX_DIMENSION}], got {self.dimension}"
        )
        for name in ("v1_gain", "v2_gain"):
            value = getattr(self, name)
            require(isfinite(value) and value != 0, name, f"must be finite and nonzero, got {value}")

    @property
    def state_dim(self) -> int:
        return self.dimension

    def initial_state(self, q: Array) -> Array:
        """The state is the configuration."""
        return np.array(q, dtype=np.float64)

    def configuration(self, x: Array) -> Array:
        """The state is the configuration."""
        return np.asarray(x)

    def estimate(self, x: Array) -> Array:
        """The state is the configuration, known exactly."""
        return np.asarray(x)

    def check_configuration(self, q: Array) -> None:
        q = np.asarray(q, dtype=np.float64)
        require(q.shape[-1] == self.dimension, "z", f"needs {self.dimension} values, got shape {q.shape}")
        require(bool(np.all(np.isfinite(q))), "z", f"must be finite, got {q.tolist()}")
        _check_magnitude(q)

    def true_factors(self) -> Array:
        return np.array([self.v1_gain, self.v2_gain])

    def with_true_factors(self, factors: Array) -> ChainedPlant:
        return replace(self, v1_gain=self.v1_gain * float(factors[0]), v2_gain=self.v2_gain * float(factors[1]))

    def kernel(self) -> tuple[int, Array]:
        row = KERNEL_LAYOUTS[CHAINED_FIELD].row(v1_gain=self.v1_gain, v2_gain=self.v2_gain, dimension=self.dimension)
        return CHAINED_FIELD, row


@dataclass(frozen=True)
class UnicyclePlant:
    """A differential-drive robot (:mod:`ilc_steering.core.unicycle`) with its true wheel radius
    and axle width, its commanded forward speed and turn rate turned into wheel speeds with the
    nominal ones. The state is the configuration ``(x, y, theta)``."""

    kind: ClassVar[PlantKind] = UNICYCLE
    factor_names: ClassVar[tuple[str, str]] = ("wheel_radius_ratio", "axle_width_ratio")
    true: UnicycleModel
    nominal: UnicycleModel

    @property
    def state_dim(self) -> int:
        return 3

    def initial_state(self, q: Array) -> Array:
        """The state is the configuration."""
        return np.array(q, dtype=np.float64)

    def configuration(self, x: Array) -> Array:
        """The state is the configuration."""
        return np.asarray(x, dtype=np.float64)

    def estimate(self, x: Array) -> Array:
        """The configuration, measured exactly."""
        return np.asarray(x, dtype=np.float64)

    def check_configuration(self, q: Array) -> None:
        """The chart (``|theta| < pi/2`` in the task frame)."""
        check_unicycle_chart(q)
        _check_magnitude(q)
        _check_angles(q, "|theta|")

    def true_factors(self) -> Array:
        return np.array(
            [self.true.wheel_radius / self.nominal.wheel_radius, self.true.axle_width / self.nominal.axle_width]
        )

    def with_true_factors(self, factors: Array) -> UnicyclePlant:
        true = UnicycleModel(self.true.wheel_radius * float(factors[0]), self.true.axle_width * float(factors[1]))
        return replace(self, true=true)

    def kernel(self) -> tuple[int, Array]:
        nominal, true = self.nominal, self.true
        row = KERNEL_LAYOUTS[UNICYCLE_FIELD].row(
            wheel_radius=nominal.wheel_radius,
            axle_width=nominal.axle_width,
            true_wheel_radius=true.wheel_radius,
            true_axle_width=true.axle_width,
        )
        return UNICYCLE_FIELD, row


@dataclass(frozen=True)
class TrailerPlant:
    """The car towing one trailer (:mod:`ilc_steering.core.trailer`) with its true geometry,
    steered through the nominal chained form. ``steering_limit`` bounds ``|phi|`` [rad] as for
    :class:`CarPlant`: the state's fourth entry is the servo's command, which winds past the stop
    while the wheel rests there. State ``(x1, y1, theta1, phi_c, delta)``."""

    kind: ClassVar[PlantKind] = CAR_TRAILER
    factor_names: ClassVar[tuple[str, str]] = ("wheelbase_ratio", "wheel_radius_ratio")
    true: TrailerModel
    nominal: TrailerModel
    steering_limit: float | None = None

    def __post_init__(self) -> None:
        _check_steering_limit(self.steering_limit)

    @property
    def state_dim(self) -> int:
        return 5

    def initial_state(self, q: Array) -> Array:
        """At rest at ``q``: the commanded steering angle is ``phi``."""
        return np.array(q, dtype=np.float64)

    def configuration(self, x: Array) -> Array:
        """The configurations, the wheel angle the clipped command."""
        q = np.array(x, dtype=np.float64)
        if self.steering_limit is not None:
            q[..., 3] = np.clip(q[..., 3], -self.steering_limit, self.steering_limit)
        return q

    def estimate(self, x: Array) -> Array:
        """The configurations, measured exactly."""
        return self.configuration(x)

    def check_configuration(self, q: Array) -> None:
        """The chart (``|theta1|, |phi|, |delta| < pi/2`` in the task frame; no jackknife) and the steering limit."""
        check_trailer_chart(q)
        _check_magnitude(q)
        _check_angles(q, "|theta1|, |phi| and the hitch angle |delta|")
        _check_limit(np.asarray(q, dtype=np.float64)[..., 3], self.steering_limit)

    def true_factors(self) -> Array:
        return np.array(
            [self.true.wheelbase / self.nominal.wheelbase, self.true.wheel_radius / self.nominal.wheel_radius]
        )

    def with_true_factors(self, factors: Array) -> TrailerPlant:
        t = self.true
        return replace(
            self, true=TrailerModel(t.wheelbase * float(factors[0]), t.wheel_radius * float(factors[1]), t.hitch_length)
        )

    def kernel(self) -> tuple[int, Array]:
        limit = np.inf if self.steering_limit is None else self.steering_limit
        n, t = self.nominal, self.true
        row = KERNEL_LAYOUTS[TRAILER_FIELD].row(
            wheelbase=n.wheelbase,
            wheel_radius=n.wheel_radius,
            true_wheelbase=t.wheelbase,
            true_wheel_radius=t.wheel_radius,
            steering_limit=limit,
            hitch_length=n.hitch_length,
            true_hitch_length=t.hitch_length,
        )
        return TRAILER_FIELD, row


PLANTS: dict[str, type[CarPlant] | type[ChainedPlant] | type[UnicyclePlant] | type[TrailerPlant]] = {
    "car": CarPlant,
    "chained": ChainedPlant,
    "unicycle": UnicyclePlant,
    "car_trailer": TrailerPlant,
}
"""``plant.model`` -> plant class."""


class PlantBatch:
    """Plants of one kind, one per trial of a batch: their kernel parameters stacked once, so a
    batch of different robots (a vector env's ``true_factors``, a robustness map's row) costs one
    compiled call per step and nothing per plant."""

    def __init__(self, plants: Sequence[Plant]) -> None:
        kernels = [plant.kernel() for plant in plants]
        fields = {field for field, _ in kernels}
        if len(fields) != 1:
            raise ValueError(f"a batch of plants must be all of one kind; got {len(plants)} of {len(fields)} kinds")
        self.field = fields.pop()
        self.params = np.array([row for _, row in kernels])
        self.size = len(kernels)

    def kernel(self) -> tuple[int, Array]:
        """The field's id and the parameters ``(B, P)``, a row per trial."""
        return self.field, self.params


def nominal_plant(chained_map: object, dimension: int, steering_limit: float | None = None) -> Plant:
    """The plant the controller assumes: a robot whose true geometry is its nominal map's (a
    chained plant of ``dimension`` with unit gains for ``chained_map=None``)."""
    if chained_map is None:
        return ChainedPlant(dimension)
    if isinstance(chained_map, CarModel):
        return CarPlant(chained_map, chained_map, steering_limit)
    if isinstance(chained_map, UnicycleModel):
        return UnicyclePlant(chained_map, chained_map)
    if isinstance(chained_map, TrailerModel):
        return TrailerPlant(chained_map, chained_map, steering_limit)
    raise ValueError(f"no plant for a robot mapped by {type(chained_map).__name__}")
