"""The car's compiled field in ``(x, y, theta, phi)`` (the kernel :mod:`ilc_steering.core.tangent`
replaced, kept as :data:`ANGLE_KERNEL` for ``benchmarks/throughput.py``), and :func:`car_kernel`,
which picks a car plant's kernel (the batched one, or section 5's lab robot's for a servo) and
builds its parameter row.

Steering limit: the steering servo integrates the commanded rate ``u2`` into a commanded angle
``phi_c`` (the fourth state), and the wheel turns to ``phi = clip(phi_c, -steering_limit,
steering_limit)``: at the stop the wheel rests while the command winds on, and it leaves the stop
when the command comes back inside. The controller measures the wheel angle ``phi``. This reading
of the paper's 45-degree case comes close to its seven iterations (eight to 0.5 mm); a stop that
discards the command learns far more slowly. The kink of the field where ``|phi_c|`` crosses the
limit is located inside the step (:func:`~ilc_steering.core.stepper.step_with_stop`).

Servo perturbations (a misaligned wheel and first-order steering and drive servos) run on the lab
robot's kernel, :mod:`ilc_steering.core.robots.car_lab`, with its play and encoders off (one
compiled servo car; tested against ``solve_ivp`` in ``tests/test_integrate.py``). A lag adds a
stable linear mode of rate ``1 / lag``; the fixed step resolves it when ``lag`` is not much below
the step (the config requires ``lag >= max_step``).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt
from numba import njit

from ilc_steering.core import tangent
from ilc_steering.core.kernels import trial_kernel
from ilc_steering.core.plants import Kernel
from ilc_steering.core.robots.car_lab_lanes import LAB_KERNEL
from ilc_steering.core.robots.car_lab_layout import LAB_LAYOUT
from ilc_steering.core.stepper import CHART_LIMIT, step_with_stop
from ilc_steering.core.tangent import CAR_LAYOUT

__all__ = ["ANGLE_KERNEL", "LAB_KERNEL", "car_kernel", "closed_loop_velocity"]

Array = npt.NDArray[np.float64]

_ELL, _RHO, _TRUE_ELL, _TRUE_RHO, _LIMIT = (CAR_LAYOUT.index(name) for name in CAR_LAYOUT.params)
_PHI_C = CAR_LAYOUT.state.index("phi_c")


@njit(cache=True, inline="always")
def closed_loop_velocity(theta, phi, v1, v2, wheelbase, wheel_radius, true_wheelbase, true_wheel_radius):  # type: ignore[no-untyped-def]
    """Eq. (3) of a car with the true geometry, driven by eqs. (4)-(5) with the nominal one:
    ``(dx, dy, dtheta, dphi)`` [m/s, m/s, rad/s, rad/s].

    Equals ``car_velocity(theta, phi, *chained_inputs(theta, phi, v1, v2, wheelbase,
    wheel_radius), true_wheelbase, true_wheel_radius)`` of :mod:`ilc_steering.core.robots.car`
    (tested) with each sine and cosine evaluated once: this is the integrator's inner loop.
    """
    s, c = np.sin(theta), np.cos(theta)
    s_phi, c_phi = np.sin(phi), np.cos(phi)
    speed = true_wheel_radius / wheel_radius * v1 / c  # true rho times the commanded u1
    dphi = -3.0 / wheelbase * s / (c * c) * s_phi * s_phi * v1 + wheelbase * c * c * c * c_phi * c_phi * v2
    return c * speed, s * speed, s_phi / c_phi * speed / true_wheelbase, dphi


@njit(cache=True, inline="always")
def _car_field(params, x, v1, v2, out):  # type: ignore[no-untyped-def]
    p = params
    phi = min(max(x[3], -p[_LIMIT]), p[_LIMIT])
    ell, rho, true_ell, true_rho = p[_ELL], p[_RHO], p[_TRUE_ELL], p[_TRUE_RHO]
    out[0], out[1], out[2], out[3] = closed_loop_velocity(x[2], phi, v1, v2, ell, rho, true_ell, true_rho)


@njit(cache=True, inline="always")
def _limit_step(rhs, n, params, x, tau, h, v1c, v2c, out, work, probe):  # type: ignore[no-untyped-def]
    step_with_stop(rhs, n, params, x, tau, h, v1c, v2c, out, work, probe, _PHI_C, params[_LIMIT])


@njit(cache=True, inline="always")
def _car_chart(params, x):  # type: ignore[no-untyped-def]
    return abs(x[2]) < CHART_LIMIT and min(abs(x[3]), params[_LIMIT]) < CHART_LIMIT


ANGLE_KERNEL = trial_kernel("car (angles)", CAR_LAYOUT, __name__, _car_field, _car_chart, _limit_step)
"""The car without servo perturbations in ``(x, y, theta, phi_c)``: the kernel the batched one replaced."""


def car_kernel(plant: Any) -> tuple[Kernel, Array]:
    """The kernel of a :class:`~ilc_steering.core.robots.car.CarPlant` and its parameter row."""
    limit = np.inf if plant.steering_limit is None else plant.steering_limit
    nominal, true = plant.nominal, plant.true
    values = dict(
        wheelbase=nominal.wheelbase,
        wheel_radius=nominal.wheel_radius,
        true_wheelbase=true.wheelbase,
        true_wheel_radius=true.wheel_radius,
        steering_limit=limit,
    )
    servo = dict(steering_offset=plant.steering_offset, steering_lag=plant.steering_lag, speed_lag=plant.speed_lag)
    if plant.lab or plant.servo:
        lab = dict(steering_backlash=plant.steering_backlash, encoder_pulses=float(plant.encoder_pulses))
        return LAB_KERNEL, LAB_LAYOUT.row(**values, **servo, **lab)
    return tangent.KERNEL, CAR_LAYOUT.row(**values)
