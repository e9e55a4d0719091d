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

from ilc_steering.errors import ParameterError

__all__ = [
    "DURATION_RANGE",
    "FACTOR_RANGE",
    "LENGTH_RANGE",
    "MAX_JITTER",
    "MAX_NOISE",
    "MAX_START_ERROR",
    "check_factors",
    "check_gains",
    "check_jitter",
    "check_noise",
    "renamed",
    "require",
    "require_length",
    "require_positive",
]

MAX_NOISE = 1e3
"""The largest measurement noise sigma [m or rad]."""
MAX_JITTER = 0.5
"""The largest ``parameter_jitter``, a relative sigma [-]."""
LENGTH_RANGE = (1e-3, 1e3)
"""[m] every length of a robot's geometry (wheelbase, wheel radius, axle width, hitch), nominal or
true: a millimetre to a kilometre. Outside it every trial leaves the chart or the float arithmetic
of eqs. 4-5 loses the geometry (``docs/trust.md``)."""
DURATION_RANGE = (1e-3, 1e4)
"""[s] the duration of one piece of an input profile (eq. 15's ``Delta_i``)."""
FACTOR_RANGE = (1e-3, 1e3)
"""[-] a true parameter over its nominal value (a robustness map's axis, a vector env's
``true_factors``, ``parameter_jitter``'s draw, a model family's ratio)."""
MAX_START_ERROR = 1.0
"""The largest ``start_error`` sigma [m or rad]: a homing error, not a different task."""


def require(ok: bool, name: str, problem: str) -> None:
    """Raise :class:`ParameterError` ``(name, problem)`` unless ``ok``."""
    if not ok:
        raise ParameterError(name, problem)


def require_positive(name: str, value: float, unit: str) -> None:
    """``value`` must be finite and > 0 (``unit`` for the message, e.g. ``"m"``)."""
    require(isfinite(value) and value > 0, name, f"must be finite and > 0 {unit}, got {value}".rstrip())


def require_length(name: str, value: float) -> None:
    """``value`` [m] a length of a robot, within :data:`LENGTH_RANGE`; the message shows the value given."""
    low, high = LENGTH_RANGE
    ok = isinstance(value, (int, float)) and isfinite(value) and low <= value <= high
    require(ok, name, f"must be a length in [{low:g}, {high:g}] m, got {value!r:.40}")


def check_factors(factors: Sequence[float] | npt.NDArray[np.float64], names: Sequence[str]) -> list[float]:
    """``factors`` (one per name of ``names``) as floats, each within :data:`FACTOR_RANGE`;
    :class:`ParameterError` naming the factor and showing the value given (never a product of it)."""
    values = np.asarray(factors, dtype=np.float64).reshape(-1)
    require(values.size == len(names), "true_factors", f"needs {len(names)} values ({list(names)}), got {values.size}")
    low, high = FACTOR_RANGE
    for name, value in zip(names, values.tolist()):
        require(
            isfinite(value) and low <= value <= high, name, f"must be a ratio in [{low:g}, {high:g}], got {value!r}"
        )
    return [float(v) for v in values]


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
    of ``size`` standard deviations in ``[0, MAX_NOISE]`` (``[0, MAX_START_ERROR]`` for a
    ``start_error``), or ``None`` when every one is 0."""
    largest = MAX_START_ERROR if name.endswith("start_error") else MAX_NOISE
    try:
        raw = np.asarray(sigma)
        if raw.dtype.kind not in "iuf":
            raise TypeError
        values = np.broadcast_to(raw.astype(np.float64), (size,)).copy()
    except (TypeError, ValueError):
        problem = f"needs one number or {size} numbers (one per coordinate), got {sigma!r:.80}"
        raise ParameterError(name, problem) from None
    require(
        bool(np.all(np.isfinite(values)) and np.all(values >= 0) and np.all(values <= largest)),
        name,
        f"each sigma must be finite and in [0, {largest:g}], got {values.tolist()}",
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
