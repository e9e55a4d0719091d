"""Section 5's lab robot (MARIO): the car with servo perturbations
(:mod:`~ilc_steering.core.robots.car_fields`) plus a steering linkage with play and a controller that
dead-reckons its heading from quantized wheel encoders: its compiled field, events and Runge-Kutta
step; a step split at the events is :mod:`~ilc_steering.core.robots.car_lab_step`, the kernel that runs
trials in lanes :mod:`~ilc_steering.core.robots.car_lab_lanes` (:data:`LAB_KERNEL` there).

Twelve states ``(x, y, theta, phi_c, phi_s, omega, A, psi, x_hat, y_hat, theta_hat,
k)``: the servo's output ``phi_s`` (the lag state, or the clipped command), the play's anchor
``A``, the wheel's rotation ``psi`` [rad] since the last pulse (within one pitch, so a pulse is
located to rounding; the total is ``2 pi k / N + psi``), the controller's estimate and its pulse
count ``k``. The wheel turns to ``phi_w = clip(A, phi_s - b/2, phi_s + b/2)``: on a stretch where
``phi_s`` is monotone, that is the play operator exactly, given ``A`` = the wheel angle at its
start; ``A`` is refreshed at every (sub)step. Eqs. 4-5 use ``theta_hat`` and ``phi_s``. Events,
each located inside the step and the step split there: the steering limit; the play engaging;
``phi_s`` turning back (its rate changes sign, so the clip formula restarts), these three by
regula falsi on substeps (:func:`~ilc_steering.core.stepper.locate`); and each encoder pulse,
``psi`` leaving ``[0, 2 pi / N]``, which jumps the estimate by the nominal odometry of an arc of
``2 pi rho_nominal / N``, found in closed form (between pulses ``psi`` is the integral of a linear
servo's response to a polynomial: :mod:`~ilc_steering.core.robots.car_lab_pulses`), so a step
with a pulse costs two Runge-Kutta steps, not seven (``benchmarks/robots.py``). The layout's
positions are :mod:`~ilc_steering.core.robots.car_lab_layout`'s.

What a step costs (``benchmarks/robots.py``, docs/speed.md): the field runs in ``tan(theta)`` with
``cos(theta)`` and ``tan(phi_s)`` carried as states (without a lag ``tan(phi_c)``: :func:`lab_gate`),
so a stage evaluates no trigonometric function, no square root and two divisions; what is fixed
between events is set once per substep (:func:`lab_constants`) or trial, and a Runge-Kutta step runs
on the nine entries that move (:func:`lab_rk`). Each change is within 1e-13 of the kernel before it
on ``tests/lab_reference.json``, the carried ``tan(phi_c)`` within 2.5e-11 on 512 packaged trials.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ilc_steering.core import dop853
from ilc_steering.core.robots.car_lab_layout import (
    ANCHOR,
    ANCHOR_AT,
    BACKLASH,
    COS,
    ELL,
    GATE,
    HAT,
    HAT_AT,
    LAB_LAYOUT,
    LIMIT,
    MOVING,
    OFFSET,
    PER_ELL,
    PER_SPEED_LAG,
    PER_STEERING_LAG,
    PSI,
    PULSES,
    RHO,
    SERVO_PARAMS,
    SPEED_LAG,
    STEERING_LAG,
    TAN_HI,
    TAN_LIMIT,
    TAN_LO,
    TAN_REST,
    TAN_SERVO,
    TRUE_ELL,
    TRUE_RHO,
    U1,
    U2_V1,
    U2_V2,
)
from ilc_steering.core.stepper import CHART_LIMIT, STAGES, poly

__all__ = [
    "LAB_LAYOUT",
    "SERVO_PARAMS",
    "lab_chart",
    "lab_constants",
    "lab_event",
    "lab_field",
    "lab_gate",
    "lab_jump",
    "lab_rk",
    "lab_servo",
    "lab_servo_rate",
    "lab_trial_constants",
    "lab_wheel",
]


_A = np.ascontiguousarray(dop853.A)  # the tableau, as the stepper holds it
_B = np.ascontiguousarray(dop853.B)
_C = np.ascontiguousarray(dop853.C)


@njit(cache=True, inline="always")
def lab_servo(params, x):  # type: ignore[no-untyped-def]
    """The steering servo's output ``phi_s``: the lag state, or the clipped command."""
    if params[STEERING_LAG] > 0:
        return x[4]
    return min(max(x[3], -params[LIMIT]), params[LIMIT])


@njit(cache=True, inline="always")
def lab_wheel(params, anchor, phi_s):  # type: ignore[no-untyped-def]
    """The wheel angle behind the linkage's play ``b``: ``clip(A, phi_s - b/2, phi_s + b/2)``."""
    half = 0.5 * params[BACKLASH]
    return min(max(anchor, phi_s - half), phi_s + half)


