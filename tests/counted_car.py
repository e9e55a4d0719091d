"""An external plant that counts its drives: the kinematic car of eq. 3 behind :class:`ExternalPlantBase`.

It stands for a real robot: every call of ``run_trials`` is a drive, and :data:`DRIVES` keeps the
batch size of each, so a test can check that nothing drives it more often than the trials counted.
``scatter`` adds Gaussian noise of that standard deviation to the true final pose (x, y [m], theta
[rad]; the wheel angle is left exact), drawn from a generator seeded by ``seed``, restarted from
the env's seed and ``seed`` on ``reset(seed=...)`` (``reseed``): a robot that does not repeat itself.

Registered as ``counted_car`` (``tests/test_scatter.py``); its config keys are the car's plus
``scatter`` and ``seed``.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any, ClassVar, Literal

import numpy as np
import numpy.typing as npt

from ilc_steering.core.external import ExternalPlantBase, ExternalTrials, plant_generator
from ilc_steering.core.plants import PlantKind
from ilc_steering.core.profiles import InputProfile
from ilc_steering.core.robots.car import CAR, CarPlant, CarPlantConfig
from ilc_steering.core.simulate import simulate

Array = npt.NDArray[np.float64]

DRIVES: list[int] = []
"""The number of trials of every ``run_trials`` call, in order, across every counted car."""


@dataclass(frozen=True)
class CountedCarPlant(ExternalPlantBase):
    """The simulated car, run as someone else's code, counting its drives."""

    kind: ClassVar[PlantKind] = CAR
    factor_names: ClassVar[tuple[str, str]] = ("wheelbase_ratio", "wheel_radius_ratio")
    name: ClassVar[str] = "the counted car"
    car: CarPlant
    scatter: float = 0.0
    seed: int = 0
    _rng: list[np.random.Generator] = field(default_factory=list, compare=False, repr=False)

    @property
    def state_dim(self) -> int:
        return self.car.state_dim

    @property
    def steering_limit(self) -> float | None:
        return self.car.steering_limit

    def with_frame(self, angle: float) -> CountedCarPlant:
        return replace(self, _rng=self._rng)  # the car's trials run in the task frame already

    def configuration(self, x: Array) -> Array:
        return self.car.configuration(x)

    def estimate(self, x: Array) -> Array:
        return self.car.estimate(x)

    def check_configuration(self, q: Array) -> None:
        self.car.check_configuration(q)

    def initial_state(self, q: Array) -> Array:
        return self.car.initial_state(q)

    def reseed(self, seed: int) -> None:
        self._rng[:] = [plant_generator(seed, self.seed)]  # the env's seed restarts the scatter

    def run_trials(self, profile: InputProfile, x0: Array, c: Array, record: bool = False) -> ExternalTrials:
        DRIVES.append(int(c.shape[0]))
        trials = simulate(self.car, profile, x0, c, 1 / 32, record)
        final = trials.final.copy()
        if self.scatter:
            if not self._rng:
                self._rng.append(np.random.default_rng(self.seed))
            final[:, :3] += self.scatter * self._rng[0].standard_normal((final.shape[0], 3))
        logs: list[dict[str, Any]] = [{} for _ in range(c.shape[0])]
        return ExternalTrials(final, trials.status, trials.times, trials.states, logs=logs)


@dataclass(frozen=True)
class CountedCarConfig(CarPlantConfig):
    model: Literal["counted_car"]  # type: ignore[assignment]
    scatter: float = 0.0  # [m, rad] standard deviation of the true final pose's scatter
    seed: int = 0  # of the scatter's generator

    plant_class: ClassVar[type] = CountedCarPlant  # type: ignore[assignment]

    def plant(self) -> CountedCarPlant:  # type: ignore[override]
        return CountedCarPlant(super().plant(), self.scatter, self.seed)


CONFIG = """\
name: counted_parking
plant:
  model: counted_car
  wheelbase: 0.2
  wheel_radius: 0.02
  true_wheelbase: 0.22
  true_wheel_radius: 0.022
  scatter: {scatter}
  seed: {seed}
task:
  start: [-1.0, 0.0, 0.7853981633974483, 0.0]
  goal:  [0.0, 0.0, 0.7853981633974483, 0.0]
  pieces: [5.0]
  v1_fixed: []
  v2_terms: 3
learning:
  nu_a: 1.0
  nu_b: 1.0
  trials: {trials}
  tolerance: {{cartesian: {tolerance}, orientation: {tolerance}}}
"""
"""Simulation 1 (forward parking) on the counted car."""
