"""The lab robot's wheel encoder between pulses, in closed form: the driving wheel's rotation from the
last pulse and the next pulse's time, so a step of :mod:`~ilc_steering.core.robots.car_lab` splits at
each pulse without searching for it with Runge-Kutta substeps.

Between pulses the controller's estimate is fixed, so the wheel's commanded speed is ``k v1(t)`` with
``k = 1 / (rho cos(theta_hat))`` (eq. 4), a polynomial in the piece's local time, and a first-order
drive servo's response to it is that polynomial's particular solution plus a decaying exponential.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ilc_steering.core.robots.car_lab_layout import PER_SPEED_LAG, PSI, PULSES, SPEED_LAG, U1
from ilc_steering.core.stepper import MAX_ITERATIONS, poly

__all__ = ["lab_pulse", "lab_wheel_speed"]


@njit(cache=True, inline="always")
def lab_wheel_speed(params, x, v1c, coef, t):  # type: ignore[no-untyped-def]
    """Between pulses (the estimate fixed) the driving wheel's speed follows ``k v1(t)``, ``k = 1 /
    (rho cos(theta_hat))`` (eq. 4), through the speed servo: into ``coef[0]`` the polynomial ``q`` its
    speed tends to (``q' + q / lag = k v1 / lag``: ``q = k sum_m (-lag)^m v1^(m)``; ``k v1`` without a
    lag), into ``coef[1]`` its integral from 0 (in local time), into ``coef[2, :2]`` both at ``t``."""
    lag, k = params[SPEED_LAG], params[U1]  # 1 / (rho cos(theta_hat)), from _lab_constants
    degree = v1c.shape[0] - 1
    coef[0, degree + 1] = 0.0  # q is of v1's degree; the row is one longer, for its integral
    coef[1, 0] = 0.0
    for i in range(degree + 1):
        acc, weight = 0.0, 1.0  # weight: (-lag)^m (i + m)! / i!
        for m in range(degree - i + 1):
            acc += weight * v1c[i + m]
            weight *= -lag * (i + m + 1)
        coef[0, i] = k * acc
        coef[1, i + 1] = k * acc / (i + 1)
    coef[2, 0], coef[2, 1] = poly(coef[1], t), poly(coef[0], t)


@njit(cache=True, inline="always")
def _lab_turn(params, x, coef, t, s):  # type: ignore[no-untyped-def]
    """The wheel's rotation [rad] over ``s`` [s] from local time ``t`` and its speed [rad/s] then,
    in closed form between pulses (:func:`lab_wheel_speed`; ``coef[2, :2]`` holds ``Q(t)`` and
    ``q(t)``): ``omega = q + (omega_0 - q(t)) e^(-s / lag)``."""
    q, big_q = coef[0], coef[1]
    rotation = poly(big_q, t + s) - coef[2, 0]
    if params[SPEED_LAG] <= 0:
        return rotation, poly(q, t + s)
    gap, decay = x[5] - coef[2, 1], np.expm1(-s * params[PER_SPEED_LAG])  # e^(-s / lag) - 1
    return rotation - gap * params[SPEED_LAG] * decay, poly(q, t + s) + gap * (1.0 + decay)


@njit(cache=True, inline="always")
def lab_pulse(params, x, coef, t, span):  # type: ignore[no-untyped-def]
    """The encoder pulse within ``span`` [s] of local time ``t``: ``(3, s)`` forward, ``(4, s)`` backward,
    or ``(-1, span)``; Newton's method, bracketed, on the closed-form rotation (:func:`_lab_turn`)."""
    pitch, psi = 2.0 * np.pi / params[PULSES], x[PSI]
    end = psi + _lab_turn(params, x, coef, t, span)[0]
    if psi <= pitch < end:
        which, sign, level = 3, 1.0, pitch
    elif psi >= 0.0 > end:
        which, sign, level = 4, -1.0, 0.0
    else:
        return -1, span
    lo, hi = 0.0, span
    g_lo, g_hi = sign * (psi - level), sign * (end - level)
    s = span * -g_lo / (g_hi - g_lo)
    for _ in range(MAX_ITERATIONS):
        rotation, speed = _lab_turn(params, x, coef, t, s)
        g = sign * (psi + rotation - level)
        if g > 0:
            hi = s
        else:
            lo = s
        nxt = s - g / (sign * speed) if speed * sign > 0 else 0.5 * (lo + hi)
        if not (lo <= nxt <= hi):
            nxt = 0.5 * (lo + hi)
        # Newton's next error is about K times the square of this correction (K = |g''| / 2|g'|, at
        # most a few hundred per second): below 1e-7 of a step's span, under the rounding of the time.
        if abs(nxt - s) <= 1e-7 * span or g == 0.0:
            return which, nxt
        s = nxt
    return which, hi
