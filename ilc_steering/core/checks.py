"""Range rules of the domain objects, each written once.

The domain classes (car geometry, plants, input profiles, the learning gains) check their own
parameters with these helpers and raise :class:`ParameterError`, which names the parameter.
Config loading builds the same objects and turns a ``ParameterError`` into a ``ConfigError``
naming the file and the YAML key (:mod:`ilc_steering.config`), so no rule is written twice.
"""

from __future__ import annotations

from math import isfinite

__all__ = ["ParameterError", "check_gains", "require", "require_positive"]


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