@njit(cache=True, inline="always")
def lab_trial_constants(params):  # type: ignore[no-untyped-def]
    """Into ``params`` past the row: what is fixed over a trial (:data:`EXTRA`)."""
    offset, half, limit, lag = params[OFFSET], 0.5 * params[BACKLASH], params[LIMIT], params[STEERING_LAG]
    params[TAN_LO], params[TAN_HI] = np.tan(offset - half), np.tan(offset + half)
    params[PER_ELL], params[PER_STEERING_LAG] = 1.0 / params[TRUE_ELL], (1.0 / lag if lag > 0 else 0.0)
    params[PER_SPEED_LAG] = 1.0 / params[SPEED_LAG] if params[SPEED_LAG] > 0 else 0.0
    gate = 0.5 * (limit + 0.5 * np.pi)  # halfway from the stop to the chart's edge
    params[TAN_LIMIT], params[GATE] = (np.tan(limit), gate) if limit < 0.5 * np.pi else (np.inf, np.inf)
    params[HAT_AT] = params[ANCHOR_AT] = np.nan  # none yet: lab_constants sets what depends on them


@njit(cache=True, inline="always")
def lab_constants(params, x):  # type: ignore[no-untyped-def]
    """Into ``params`` past the row, fixed over a substep from ``x``: eq. 4's gain and eq. 5's at the
    estimate (with no encoder, the nominal geometry's; :func:`lab_inputs`), ``tan(A + offset)``;
    each recomputed only when what it depends on moved (the estimate jumps at a pulse only)."""
    ell, theta_hat, anchor = params[ELL], x[HAT + 2], x[ANCHOR]
    if theta_hat != params[HAT_AT]:
        params[HAT_AT] = theta_hat
        if params[PULSES] > 0:
            s, c = np.sin(theta_hat), np.cos(theta_hat)
            params[U1], params[U2_V1] = 1.0 / (params[RHO] * c), -3.0 / ell * s / (c * c)
            params[U2_V2] = ell * c * c * c
        else:
            params[U1], params[U2_V1], params[U2_V2] = 1.0 / params[RHO], -3.0 / ell, ell
    if anchor != params[ANCHOR_AT]:
        params[ANCHOR_AT] = anchor
        params[TAN_REST] = np.tan(anchor + params[OFFSET])


@njit(cache=True, inline="always")
def lab_gate(params, x):  # type: ignore[no-untyped-def]
    """The carried ``tan(phi_s)`` at a step's start; without a lag ``tan(phi_c)``, moving past the stop
    (a stage of a step resting there may look inside) up to a gate halfway to ``pi/2``."""
    if params[STEERING_LAG] > 0:
        return np.tan(x[4])
    return np.tan(min(max(x[3], -params[GATE]), params[GATE]))


@njit(cache=True, inline="always")
def lab_inputs(params, x, v1, v2):  # type: ignore[no-untyped-def]
    """Eqs. 4-5 with the nominal geometry at the controller's estimate (:func:`lab_constants`; with
    no encoder, at the true heading, ``x[2] = tan(theta)``): ``(u1, u2, tan(phi_s))``."""
    inside = params[STEERING_LAG] > 0 or abs(x[3]) < params[LIMIT]
    t = x[TAN_SERVO] if inside else np.copysign(params[TAN_LIMIT], x[3])  # at the stop: its own tangent
    cos2 = 1.0 / (1.0 + t * t)  # cos(phi_s)^2, and sin(phi_s)^2 = t^2 cos2
    if params[PULSES] > 0:
        return v1 * params[U1], cos2 * (params[U2_V1] * t * t * v1 + params[U2_V2] * v2), t
    secant = np.sqrt(1.0 + x[2] * x[2])  # 1 / cos(theta), no division by a cosine that may be 0
    u2 = cos2 * (params[U2_V1] * x[2] * secant * t * t * v1 + params[U2_V2] * v2 / (secant * secant * secant))
    return v1 * secant * params[U1], u2, t


@njit(cache=True, inline="always")
def lab_servo_rate(params, x, v1, v2):  # type: ignore[no-untyped-def]
    """``d phi_s / dt``."""
    limit = params[LIMIT]
    if params[STEERING_LAG] > 0:
        return (min(max(x[3], -limit), limit) - x[4]) * params[PER_STEERING_LAG]
    if abs(x[3]) >= limit:
        return 0.0
    return lab_inputs(params, x, v1, v2)[1]


