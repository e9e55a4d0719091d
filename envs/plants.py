"""Simulated plants: the *true* systems the learner drives, and their batched simulation.

A plant holds its true parameters; the learner never sees it. It is driven by the chained
inputs ``v(t)`` of an input profile: the car converts them with the controller's *nominal*
transform (eqs. 4-5) from its measured configuration at every instant.
"""

from __future__ import annotations

from dataclasses import dataclass
from math import isfinite

import numpy as np
import numpy.typing as npt

from ilc_steering.envs.car import CarModel
from ilc_steering.envs.integrate import CAR, CHAINED, DEFAULT_MAX_STEP, integrate, steps_per_piece
from ilc_steering.envs.profiles import PiecewiseProfile

__all__ = ["CarPlant", "ChainedPlant", "Plant", "Trials", "simulate"]

Array = npt.NDArray[np.float64]


@dataclass(frozen=True)
class CarPlant:
    """The car of eq. (3) with its true geometry, steered through the nominal eqs. (4)-(5).

    ``steering_limit`` bounds the wheel angle ``|phi|`` [rad] (``None`` for none). The state's
    fourth entry is then the servo's commanded angle, which may wind past the limit while the
    wheel rests at the stop (see :mod:`ilc_steering.envs.integrate`); :meth:`configuration`
    gives the car's ``q``.
    """

    true: CarModel
    nominal: CarModel
    steering_limit: float | None = None

    def __post_init__(self) -> None:
        if self.steering_limit is not None and not (0 < self.steering_limit < np.pi / 2):
            raise ValueError(f"steering_limit must be in (0, pi/2) rad or None, got {self.steering_limit}")

    @property
    def state_dim(self) -> int:
        return 4

    def configuration(self, x: Array) -> Array:
        """The configurations ``q`` of states ``x`` (``(..., 4)``): the wheel angle is the clipped command."""
        if self.steering_limit is None:
            return np.asarray(x)
        q = np.array(x, dtype=np.float64)
        q[..., 3] = np.clip(q[..., 3], -self.steering_limit, self.steering_limit)
        return q

    def kernel(self) -> tuple[int, Array]:
        limit = np.inf if self.steering_limit is None else self.steering_limit
        params = [self.nominal.wheelbase, self.nominal.wheel_radius, self.true.wheelbase, self.true.wheel_radius]
        return CAR, np.array([*params, limit])


@dataclass(frozen=True)
class ChainedPlant:
    """The chained form of eq. (1) with true input gains: ``v1_gain * v1`` drives every
    ``v1`` term and ``v2_gain * v2`` drives ``z2`` (a perturbation of the form of eq. 37)."""

    dimension: int
    v1_gain: float = 1.0
    v2_gain: float = 1.0

    def __post_init__(self) -> None:
        if self.dimension < 3:
            raise ValueError(f"dimension must be >= 3, got {self.dimension}")
        for name in ("v1_gain", "v2_gain"):
            value = getattr(self, name)
            if not (isfinite(value) and value != 0):
                raise ValueError(f"{name} must be finite and nonzero, got {value}")

    @property
    def state_dim(self) -> int:
        return self.dimension

    def configuration(self, x: Array) -> Array:
        """The state is the configuration."""
        return np.asarray(x)

    def kernel(self) -> tuple[int, Array]:
        return CHAINED, np.array([self.v1_gain, self.v2_gain])


Plant = CarPlant | ChainedPlant


@dataclass(frozen=True)
class Trials:
    """The outcome of a batch of trials: final plant states ``(B, nx)`` (see
    ``Plant.configuration`` for the robot's configuration), per-trial status
    (:data:`~ilc_steering.envs.integrate.OK` or ``LEFT_CHART``), and optionally the times
    ``(S,)`` [s] and states ``(B, S, nx)`` at every step."""

    final: Array
    status: npt.NDArray[np.int64]
    times: Array | None = None
    states: Array | None = None


def simulate(
    plant: Plant,
    profile: PiecewiseProfile,
    x0: Array,
    c: Array,
    max_step: float = DEFAULT_MAX_STEP,
    record: bool = False,
    parallel: bool = False,
) -> Trials:
    """Run a batch of trials of ``plant`` from states ``x0`` ``(B, nx)`` with coefficients ``c`` ``(B, 1 + q)``."""
    durations = np.asarray(profile.durations, dtype=np.float64)
    steps = steps_per_piece(durations, max_step)
    v1, v2 = profile.polynomials(c)
    model, params = plant.kernel()
    final, status, states = integrate(model, params, x0, durations, steps, v1, v2, record=record, parallel=parallel)
    if not record:
        return Trials(final, status)
    times = np.concatenate(
        [[0.0]] + [t0 + np.arange(1, k + 1) * d / k for t0, d, k in zip(profile.breakpoints, durations, steps)]
    )
    return Trials(final, status, times, states)
