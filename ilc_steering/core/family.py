r"""The nominal structure with its physical parameters free: what a learner may simulate.

A :class:`ModelFamily` is built from a :class:`~ilc_steering.core.nominal.NominalModel` alone:
the plant the controller *assumes*, with a vector :math:`\theta` of log-ratios of the parameters
it is least sure of, and no other knowledge. A learner simulates it (on the compiled kernel, no
trial spent) to fit :math:`\theta` to the trials it has measured and to invert the refit model.

- a car (a :class:`~ilc_steering.core.robots.car.CarModel` map): :math:`\tilde\ell = \ell e^{\theta_1}`
  and :math:`\tilde\rho = \rho e^{\theta_2}`, the wheelbase and wheel radius of eq. 3 (the
  controller keeps the nominal ones in eqs. 4-5), with the robot's known steering limit;
- the chained form (no map): the input gains :math:`g_1 = e^{\theta_1}` on ``v1`` and
  :math:`g_2 = e^{\theta_2}` on ``v2`` (eq. 37);
- any other robot: the true parameters its plant's ``with_family`` scales (a unicycle's wheel
  radius and axle width; a car-trailer's wheelbase, wheel radius and hitch length).

With ``actuators`` (names from the plant's ``actuator_names``: the car's ``steering_offset``,
``steering_lag``, ``steering_backlash`` and ``speed_lag``) the family also leaves free the
actuators' own parameters, as absolute values after the ratios: the wheel's offset [rad] in ``+-``
:data:`MAX_ACTUATOR_OFFSET`, the play in the steering linkage [rad] in ``[0,``
:data:`MAX_ACTUATOR_BACKLASH` ``]`` and the servos' first-order lags [s] in ``[max_step / 4,``
:data:`MAX_ACTUATOR_LAG` ``]`` (a lag much below the integrator's step is not resolved by it, so a
lag-free servo is another family: the lag held at 0). Every hypothesis then runs on the servo's
(the lab's) kernel.

A controller that dead-reckons its heading from encoder pulses (the nominal model's
``encoder_pulses``, part of the controller) is part of every hypothesis: the family's plants count
the same pulses, so a wrong wheel radius is seen, as on the robot, through the heading the
controller estimates from it.

At :math:`\theta = 0` the family is the nominal model itself, its final states those of eq. 23
(to the integrator's 1e-9), except that it keeps the steering stop, which eq. 23 ignores.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt

from ilc_steering.core.grid import DEFAULT_MAX_STEP
from ilc_steering.core.integrate import OK
from ilc_steering.core.nominal import NominalModel
from ilc_steering.core.plants import Plant, PlantBatch
from ilc_steering.core.robots import nominal_plant
from ilc_steering.core.simulate import simulate
from ilc_steering.errors import BadInput

__all__ = ["MAX_ACTUATOR_BACKLASH", "MAX_ACTUATOR_LAG", "MAX_ACTUATOR_OFFSET", "MAX_LOG_RATIO", "ModelFamily"]

Array = npt.NDArray[np.float64]

MAX_LOG_RATIO = float(np.log(2.0))
"""The largest ``|theta_i|``: the family's parameters stay within a factor 2 of the nominal ones."""

MAX_ACTUATOR_OFFSET = 0.15
"""[rad] the largest steering offset of the family with actuators."""
MAX_ACTUATOR_LAG = 0.4
"""[s] the largest steering or drive lag of the family with actuators (a hobby servo's is well below)."""
MAX_ACTUATOR_BACKLASH = 0.05
"""[rad] the largest play in the steering linkage of the family with actuators (about 3 degrees)."""

_MAX_CACHED = 4096
_MAX_FINALS = 16384  # trials' outcomes kept per family (a few updates' worth of an identification)


