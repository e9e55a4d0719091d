r"""The car-like robot (eq. 3) as a plant: its true geometry and perturbations, its config keys.

Configuration ``q = (x, y, theta, phi)``: rear-axle midpoint [m], body orientation [rad] and
steering angle [rad]. Inputs: ``u1`` the driving-wheel angular velocity [rad/s], ``u2`` the
steering rate [rad/s]. The car's kinematics, eq. 3, the chained form of eq. 4 and the input
transformation of eq. 5, are :mod:`ilc_steering.core.robots.car_model` (re-exported here): the
controller uses them with the *nominal* geometry, the plant (:class:`CarPlant`, ``plant.model:
car``) moves with the true one.

The plant, its config keys and its drawing are plain numpy, so a learner that needs the map pays
for no compiler; the car's compiled fields are in :mod:`ilc_steering.core.robots.car_fields` (the
car with servos), :mod:`ilc_steering.core.robots.car_lab` (the lab robot) and
:mod:`ilc_steering.core.tangent` (the batched kernel), imported when a car is first simulated.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from math import isfinite
from typing import Any, ClassVar, Literal

import numpy as np
import numpy.typing as npt

from ilc_steering.core.checks import check_factors, renamed, require
from ilc_steering.core.plants import (
    CHART_MARGIN,
    FactorFamily,
    Kernel,
    PlantKind,
    check_steered,
    check_steering_limit,
)
from ilc_steering.core.robots.car_model import CarModel, car_velocity, chained_inputs, wheel_ratios
from ilc_steering.core.robots.chart import check_chart, frame_angle, rotate
from ilc_steering.core.robots.outline import car_outline
from ilc_steering.errors import BadInput

__all__ = [
    "CAR",
    "MAX_BACKLASH",
    "MAX_LAG",
    "MAX_PULSES",
    "MAX_STEERING_OFFSET",
    "CarModel",
    "CarPlant",
    "CarPlantConfig",
    "car_outline",
    "car_velocity",
    "chained_inputs",
    "check_chart",
    "frame_angle",
    "rotate",
]

Array = npt.NDArray[np.float64]


CAR = PlantKind("car", True, ("x [m]", "y [m]", "θ [rad]", "φ [rad]"), ("u1 [rad/s]", "u2 [rad/s]"))
MAX_BACKLASH = 0.2
"""[rad] the largest ``steering_backlash`` of a car plant."""
MAX_PULSES = 100_000
"""The largest ``encoder_pulses`` (per wheel turn) of a car plant."""
MAX_STEERING_OFFSET = 0.5
"""[rad] the largest ``|steering_offset|`` of a car plant."""
MAX_LAG = 10.0
"""[s] the largest servo time constant of a car plant."""


@dataclass(frozen=True)
class CarPlant(FactorFamily):
    """The car of eq. (3) with its true geometry, steered through the nominal eqs. (4)-(5).

    ``steering_limit`` bounds the wheel angle ``|phi|`` [rad] (``None`` for none). The state's
    fourth entry is then the servo's commanded angle, which may wind past the limit while the
    wheel rests at the stop (see :mod:`ilc_steering.core.tangent`); :meth:`configuration`
    gives the car's ``q``.

    Three perturbations outside any geometry the controller could assume, each 0 (off) by default:

    - ``steering_offset`` [rad]: a misaligned wheel; its true angle is the measured one plus this;
    - ``steering_lag`` [s]: the wheel follows the (clipped) commanded angle ``phi_c`` through a
      first-order servo, ``dphi_w/dt = (clip(phi_c) - phi_w) / steering_lag``; the controller
      measures ``phi_w``;
    - ``speed_lag`` [s]: the driving wheel's speed follows ``u1`` through a first-order servo,
      ``domega/dt = (u1 - omega) / speed_lag``, from rest at the start of a trial; the trial is
      measured at ``T``, before the wheel has spun down.

    With any of them on, the state has the twelve entries of the lab robot's kernel
    (:mod:`~ilc_steering.core.robots.car_lab`, its play and encoders off), the servo's output
    ``phi_w`` fifth and the wheel's speed ``omega`` sixth; without, it is ``(x, y, theta, phi_c)``.

    Two imperfections of section 5's lab robot, each 0 (off) by default:

    - ``steering_backlash`` [rad]: play ``b`` in the steering linkage; the wheel rests while the
      servo's output ``phi_s`` moves within ``b/2`` of it and is pushed along beyond (the play
      operator); the controller measures ``phi_s``, not the wheel;
    - ``encoder_pulses``: pulses per turn of the driving wheel's encoder (0: none); the heading
      the controller uses in eqs. 4-5 is then dead-reckoned, stepping by the nominal odometry of
      one pitch of travel at each pulse, from the true one at the start of a trial.

    With either on, the play's anchor, the wheel's rotation and the controller's estimate move in
    the state's last six entries; the final
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
    servo_kernel: bool = False
    """Run on the servo's kernel even with every servo perturbation off: a model family
    whose hypotheses vary the actuator's parameters keeps one kernel for all of them."""

    @classmethod
    def nominal_plant(cls, chained_map: Any, dimension: int, steering_limit: float | None) -> CarPlant:
        """The car the controller assumes: its true geometry the nominal one, with the known steering limit."""
        return cls(chained_map, chained_map, steering_limit)

    def __post_init__(self) -> None:
        check_steering_limit(self.steering_limit)
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
        """Whether a lab-robot imperfection is on (play or encoders)."""
        return bool(self.steering_backlash or self.encoder_pulses)

    @property
    def servo(self) -> bool:
        """Whether a servo perturbation is on and no lab-robot imperfection (the lab's kernel either way)."""
        return bool(self.servo_kernel or self.steering_offset or self.steering_lag or self.speed_lag) and not self.lab

    @property
    def state_dim(self) -> int:
        return 12 if self.lab or self.servo else 4

    def initial_state(self, q: Array) -> Array:
        """At rest at ``q``: the commanded and the measured wheel angles are ``phi``, the wheel speed 0;
        with a servo or the lab robot's imperfections also the play's anchor, the wheel's rotation 0,
        the estimate ``q``, no pulses."""
        q = np.asarray(q, dtype=np.float64)
        if not self.servo and not self.lab:
            return q.copy()
        zero = np.zeros_like(q[..., :1])
        return np.concatenate([q, q[..., 3:4], zero, q[..., 3:4], zero, q[..., :3], zero], axis=-1)

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
        check_steered(q, check_chart, "|theta| and |phi|", self.steering_limit)

    def true_factors(self) -> Array:
        return wheel_ratios(self.true, self.nominal)

    def actuator_names(self) -> tuple[str, ...]:
        """The actuators' parameters a model family may leave free beside :meth:`family_names`: the
        wheel's offset [rad], the steering servo's first-order time constant [s], the play in its
        linkage [rad] and the drive's time constant [s]."""
        return ("steering_offset", "steering_lag", "steering_backlash", "speed_lag")

    def with_actuators(self, values: Array) -> CarPlant:
        """The plant with the actuators of :meth:`actuator_names` set to ``values`` (absolute, in rad
        and s), always on the servo's (the lab's) kernel."""
        offset, steering_lag, backlash, speed_lag = map(float, values)
        return replace(
            self,
            steering_offset=offset,
            steering_lag=steering_lag,
            steering_backlash=backlash,
            speed_lag=speed_lag,
            servo_kernel=True,
        )

    def with_odometry(self, pulses: int) -> CarPlant:
        """The plant whose controller dead-reckons its heading from ``pulses`` encoder pulses per turn
        (the nominal model's ``encoder_pulses``: part of the controller, known to it)."""
        return replace(self, encoder_pulses=int(pulses))

    def with_true_factors(self, factors: Array) -> CarPlant:
        f = check_factors(factors, self.factor_names)  # the user's own ratio named, not the product
        true = CarModel(self.true.wheelbase * f[0], self.true.wheel_radius * f[1])
        return replace(self, true=true)

    def kernel(self) -> tuple[Kernel, Array]:
        """The batched kernel of :mod:`~ilc_steering.core.tangent`, or with a servo perturbation or
        a lab imperfection on, the servo's of :mod:`~ilc_steering.core.robots.car_fields` or the lab's of
        :mod:`~ilc_steering.core.robots.car_lab`."""
        from ilc_steering.core.robots.car_fields import car_kernel  # numba, loaded when a car is first simulated

        return car_kernel(self)

    def reference_field(self, profile: Any, c: Array) -> tuple[Callable[[float, Array], Array], float, Any]:
        """Eqs. 4-5 with the nominal geometry from the measured wheel angle (the clipped command, or
        the lagging wheel), eq. 3 with the true geometry, misaligned wheel and lagging drive, the
        servo integrating ``u2``. Not for the lab robot, whose events need
        :func:`ilc_steering.core.reference.lab_car_trial`."""
        if self.lab:
            raise NotImplementedError("the lab robot's reference is core.reference.lab_car_trial (its events)")
        limit = np.inf if self.steering_limit is None else self.steering_limit
        nominal, true = self.nominal, self.true
        offset, steering_lag, speed_lag, servo = self.steering_offset, self.steering_lag, self.speed_lag, self.servo

        def field(t: float, q: Array) -> Array:
            v1, v2 = profile.evaluate(c, np.array(t))
            commanded = min(max(q[3], -limit), limit)
            phi = q[4] if steering_lag else commanded
            u1, u2 = chained_inputs(q[2], phi, float(v1), float(v2), nominal.wheelbase, nominal.wheel_radius)
            omega = q[5] if speed_lag else u1
            dx, dy, dtheta, _ = car_velocity(q[2], phi + offset, omega, u2, true.wheelbase, true.wheel_radius)
            if not servo:
                return np.array([dx, dy, dtheta, u2])
            dphi_w = (commanded - q[4]) / steering_lag if steering_lag else 0.0
            domega = (u1 - q[5]) / speed_lag if speed_lag else 0.0
            # The lab kernel's other entries, its play and encoders off: the wheel (the play's anchor)
            # follows the servo's output, the wheel turns, the estimate rests at the start, no pulse.
            dwheel = dphi_w if steering_lag else (0.0 if abs(q[3]) >= limit else u2)
            return np.array([dx, dy, dtheta, u2, dphi_w, domega, dwheel, omega, 0.0, 0.0, 0.0, 0.0])

        def chart(t: float, x: Array) -> float:
            return float(np.pi / 2 - CHART_MARGIN - abs(x[2]))

        return field, limit, chart