@njit(cache=True, inline="always")
def lab_field(params, x, v1, v2, out):  # type: ignore[no-untyped-def]
    """The lab robot's field with ``x[2] = z = tan(theta)`` (so ``z' = (1 + z^2) theta'``): one tangent
    a stage, ``tan(phi_s)``; the wheel's ``tan(phi_w + offset)`` from it by the addition formula."""
    limit = params[LIMIT]
    u1, u2, t = lab_inputs(params, x, v1, v2)
    phi_s, half, anchor = lab_servo(params, x), 0.5 * params[BACKLASH], x[ANCHOR]
    if anchor < phi_s - half:  # the play engaged, the servo pulling the wheel to its side
        tan_wheel = (t + params[TAN_LO]) / (1.0 - t * params[TAN_LO])
    elif anchor > phi_s + half:
        tan_wheel = (t + params[TAN_HI]) / (1.0 - t * params[TAN_HI])
    else:  # the wheel rests at the anchor
        tan_wheel = params[TAN_REST]
    omega = x[5] if params[SPEED_LAG] > 0 else u1
    speed = params[TRUE_RHO] * omega
    z, c = x[2], x[COS]
    turn = tan_wheel * speed * params[PER_ELL]  # theta'
    out[0] = c * speed
    out[1] = z * c * speed
    out[2] = (1.0 + z * z) * turn
    out[COS] = -z * c * turn
    out[3] = u2
    out[4] = (min(max(x[3], -limit), limit) - x[4]) * params[PER_STEERING_LAG]  # 0 without a lag
    out[5] = (u1 - x[5]) * params[PER_SPEED_LAG]
    out[PSI] = omega
    if params[STEERING_LAG] > 0:  # tan(phi_s)'; without a lag tan(phi_c)' (lab_gate)
        out[TAN_SERVO] = (1.0 + t * t) * out[4]
    else:
        out[TAN_SERVO] = (1.0 + x[TAN_SERVO] * x[TAN_SERVO]) * u2 if abs(x[3]) < params[GATE] else 0.0


@njit(cache=True, inline="always")
def lab_event(j, params, x, tau, v1c, v2c, sides):  # type: ignore[no-untyped-def]
    """Event ``j`` of the lab robot as a value that crosses from <= 0 to > 0 when it fires;
    ``sides`` holds what is fixed over a substep (the side of the limit, the servo's direction)."""
    if j == 0:
        return sides[0] * (abs(x[3]) - params[LIMIT])
    if j == 1 or j == 2:
        if sides[1] == 0:
            return -1.0
        phi_s = lab_servo(params, x)
        if j == 1:
            if sides[2] != 0:  # engaged on the side it moves to: no kink ahead of the next turn
                return -1.0
            return sides[1] * (phi_s - x[ANCHOR]) - 0.5 * params[BACKLASH]
        return -sides[1] * lab_servo_rate(params, x, poly(v1c, tau), poly(v2c, tau))
    if j == 3:
        return x[PSI] - 2.0 * np.pi / params[PULSES]
    return -x[PSI]


@njit(cache=True, inline="always")
def lab_jump(j, params, x):  # type: ignore[no-untyped-def]
    """At pulse ``j`` (3 forward, 4 backward): the estimate moves by the nominal odometry of one
    encoder pitch of wheel travel, at the servo's steering angle."""
    if j < 3:
        return
    sign = 1.0 if j == 3 else -1.0
    ds = sign * 2.0 * np.pi * params[RHO] / params[PULSES]
    dtheta = ds * np.tan(lab_servo(params, x)) / params[ELL]
    x[HAT] += ds * np.cos(x[HAT + 2] + 0.5 * dtheta)
    x[HAT + 1] += ds * np.sin(x[HAT + 2] + 0.5 * dtheta)
    x[HAT + 2] += dtheta
    x[HAT + 3] += sign
    x[PSI] -= sign * 2.0 * np.pi / params[PULSES]


@njit(cache=True, inline="always")
def lab_rk(rhs, params, x, tau, h, v1c, v2c, out, work):  # type: ignore[no-untyped-def]
    """:func:`~ilc_steering.core.stepper.rk_step` on the first :data:`MOVING` entries (the rest carried
    over), the stages combined across entries in rk_step's order (the same sums), past the zeros."""
    tmp = work[STAGES]
    tmp[ANCHOR] = x[ANCHOR]
    for s in range(STAGES):
        for i in range(MOVING):
            tmp[i] = 0.0
        for j in range(s):
            a = _A[s, j]
            if a != 0.0:
                for i in range(MOVING):
                    tmp[i] += a * work[j, i]
        for i in range(MOVING):
            tmp[i] = x[i] + h * tmp[i]
        t = tau + _C[s] * h
        rhs(params, tmp, poly(v1c, t), poly(v2c, t), work[s])
    for i in range(MOVING):
        out[i] = 0.0
    for s in range(STAGES):
        b = _B[s]
        if b != 0.0:
            for i in range(MOVING):
                out[i] += b * work[s, i]
    for i in range(MOVING):
        out[i] = x[i] + h * out[i]
    for i in range(MOVING, x.shape[0]):
        out[i] = x[i]


@njit(cache=True, inline="always")
def lab_chart(params, x):  # type: ignore[no-untyped-def]
    phi_s = lab_servo(params, x)
    wheel = lab_wheel(params, x[6], phi_s) + params[OFFSET]
    return max(abs(x[2]), abs(x[10]), abs(phi_s), abs(wheel)) < CHART_LIMIT