class ModelFamily:
    """The nominal plant with free parameters ``theta`` (log-ratios to the nominal values).

    Parameters
    ----------
    model
        The nominal model; its map (a car's geometry, or none for the chained form) sets the family.
    max_step
        The integrator's longest step [s].
    actuators
        The actuator parameters also left free (of the plant's ``actuator_names``; the others stay 0).
    """

    def __init__(
        self, model: NominalModel, max_step: float = DEFAULT_MAX_STEP, actuators: tuple[str, ...] = ()
    ) -> None:
        self.model = model
        self.max_step = max_step
        nominal: Any = nominal_plant(model.chained_map, model.dimension, model.steering_limit)
        if model.encoder_pulses:  # the controller's odometry: every hypothesis dead-reckons as it does
            if not hasattr(nominal, "with_odometry"):
                raise BadInput(
                    f"ModelFamily: the nominal model counts {model.encoder_pulses} encoder pulses a turn, but the "
                    f"{model.chained_map.robot} robot's plant has no odometry to count them (no with_odometry)"
                )
            nominal = nominal.with_odometry(model.encoder_pulses)
        self.names: tuple[str, ...] = nominal.family_names()
        self._ratios = len(self.names)
        self.low = np.full(self._ratios, -MAX_LOG_RATIO)
        """The smallest value of each parameter (log-ratios, then rad and s)."""
        self.high = np.full(self._ratios, MAX_LOG_RATIO)
        """The largest value of each parameter."""
        self.actuators = actuators
        """The actuator parameters left free."""
        self._actuator_index: list[int] = []
        if actuators:
            known = nominal.actuator_names() if hasattr(nominal, "actuator_names") else ()
            unknown = [name for name in actuators if name not in known]
            if unknown:
                raise BadInput(f"ModelFamily: the robot has no actuator parameter {unknown} (it has {known})")
            bounds = {
                "steering_offset": (-MAX_ACTUATOR_OFFSET, MAX_ACTUATOR_OFFSET),
                "steering_lag": (max_step / 4, MAX_ACTUATOR_LAG),
                "steering_backlash": (0.0, MAX_ACTUATOR_BACKLASH),
                "speed_lag": (max_step / 4, MAX_ACTUATOR_LAG),
            }
            self._actuator_index = [known.index(name) for name in actuators]
            self._actuator_zero = np.zeros(len(known))
            self.names += actuators
            self.low = np.append(self.low, [bounds[name][0] for name in actuators])
            self.high = np.append(self.high, [bounds[name][1] for name in actuators])
            nominal = self._with_actuators(nominal, np.zeros(len(actuators)).clip(self.low[self._ratios :]))
        self._nominal: Plant = nominal
        self._q0 = self.to_configuration(model.z_start)
        self._x0 = self._nominal.initial_state(self._q0)
        self._field = self._nominal.kernel()[0]
        self._rows: dict[bytes, Array] = {}
        self._finals: dict[bytes, tuple[Array, bool]] = {}

    @property
    def size(self) -> int:
        """The number of free parameters."""
        return len(self.names)

    @property
    def origin(self) -> Array:
        """The nominal model's parameters (the actuators' at their smallest offset and lag)."""
        return np.zeros(self.size).clip(self.low, self.high)

    def parameters(self, theta: Array) -> dict[str, float]:
        """The ratios (true over nominal) that ``theta`` stands for, by name (the actuators' values)."""
        k = self._ratios
        return {name: float(np.exp(t)) if i < k else float(t) for i, (name, t) in enumerate(zip(self.names, theta))}

    def plant(self, theta: Array) -> Plant:
        """The hypothesised plant with parameters ``theta``."""
        theta = np.clip(np.asarray(theta, dtype=np.float64), self.low, self.high)
        plant = self._nominal.with_family(np.exp(theta[: self._ratios]))
        return self._with_actuators(plant, theta[self._ratios :]) if self.actuators else plant

    def _with_actuators(self, plant: Any, values: Array) -> Any:
        full = self._actuator_zero.copy()
        full[self._actuator_index] = values
        return plant.with_actuators(full)

    def configurations(self, theta: Array, c: Array) -> tuple[Array, npt.NDArray[np.bool_]]:
        """Final configurations ``(B, nq)`` (task frame; ``z`` for the chained form) of trials with
        coefficients ``c`` ``(B, 1 + q)`` on the plant ``theta``, and whether each stayed in the chart."""
        plant = self.plant(theta)
        c = np.ascontiguousarray(np.atleast_2d(c), dtype=np.float64)
        x0 = np.ascontiguousarray(np.broadcast_to(plant.initial_state(self._q0), (c.shape[0], plant.state_dim)))
        trials = simulate(plant, self.model.profile, x0, c, self.max_step)
        return plant.configuration(trials.final), trials.status == OK

    def configurations_many(self, thetas: Array, c: Array) -> tuple[Array, npt.NDArray[np.bool_]]:
        """Like :meth:`configurations`, but trial ``i`` on its own plant ``thetas[i]`` ``(B, size)``:
        many hypotheses in one compiled call.

        A trial is simulated once: its outcome is kept by its ``(theta, c)`` bytes and handed back
        when asked again (a learner refits the same hypotheses to the same trials update after
        update). A trial's outcome does not depend on the trials beside it in the call
        (``tests/test_purity.py``), so a kept one is the very one a new call would compute."""
        thetas = np.atleast_2d(np.asarray(thetas, dtype=np.float64))
        c = np.ascontiguousarray(np.atleast_2d(c), dtype=np.float64)
        if thetas.shape[0] != c.shape[0]:
            raise BadInput(f"configurations_many: {thetas.shape[0]} parameter rows for {c.shape[0]} trials")
        keys = [theta.tobytes() + trial.tobytes() for theta, trial in zip(thetas, c)]
        known = self._finals
        if len(known) + len(keys) > _MAX_FINALS:
            known.clear()
        new: dict[bytes, int] = {}
        for i, key in enumerate(keys):
            if key not in known and key not in new:
                new[key] = i
        if new:
            index = list(new.values())
            rows = np.array([self._row(thetas[i]) for i in index])
            x0 = np.ascontiguousarray(np.broadcast_to(self._x0, (len(index), self._nominal.state_dim)))
            trials = simulate(PlantBatch.from_rows(self._field, rows), self.model.profile, x0, c[index], self.max_step)
            q_new, ok_new = self._nominal.configuration(trials.final), trials.status == OK
            kept = q_new.copy()  # the caller may write into what it is handed
            known.update((key, (kept[j], bool(ok_new[j]))) for j, key in enumerate(new))
            if len(index) == len(keys):
                return q_new, ok_new
        if not keys:
            return np.empty((0, self._q0.size)), np.empty(0, dtype=bool)
        finals = [known[key] for key in keys]
        return np.array([q for q, _ in finals]), np.array([ok for _, ok in finals])

    def _row(self, theta: Array) -> Array:
        """The kernel's parameter row of the plant ``theta`` (cached: a learner asks for the same
        hypotheses again and again)."""
        key = np.asarray(theta, dtype=np.float64).tobytes()
        row = self._rows.get(key)
        if row is None:
            if len(self._rows) >= _MAX_CACHED:
                self._rows.clear()
            field, row = self.plant(theta).kernel()
            if field is not self._field:
                raise BadInput("configurations_many: a hypothesis changed the plant's kind")
            self._rows[key] = row
        return row

    def to_configuration(self, z: Array) -> Array:
        """Chained coordinates ``(..., n)`` to configurations (the nominal map's inverse)."""
        return self.model.chained_map.from_chained(z)

    def to_chained(self, q: Array) -> Array:
        """Configurations to chained coordinates (the nominal map)."""
        return self.model.chained_map.to_chained(q)