@dataclass(frozen=True)
class CarPlantConfig:
    model: Literal["car"]
    wheelbase: float  # nominal ell [m], known to the controller
    wheel_radius: float  # nominal rho [m]
    true_wheelbase: float  # the simulated robot's ell [m]
    true_wheel_radius: float  # the simulated robot's rho [m]
    steering_limit: float | None = None  # bound on |phi| [rad]; None for none
    steering_offset: float = 0.0  # [rad] the wheel's true angle exceeds the measured one by this (misaligned wheel)
    steering_lag: float = 0.0  # [s] time constant of the steering servo (wheel follows the command); 0: none
    speed_lag: float = 0.0  # [s] time constant of the drive servo (wheel speed follows u1); 0: none
    steering_backlash: float = 0.0  # [rad] play in the steering linkage (section 5); 0: none
    encoder_pulses: int = 0  # pulses per wheel turn; > 0: the heading is dead-reckoned from them; 0: measured

    kind: ClassVar[PlantKind] = CAR
    plant_class: ClassVar[type[CarPlant]] = CarPlant
    dimension: ClassVar[int] = 4

    def __post_init__(self) -> None:
        self.plant()

    def nominal_map(self) -> CarModel:
        """The geometry the controller assumes (eqs. 4-5)."""
        return CarModel(self.wheelbase, self.wheel_radius)

    def plant(self) -> CarPlant:
        """The simulated car: true geometry, steered with the nominal one."""
        nominal = self.nominal_map()
        with renamed({"wheelbase": "true_wheelbase", "wheel_radius": "true_wheel_radius"}):
            true = CarModel(self.true_wheelbase, self.true_wheel_radius)
        return CarPlant(
            true,
            nominal,
            self.steering_limit,
            self.steering_offset,
            self.steering_lag,
            self.speed_lag,
            self.steering_backlash,
            self.encoder_pulses,
        )

    def check_task(self, max_step: float, cyclic: bool) -> None:
        """A servo lag the integrator's step resolves; no lab imperfection on a cycle."""
        for lag in ("steering_lag", "speed_lag"):
            value = getattr(self, lag)
            require(
                value == 0 or value >= max_step,
                lag,
                f"{value} s is shorter than the integrator step simulation.max_step = {max_step} s, "
                "which would not resolve it; lower max_step or set the lag to 0",
            )
        if cyclic and (self.steering_backlash or self.encoder_pulses):  # a rule of two keys: named by both
            raise BadInput(
                "steering_backlash and encoder_pulses are for one-trial tasks (a cycle would carry the "
                "dead-reckoned estimate from trial to trial)"
            )
