"""The integrator's time grid: equal steps on each span of an input profile, and its cap.

A trial takes ``sum_s ceil(span_s / max_step)`` steps. :data:`MAX_STEPS_PER_TRIAL` bounds that, so
that no config can ask for a trial that runs for hours or a recording that fills the memory (a
recorded car trial at the cap holds 200,000 x 4 float64, 6.4 MB).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import numpy.typing as npt

from ilc_steering.core.checks import require

__all__ = ["DEFAULT_MAX_STEP", "MAX_STEPS_PER_TRIAL", "check_grid", "steps_per_span"]

DEFAULT_MAX_STEP = 1.0 / 32.0
"""[s] the default longest step: within 1e-9 of a tight reference on the paper's tasks."""
MAX_STEPS_PER_TRIAL = 200_000
"""The most integrator steps one trial may take (the paper's 5 s trials take 160)."""


def steps_per_span(spans: Sequence[float] | npt.NDArray[np.float64], max_step: float) -> npt.NDArray[np.int64]:
    """The number of equal steps on each span [s] so that none is longer than ``max_step`` [s]."""
    return np.maximum(1, np.ceil(np.asarray(spans, dtype=np.float64) / max_step - 1e-9)).astype(np.int64)


def check_grid(spans: Sequence[float], max_step: float) -> None:
    """``ParameterError`` on ``max_step`` when a trial over ``spans`` [s] would exceed :data:`MAX_STEPS_PER_TRIAL`."""
    total = float(np.sum(np.ceil(np.asarray(spans, dtype=np.float64) / max_step)))
    require(
        total <= MAX_STEPS_PER_TRIAL,
        "max_step",
        f"{max_step} s over a trial of {sum(spans):.6g} s makes {total:.3g} steps; at most {MAX_STEPS_PER_TRIAL} "
        "are allowed (raise max_step or shorten the pieces)",
    )
