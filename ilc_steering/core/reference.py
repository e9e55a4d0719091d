"""Reference trials with scipy's adaptive ``solve_ivp``: slow and tight, for tests and benchmarks.

Each span of the input profile is integrated separately (the inputs jump between spans), and
with a steering limit the integration restarts at every crossing of ``|phi_c| = limit``, where
the vector field has a kink (see :mod:`ilc_steering.core.integrate`). The car's field is built
from eqs. 3-5 as written in :mod:`ilc_steering.core.car`, not from the kernel's fused form.
"""

from __future__ import annotations

from collections.abc import Callable
from itertools import pairwise

import numpy as np
import numpy.typing as npt
from scipy.integrate import solve_ivp

from ilc_steering.core.car import car_velocity, chained_inputs
from ilc_steering.core.plants import CHART_MARGIN, CarPlant
from ilc_steering.core.profiles import InputProfile

__all__ = ["car_field", "car_trial", "reference_trial"]

Array = npt.NDArray[np.float64]
Field = Callable[[float, Array], Array]


def reference_trial(
    field: Field,
    x0: Array,
    breakpoints: Array,
    limit: float = np.inf,
    rtol: float = 1e-12,
    chart: Callable[[float, Array], float] | None = None,
) -> Array:
    """The state at ``breakpoints[-1]`` of ``dx/dt = field(t, x)`` from ``x0``, by DOP853 at
    ``rtol`` (= atol), restarted at the breakpoints and at every ``|x[3]| = limit``; the trial
    halts where ``chart(t, x)`` falls to 0 (the robot leaves the chart), if given."""

    def crossing(t: float, x: Array) -> float:
        return float(abs(x[3]) - limit)

    crossing.terminal = True  # type: ignore[attr-defined]
    if chart is not None:
        chart.terminal = True  # type: ignore[attr-defined]
    x = np.array(x0, dtype=np.float64)
    for t, t1 in pairwise(breakpoints):
        while t < t1:
            # Off an event by a hair, so the restarted solver does not stop on it again.
            events = [crossing] if np.isfinite(limit) and abs(abs(x[3]) - limit) > 1e-13 else []
            sol = solve_ivp(
                field, (t, t1), x, method="DOP853", rtol=rtol, atol=rtol, events=events + ([chart] if chart else [])
            )
            x, t = sol.y[:, -1], sol.t[-1]
            if chart is not None and sol.status == 1 and sol.t_events[-1].size:
                return np.asarray(x, dtype=np.float64)
            if sol.status == 1 and t < t1:
                nudge = min(1e-12, t1 - t)
                x, t = x + nudge * np.asarray(field(t, x)), t + nudge
    return x


def car_field(plant: CarPlant, profile: InputProfile, c: Array) -> Field:
    """The closed-loop car ``plant`` under coefficients ``c``: eqs. 4-5 with its nominal geometry
    from the measured wheel angle (the clipped command, or the lagging wheel), eq. 3 with its true
    geometry, misaligned wheel and lagging drive, the servo integrating ``u2``."""
    limit = np.inf if plant.steering_limit is None else plant.steering_limit
    nominal, true = plant.nominal, plant.true

    offset, steering_lag, speed_lag = plant.steering_offset, plant.steering_lag, plant.speed_lag

    def field(t: float, q: Array) -> Array:
        v1, v2 = profile.evaluate(c, np.array(t))
        commanded = min(max(q[3], -limit), limit)
        phi = q[4] if steering_lag else commanded
        u1, u2 = chained_inputs(q[2], phi, float(v1), float(v2), nominal.wheelbase, nominal.wheel_radius)
        omega = q[5] if speed_lag else u1
        dx, dy, dtheta, _ = car_velocity(q[2], phi + offset, omega, u2, true.wheelbase, true.wheel_radius)
        if not plant.servo:
            return np.array([dx, dy, dtheta, u2])
        dphi_w = (commanded - q[4]) / steering_lag if steering_lag else 0.0
        domega = (u1 - q[5]) / speed_lag if speed_lag else 0.0
        return np.array([dx, dy, dtheta, u2, dphi_w, domega])

    return field


def car_trial(plant: CarPlant, profile: InputProfile, x0: Array, c: Array, rtol: float = 1e-12) -> Array:
    """The final state of one trial of ``plant`` from ``x0`` (task frame) by :func:`reference_trial`."""
    limit = np.inf if plant.steering_limit is None else plant.steering_limit

    def chart(t: float, x: Array) -> float:
        return float(np.pi / 2 - CHART_MARGIN - abs(x[2]))

    return reference_trial(car_field(plant, profile, c), x0, profile.breakpoints, limit, rtol, chart)
