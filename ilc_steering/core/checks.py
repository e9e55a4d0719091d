"""Range rules of the domain objects, each written once.

The domain classes (car geometry, plants, input profiles, the learning gains) check their own
parameters with these helpers and raise :class:`ParameterError`, which names the parameter.
Config loading builds the same objects and turns a ``ParameterError`` into a ``ConfigError``
naming the file and the YAML key (:mod:`ilc_steering.config`), so no rule is written twice.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from math import isfinite

import numpy as np
import numpy.typing as npt

__all__ = [
    "MAX_JITTER",
    "MAX_NOISE",
    "ParameterError",
    "check_gains",
    "check_jitter",
    "check_noise",
    "renamed",
    "require",
    "require_positive",
]

MAX_NOISE = 1e3
"""The largest measurement noise sigma [m or rad]."""
MAX_JITTER = 0.5
"""The largest ``parameter_jitter``, a relative sigma [-]."""


class ParameterError(ValueError):
    """A parameter out of its range: ``name`` is the parameter, ``problem`` what is wrong with it."""

    def __init__(self, name: str, problem: str) -> None:
        super().__init__(f"{name}: {problem}")
        self.name = name
        self.problem = problem


def require(ok: bool, name: str, problem: str) -> None:
    """Raise :class:`ParameterError` ``(name, problem)`` unless ``ok``."""
    if not ok:
        raise ParameterError(name, problem)


def require_positive(name: str, value: float, unit: str) -> None:
    """``value`` must be finite and > 0 (``unit`` for the message, e.g. ``"m"``)."""
    require(isfinite(value) and value > 0, name, f"must be finite and > 0 {unit}, got {value}".rstrip())


def check_gains(nu_a: float, nu_b: float) -> None:
    """Eqs. (33)-(34), (40): both learning gains must lie in ``(0, 2)``, where ``|1 - nu| < 1``."""
    for name, value in (("nu_a", nu_a), ("nu_b", nu_b)):
        require(isfinite(value) and 0 < value < 2, name, f"must be in (0, 2), got {value}")


def check_jitter(sigma: float) -> float | None:
    """A ``parameter_jitter`` (relative sigma of the true parameters per trial) in ``[0, MAX_JITTER]``,
    or ``None`` when it is 0."""
    number = isinstance(sigma, (int, float)) and not isinstance(sigma, bool)
    require(
        number and isfinite(sigma) and 0 <= sigma <= MAX_JITTER,
        "parameter_jitter",
        f"must be a number in [0, {MAX_JITTER}] (a relative sigma), got {sigma!r:.80}",
    )
    return float(sigma) if sigma > 0 else None


def check_noise(
    sigma: float | Sequence[float], size: int, name: str = "measurement_noise"
) -> npt.NDArray[np.float64] | None:
    """A measurement noise ``sigma`` (one value for every coordinate, or ``size`` values) as an array
    of ``size`` standard deviations in ``[0, MAX_NOISE]``, or ``None`` when every one is 0."""
    try:
        raw = np.asarray(sigma)
        if raw.dtype.kind not in "iuf":
            raise TypeError
        values = np.broadcast_to(raw.astype(np.float64), (size,)).copy()
    except (TypeError, ValueError):
        problem = f"needs one number or {size} numbers (one per coordinate), got {sigma!r:.80}"
        raise ParameterError(name, problem) from None
    require(
        bool(np.all(np.isfinite(values)) and np.all(values >= 0) and np.all(values <= MAX_NOISE)),
        name,
        f"each sigma must be finite and in [0, {MAX_NOISE:g}], got {values.tolist()}",
    )
    return values if np.any(values > 0) else None


@contextmanager
def renamed(names: dict[str, str]) -> Iterator[None]:
    """Re-raise a :class:`ParameterError` of the block under the name ``names`` gives its parameter
    (a true geometry built by the class of the nominal one: ``wheelbase`` is ``true_wheelbase``)."""
    try:
        yield
    except ParameterError as error:
        raise ParameterError(names.get(error.name, error.name), error.problem) from None
