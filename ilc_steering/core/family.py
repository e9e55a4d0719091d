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

At :math:`\theta = 0` the family is the nominal model itself, its final states those of eq. 23
(to the integrator's 1e-9), except that it keeps the steering stop, which eq. 23 ignores.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from ilc_steering.core.grid import DEFAULT_MAX_STEP
from ilc_steering.core.integrate import OK
from ilc_steering.core.nominal import NominalModel
from ilc_steering.core.plants import Plant, PlantBatch
from ilc_steering.core.robots import nominal_plant
from ilc_steering.core.simulate import simulate

__all__ = ["MAX_LOG_RATIO", "ModelFamily"]

Array = npt.NDArray[np.float64]

MAX_LOG_RATIO = float(np.log(2.0))
"""The largest ``|theta_i|``: the family's parameters stay within a factor 2 of the nominal ones."""

_MAX_CACHED = 4096


class ModelFamily:
    """The nominal plant with free parameters ``theta`` (log-ratios to the nominal values).

    Parameters
    ----------
    model
        The nominal model; its map (a car's geometry, or none for the chained form) sets the family.
    max_step
        The integrator's longest step [s].
    """

    def __init__(self, model: NominalModel, max_step: float = DEFAULT_MAX_STEP) -> None:
        self.model = model
        self.max_step = max_step
        self._nominal: Plant = nominal_plant(model.chained_map, model.dimension, model.steering_limit)
        self.names: tuple[str, ...] = self._nominal.family_names()
        self._q0 = self.to_configuration(model.z_start)
        self._x0 = self._nominal.initial_state(self._q0)
        self._field = self._nominal.kernel()[0]
        self._rows: dict[bytes, Array] = {}

    @property
    def size(self) -> int:
        """The number of free parameters."""
        return len(self.names)

    def parameters(self, theta: Array) -> dict[str, float]:
        """The ratios (true over nominal) that ``theta`` stands for, by name."""
        return {name: float(np.exp(t)) for name, t in zip(self.names, theta)}

    def plant(self, theta: Array) -> Plant:
        """The hypothesised plant with parameters ``theta``."""
        ratio = np.exp(np.clip(np.asarray(theta, dtype=np.float64), -MAX_LOG_RATIO, MAX_LOG_RATIO))
        return self._nominal.with_family(ratio)

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
        many hypotheses in one compiled call."""
        thetas = np.atleast_2d(np.asarray(thetas, dtype=np.float64))
        c = np.ascontiguousarray(np.atleast_2d(c), dtype=np.float64)
        if thetas.shape[0] != c.shape[0]:
            raise ValueError(f"configurations_many: {thetas.shape[0]} parameter rows for {c.shape[0]} trials")
        rows = np.array([self._row(theta) for theta in thetas])
        x0 = np.ascontiguousarray(np.broadcast_to(self._x0, (c.shape[0], self._nominal.state_dim)))
        trials = simulate(PlantBatch.from_rows(self._field, rows), self.model.profile, x0, c, self.max_step)
        return self._nominal.configuration(trials.final), trials.status == OK

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
                raise ValueError("configurations_many: a hypothesis changed the plant's kind")
            self._rows[key] = row
        return row

    def to_configuration(self, z: Array) -> Array:
        """Chained coordinates ``(..., n)`` to configurations (the nominal map's inverse)."""
        return self.model.chained_map.from_chained(z)

    def to_chained(self, q: Array) -> Array:
        """Configurations to chained coordinates (the nominal map)."""
        return self.model.chained_map.to_chained(q)
