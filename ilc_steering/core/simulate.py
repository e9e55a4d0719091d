"""Batches of trials of a plant under an input profile, on the compiled kernel."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from ilc_steering.core.grid import DEFAULT_MAX_STEP, steps_per_span
from ilc_steering.core.integrate import integrate
from ilc_steering.core.plants import Plant, PlantBatch
from ilc_steering.core.profiles import InputProfile

__all__ = ["Trials", "simulate"]

Array = npt.NDArray[np.float64]


@dataclass(frozen=True)
class Trials:
    """The outcome of a batch of trials: final plant states ``(B, nx)`` (see
    ``Plant.configuration`` for the robot's configuration), per-trial status
    (:data:`~ilc_steering.core.integrate.OK` or ``LEFT_CHART``), and optionally the times
    ``(S,)`` [s] and states ``(B, S, nx)`` at every step."""

    final: Array
    status: npt.NDArray[np.int64]
    times: Array | None = None
    states: Array | None = None


def simulate(
    plant: Plant | PlantBatch | Sequence[Plant],
    profile: InputProfile,
    x0: Array,
    c: Array,
    max_step: float = DEFAULT_MAX_STEP,
    record: bool = False,
    parallel: bool = False,
) -> Trials:
    """Run a batch of trials of ``plant`` from states ``x0`` ``(B, nx)`` with coefficients ``c``
    ``(B, 1 + q)``, in steps of at most ``max_step`` [s]; ``record`` keeps every step's state.

    ``plant`` may be a :class:`~ilc_steering.core.plants.PlantBatch` or a sequence of ``B``
    plants of one kind, a plant per trial (different true parameters, say): the batch is still
    one call of the compiled kernel."""
    spans = np.asarray(profile.spans, dtype=np.float64)
    steps = steps_per_span(spans, max_step)
    v1, v2 = profile.polynomials(c)
    if isinstance(plant, Sequence):
        plant = PlantBatch(plant)
    field, params = plant.kernel()
    final, status, states = integrate(field, params, x0, spans, steps, v1, v2, record=record, parallel=parallel)
    if not record:
        return Trials(final, status)
    starts = profile.breakpoints[:-1]
    times = np.concatenate([[0.0]] + [t0 + np.arange(1, k + 1) * d / k for t0, d, k in zip(starts, spans, steps)])
    return Trials(final, status, times, states)
