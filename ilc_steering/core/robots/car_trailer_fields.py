"""The car towing a trailer, compiled: its kinematics (plain arithmetic, compiled as written, so the
derivation lives in one place) and its two kernels, with :mod:`ilc_steering.core.robots.car_trailer`'s
notation.

:data:`KERNEL` (with a steering limit) integrates the angle form ``(x1, y1, theta1, phi_c, delta)``
trial by trial, its stop located inside each step (as the car's,
:func:`~ilc_steering.core.stepper.step_with_stop`). :data:`LANES_KERNEL` (without one) integrates
across trials in blocks of lanes, in tangent coordinates (below).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numba import njit

from ilc_steering.core.kernels import lane_kernel, trial_kernel
from ilc_steering.core.plants import KernelLayout
from ilc_steering.core.stepper import CHART_LIMIT, step_with_stop

__all__ = ["KERNEL", "LANES_KERNEL", "LAYOUT", "trailer_inputs", "trailer_velocity"]


def trailer_velocity(
    theta1: Any, phi: Any, delta: Any, u1: Any, u2: Any, wheelbase: float, wheel_radius: float, hitch_length: float
) -> tuple[Any, Any, Any, Any, Any]:
    """``(dx1, dy1, dtheta1, dphi, ddelta)`` of the car and trailer under inputs ``u1``, ``u2`` [rad/s]."""
    v = wheel_radius * u1
    ahead = v * np.cos(delta)
    turn = v * np.sin(delta) / hitch_length
    return ahead * np.cos(theta1), ahead * np.sin(theta1), turn, u2, v * np.tan(phi) / wheelbase - turn


def trailer_inputs(
    theta1: Any, phi: Any, delta: Any, v1: Any, v2: Any, wheelbase: float, wheel_radius: float, hitch_length: float
) -> tuple[Any, Any]:
    r"""The car-with-trailer's inputs ``(u1, u2)`` that realise the chained inputs ``(v1, v2)``:
    ``u = beta(q) v``, its equivalent of the car's eqs. 4-5 (after Sørdalen 1993; the derivation is
    :mod:`ilc_steering.core.robots.car_trailer`'s docstring).

    What the towing car's own program computes from its state at each instant of a trial, to steer
    the trailer by the chained inputs the trial sends (``docs/your_robot.md``, ``docs/modelling.md``):

    .. math::

        u_1 = \frac{v_1}{\rho \cos\delta \cos\theta_1}, \qquad u_2 = \frac{v_2 - a(q) v_1}{b(q)},

    with :math:`a` and :math:`b = \partial z_2 / \partial\phi` of that derivation. Driven so, the
    car and trailer with this very geometry move their chained coordinates ``z = alpha(q)``
    (:meth:`~ilc_steering.core.robots.car_trailer.TrailerModel.to_chained`) by eq. 1 with ``n = 5``.
    ``TrailerModel.inputs(q, v1, v2)`` is this function at ``q``'s angles. Plain arithmetic and
    numpy ufuncs, so that the compiled simulator compiles this very function.

    Parameters
    ----------
    theta1, phi, delta
        The trailer's heading, the car's steering angle and the hitch angle ``theta0 - theta1``
        [rad] in the task frame: scalars or arrays of one shape, within the chart (each below
        ``pi/2`` in magnitude; at its edge the inputs grow without bound; nothing is checked here:
        :func:`~ilc_steering.core.robots.car_trailer.check_trailer_chart` checks a configuration).
    v1, v2
        The chained inputs: ``v1`` [m/s] (the speed of ``z1 = x1``) and ``v2`` [1/(m^2 s)] (that of
        ``z2``), broadcast against the angles.
    wheelbase, wheel_radius, hitch_length
        The car's ``ell`` and ``rho`` and the hitch length ``d`` from its rear axle to the trailer's
        axle [m].

    Returns
    -------
    u1, u2
        The driving wheel's angular velocity and the steering rate [rad/s].
    """
    d = hitch_length
    c, s = np.cos(theta1), np.sin(theta1)
    cd, sd = np.cos(delta), np.sin(delta)
    td = sd / cd
    e = np.tan(phi) / wheelbase - sd / d
    c4 = c * c * c * c
    cd3 = cd * cd * cd
    dz2_dtheta = 3.0 * td * td * (c * c + 5.0 * s * s) / (d * d * c4 * c * c) + 4.0 * e * s / (d * cd3 * c4 * c)
    dz2_ddelta = 6.0 * td * s / (d * d * cd * cd * c4 * c) + (3.0 * e * sd / (cd3 * cd) - 1.0 / (d * cd * cd)) / (
        d * c4
    )
    a = (dz2_dtheta * sd / d + dz2_ddelta * e) / (cd * c)
    c_phi = np.cos(phi)
    u1 = v1 / (wheel_radius * cd * c)
    u2 = (v2 - a * v1) * wheelbase * d * c_phi * c_phi * cd3 * c4
    return u1, u2


LAYOUT = KernelLayout(
    ("x1", "y1", "theta1", "phi_c", "delta"),
    (
        "wheelbase",
        "wheel_radius",
        "true_wheelbase",
        "true_wheel_radius",
        "steering_limit",
        "hitch_length",
        "true_hitch_length",
    ),
)
_ELL, _RHO, _TRUE_ELL, _TRUE_RHO, _LIMIT, _D, _TRUE_D = (LAYOUT.index(name) for name in LAYOUT.params)
_PHI_C = LAYOUT.state.index("phi_c")
# The transformation and kinematics are compiled from the very functions above (plain arithmetic
# and ufuncs), so the derivation lives in one place.
_inputs = njit(cache=True, inline="always")(trailer_inputs)
_velocity = njit(cache=True, inline="always")(trailer_velocity)


@njit(cache=True, inline="always")
def _field(params, x, v1, v2, out):  # type: ignore[no-untyped-def]
    p = params
    phi = min(max(x[3], -p[_LIMIT]), p[_LIMIT])
    u1, u2 = _inputs(x[2], phi, x[4], v1, v2, p[_ELL], p[_RHO], p[_D])
    out[0], out[1], out[2], out[3], out[4] = _velocity(x[2], phi, x[4], u1, u2, p[_TRUE_ELL], p[_TRUE_RHO], p[_TRUE_D])


@njit(cache=True, inline="always")
def _step(rhs, n, params, x, tau, h, v1c, v2c, out, work, probe):  # type: ignore[no-untyped-def]
    step_with_stop(rhs, n, params, x, tau, h, v1c, v2c, out, work, probe, _PHI_C, params[_LIMIT])


@njit(cache=True, inline="always")
def _chart(params, x):  # type: ignore[no-untyped-def]
    return max(abs(x[2]), min(abs(x[3]), params[_LIMIT]), abs(x[4])) < CHART_LIMIT


KERNEL = trial_kernel("car-trailer", LAYOUT, __name__, _field, _chart, _step)
"""The trailer with a steering limit: the angle form, its stop located in each step."""

# Without a steering limit the closed loop is integrated in (x1, y1, s, w, e) with s = tan(theta1),
# w = tan(phi), e = tan(delta), across trials in blocks of lanes (as the car's batched kernel,
# ilc_steering.core.tangent): cos(theta1) = 1 / sqrt(1 + s^2), cos(delta) = 1 / sqrt(1 + e^2), and
# no other transcendental function, so the step vectorizes. The derivatives are those of the angle
# form: s' = theta1' (1 + s^2), e' = delta' (1 + e^2), and w' = phi' (1 + w^2), in which eq. 5's
# cos^2(phi) of u2 cancels. A stage outside the chart makes the step not finite: in tangent
# coordinates a state can pass through infinity (the hitch angle through pi/2) within one step;
# with numpy's error model a tangent that overflows divides to inf or NaN, which halts the trial,
# where Python's would raise ZeroDivisionError out of compiled code.
_T_CHART = float(np.tan(CHART_LIMIT))


@njit(cache=True, inline="always")
def _lane_field(p, j, x, v1, v2, k):  # type: ignore[no-untyped-def]
    ell, rho, d, true_ell, true_rho, true_d = p[0, j], p[1, j], p[2, j], p[3, j], p[4, j], p[5, j]
    s, w, e = x[2, j], x[3, j], x[4, j]
    r1 = 1.0 + s * s
    c = 1.0 / np.sqrt(r1)
    sn = s * c
    r2 = 1.0 + e * e
    cd = 1.0 / np.sqrt(r2)
    sd = e * cd
    big_e = w / ell - sd / d
    c2 = c * c
    c4 = c2 * c2
    cd2 = cd * cd
    cd3 = cd2 * cd
    dz2_dtheta = 3.0 * e * e * (c2 + 5.0 * sn * sn) / (d * d * c4 * c2) + 4.0 * big_e * sn / (d * cd3 * c4 * c)
    dz2_ddelta = 6.0 * e * sn / (d * d * cd2 * c4 * c) + (3.0 * big_e * sd / (cd3 * cd) - 1.0 / (d * cd2)) / (d * c4)
    a = (dz2_dtheta * sd / d + dz2_ddelta * big_e) / (cd * c)
    v = true_rho * v1 / (rho * cd * c)
    ahead = v * cd
    turn = v * sd / true_d
    k[0, j] = ahead * c
    k[1, j] = ahead * sn
    k[2, j] = turn * r1
    k[3, j] = (v2 - a * v1) * ell * d * cd3 * c4
    k[4, j] = (v * w / true_ell - turn) * r2
    if max(abs(s), abs(w), abs(e)) >= _T_CHART:  # a stage past the chart: tan(delta) can blow up within
        k[0, j] = np.nan  # a step and come back; the step is then not finite, and the trial halts


@njit(cache=True, inline="always")
def _load(row, q, p, x, j):  # type: ignore[no-untyped-def]
    p[0, j], p[1, j], p[2, j] = row[_ELL], row[_RHO], row[_D]
    p[3, j], p[4, j], p[5, j] = row[_TRUE_ELL], row[_TRUE_RHO], row[_TRUE_D]
    x[0, j], x[1, j] = q[0], q[1]
    x[2, j], x[3, j], x[4, j] = np.tan(q[2]), np.tan(q[3]), np.tan(q[4])


@njit(cache=True, inline="always")
def _lane_chart(x, j):  # type: ignore[no-untyped-def]
    inside = max(abs(x[2, j]), abs(x[3, j]), abs(x[4, j])) < _T_CHART
    return np.isfinite(x[0, j]) and np.isfinite(x[1, j]) and inside


@njit(cache=True, inline="always")
def _store(x, j, dst):  # type: ignore[no-untyped-def]
    """Lane ``j`` as ``(x1, y1, theta1, phi, delta)`` into ``dst``."""
    dst[0], dst[1] = x[0, j], x[1, j]
    dst[2], dst[3], dst[4] = np.arctan(x[2, j]), np.arctan(x[3, j]), np.arctan(x[4, j])


LANES_KERNEL = lane_kernel(
    "batched car-trailer", LAYOUT, __name__, (_load, _lane_field, _lane_chart, _store), (5, 6), error_model="numpy"
)
"""The trailer without a steering limit, in tangent coordinates, vectorized across trials."""
