"""Reference trials with scipy's adaptive ``solve_ivp``: slow and tight, for tests and benchmarks.

Each piece of the input profile is integrated separately (the inputs jump between pieces), and
with a steering limit the integration restarts at every crossing of ``|phi_c| = limit``, where
the vector field has a kink (see :mod:`ilc_steering.envs.integrate`).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import numpy.typing as npt
from scipy.integrate import solve_ivp

from ilc_steering.envs.car import car_velocity, chained_inputs
from ilc_steering.envs.scenario import Scenario

__all__ = ["car_field", "car_trial", "reference_trial"]

Array = npt.NDArray[np.float64]
Field = Callable[[float, Array], Array]


def reference_trial(field: Field, x0: Array, breakpoints: Array, limit: float = np.inf, rtol: float = 1e-12) -> Array:
    """The state at ``breakpoints[-1]`` of ``dx/dt = field(t, x)`` from ``x0``, by DOP853 at
    ``rtol`` (= atol), restarted at the breakpoints and at every ``|x[3]| = limit``."""

    def crossing(t: float, x: Array) -> float:
        return abs(x[3]) - limit

    crossing.terminal = True  # type: ignore[attr-defined]
    x = np.array(x0, dtype=np.float64)
    for t, t1 in zip(breakpoints[:-1], breakpoints[1:]):
        while t < t1:
            # Off an event by a hair, so the restarted solver does not stop on it again.
            events = crossing if np.isfinite(limit) and abs(abs(x[3]) - limit) > 1e-13 else None
            sol = solve_ivp(field, (t, t1), x, method="DOP853", rtol=rtol, atol=rtol, events=events)
            x, t = sol.y[:, -1], sol.t[-1]
            if sol.status == 1 and t < t1:
                nudge = min(1e-12, t1 - t)
                x, t = x + nudge * np.asarray(field(t, x)), t + nudge
    return x


def car_field(scenario: Scenario, c: Array) -> Field:
    """The closed-loop car of a car scenario under coefficients ``c``, on the library's formulas."""
    cfg = scenario.config.plant
    if cfg.model != "car":
        raise ValueError(f"car_field needs a car scenario, got plant.model = {cfg.model!r}")
    limit = np.inf if cfg.steering_limit is None else cfg.steering_limit

    def field(t: float, q: Array) -> Array:
        v1, v2 = scenario.profile.evaluate(c, np.array(t))
        phi = min(max(q[3], -limit), limit)
        u1, u2 = chained_inputs(q[2], phi, float(v1), float(v2), cfg.wheelbase, cfg.wheel_radius)
        dx, dy, dtheta, _ = car_velocity(q[2], phi, u1, u2, cfg.true_wheelbase, cfg.true_wheel_radius)
        return np.array([dx, dy, dtheta, u2])

    return field


def car_trial(scenario: Scenario, c: Array, rtol: float = 1e-12) -> Array:
    """The final plant state (task frame) of one trial of a car scenario by :func:`reference_trial`."""
    limit = scenario.config.plant.steering_limit
    return reference_trial(car_field(scenario, c), scenario.x_start, scenario.profile.breakpoints,
                           np.inf if limit is None else limit, rtol)
