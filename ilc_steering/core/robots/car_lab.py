"""Section 5's lab robot (MARIO): the car with servo perturbations
(:mod:`~ilc_steering.core.robots.car_fields`) plus a steering linkage with play and a controller that
dead-reckons its heading from quantized wheel encoders; its compiled kernel, :data:`LAB_KERNEL`.

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
``cos(theta)`` and ``tan(phi_s)`` carried as states (without a lag ``tan(phi_c)``: :func:`_lab_gate`),
so a stage evaluates no trigonometric function, no square root and two divisions; what is fixed
between events is set once per substep (:func:`_lab_constants`) or step, and a Runge-Kutta step runs
on the nine entries that move (:func:`_lab_rk`). Each change is within 1e-13 of the kernel before it
on ``tests/lab_reference.json``, the carried ``tan(phi_c)`` within 2.5e-11 on 512 packaged trials.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
from numba import njit

from ilc_steering.core import dop853
from ilc_steering.core.integrate import checked_batch
from ilc_steering.core.kernels import trial_kernel
from ilc_steering.core.robots.car_lab_layout import (
    ANCHOR,
    ANCHOR_AT,
    BACKLASH,
    COS,
    ELL,
    EXTRA,
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
from ilc_steering.core.robots.car_lab_pulses import lab_pulse, lab_wheel_speed
from ilc_steering.core.stepper import CHART_LIMIT, STAGES, locate, poly

__all__ = ["LAB_KERNEL", "LAB_LAYOUT", "SERVO_PARAMS", "lab_substeps"]

Array = npt.NDArray[np.float64]
Int = npt.NDArray[np.int64]

_MAX_EVENTS = 10_000  # events within one step of the lab robot before it gives up locating them
_LAB_EVENT_TIME = 1e-14  # relative to the step: how closely a lab event is located


_A = np.ascontiguousarray(dop853.A)  # the tableau, as the stepper holds it
_B = np.ascontiguousarray(dop853.B)
_C = np.ascontiguousarray(dop853.C)


@njit(cache=True, inline="always")
def _lab_servo(params, x):  # type: ignore[no-untyped-def]
    """The steering servo's output ``phi_s``: the lag state, or the clipped command."""
    if params[STEERING_LAG] > 0:
        return x[4]
    return min(max(x[3], -params[LIMIT]), params[LIMIT])


@njit(cache=True, inline="always")
def _lab_wheel(params, anchor, phi_s):  # type: ignore[no-untyped-def]
    """The wheel angle behind the linkage's play ``b``: ``clip(A, phi_s - b/2, phi_s + b/2)``."""
    half = 0.5 * params[BACKLASH]
    return min(max(anchor, phi_s - half), phi_s + half)


@njit(cache=True, inline="always")
def _lab_step_constants(params):  # type: ignore[no-untyped-def]
    """Into ``params`` past the row: what is fixed over a step (:data:`EXTRA`)."""
    offset, half, limit, lag = params[OFFSET], 0.5 * params[BACKLASH], params[LIMIT], params[STEERING_LAG]
    params[TAN_LO], params[TAN_HI] = np.tan(offset - half), np.tan(offset + half)
    params[PER_ELL], params[PER_STEERING_LAG] = 1.0 / params[TRUE_ELL], (1.0 / lag if lag > 0 else 0.0)
    params[PER_SPEED_LAG] = 1.0 / params[SPEED_LAG] if params[SPEED_LAG] > 0 else 0.0
    gate = 0.5 * (limit + 0.5 * np.pi)  # halfway from the stop to the chart's edge
    params[TAN_LIMIT], params[GATE] = (np.tan(limit), gate) if limit < 0.5 * np.pi else (np.inf, np.inf)
    params[HAT_AT] = params[ANCHOR_AT] = np.nan  # none yet: _lab_constants sets what depends on them


@njit(cache=True, inline="always")
def _lab_constants(params, x):  # type: ignore[no-untyped-def]
    """Into ``params`` past the row, fixed over a substep from ``x``: eq. 4's gain and eq. 5's at the
    estimate (with no encoder, the nominal geometry's; :func:`_lab_inputs`), ``tan(A + offset)``;
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
def _lab_gate(params, x):  # type: ignore[no-untyped-def]
    """The carried ``tan(phi_s)`` at a step's start; without a lag ``tan(phi_c)``, moving past the stop
    (a stage of a step resting there may look inside) up to a gate halfway to ``pi/2``."""
    if params[STEERING_LAG] > 0:
        return np.tan(x[4])
    return np.tan(min(max(x[3], -params[GATE]), params[GATE]))


@njit(cache=True, inline="always")
def _lab_inputs(params, x, v1, v2):  # type: ignore[no-untyped-def]
    """Eqs. 4-5 with the nominal geometry at the controller's estimate (:func:`_lab_constants`; with
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
def _lab_servo_rate(params, x, v1, v2):  # type: ignore[no-untyped-def]
    """``d phi_s / dt``."""
    limit = params[LIMIT]
    if params[STEERING_LAG] > 0:
        return (min(max(x[3], -limit), limit) - x[4]) * params[PER_STEERING_LAG]
    if abs(x[3]) >= limit:
        return 0.0
    return _lab_inputs(params, x, v1, v2)[1]


@njit(cache=True, inline="always")
def _lab_field(params, x, v1, v2, out):  # type: ignore[no-untyped-def]
    """The lab robot's field with ``x[2] = z = tan(theta)`` (so ``z' = (1 + z^2) theta'``): one tangent
    a stage, ``tan(phi_s)``; the wheel's ``tan(phi_w + offset)`` from it by the addition formula."""
    limit = params[LIMIT]
    u1, u2, t = _lab_inputs(params, x, v1, v2)
    phi_s, half, anchor = _lab_servo(params, x), 0.5 * params[BACKLASH], x[ANCHOR]
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
    if params[STEERING_LAG] > 0:  # tan(phi_s)'; without a lag tan(phi_c)' (_lab_gate)
        out[TAN_SERVO] = (1.0 + t * t) * out[4]
    else:
        out[TAN_SERVO] = (1.0 + x[TAN_SERVO] * x[TAN_SERVO]) * u2 if abs(x[3]) < params[GATE] else 0.0


@njit(cache=True, inline="always")
def _lab_event(j, params, x, tau, v1c, v2c, sides):  # type: ignore[no-untyped-def]
    """Event ``j`` of the lab robot as a value that crosses from <= 0 to > 0 when it fires;
    ``sides`` holds what is fixed over a substep (the side of the limit, the servo's direction)."""
    if j == 0:
        return sides[0] * (abs(x[3]) - params[LIMIT])
    if j == 1 or j == 2:
        if sides[1] == 0:
            return -1.0
        phi_s = _lab_servo(params, x)
        if j == 1:
            if sides[2] != 0:  # engaged on the side it moves to: no kink ahead of the next turn
                return -1.0
            return sides[1] * (phi_s - x[ANCHOR]) - 0.5 * params[BACKLASH]
        return -sides[1] * _lab_servo_rate(params, x, poly(v1c, tau), poly(v2c, tau))
    if j == 3:
        return x[PSI] - 2.0 * np.pi / params[PULSES]
    return -x[PSI]


@njit(cache=True, inline="always")
def _lab_jump(j, params, x):  # type: ignore[no-untyped-def]
    """At pulse ``j`` (3 forward, 4 backward): the estimate moves by the nominal odometry of one
    encoder pitch of wheel travel, at the servo's steering angle."""
    if j < 3:
        return
    sign = 1.0 if j == 3 else -1.0
    ds = sign * 2.0 * np.pi * params[RHO] / params[PULSES]
    dtheta = ds * np.tan(_lab_servo(params, x)) / params[ELL]
    x[HAT] += ds * np.cos(x[HAT + 2] + 0.5 * dtheta)
    x[HAT + 1] += ds * np.sin(x[HAT + 2] + 0.5 * dtheta)
    x[HAT + 2] += dtheta
    x[HAT + 3] += sign
    x[PSI] -= sign * 2.0 * np.pi / params[PULSES]


@njit(cache=True, inline="always")
def _lab_rk(rhs, params, x, tau, h, v1c, v2c, out, work):  # type: ignore[no-untyped-def]
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
def _lab_event_after(rhs, state, s):  # type: ignore[no-untyped-def]
    """Event ``j``'s value after a substep of length ``s`` from ``cur`` at local time ``t``."""
    params, cur, t, v1c, v2c, probe, work, j, sides = state
    sides[3] += 1.0  # the Runge-Kutta steps a step took (_lab_step)
    _lab_rk(rhs, params, cur, t, s, v1c, v2c, probe, work)
    return _lab_event(j, params, probe, t + s, v1c, v2c, sides)


@njit(cache=True, inline="always")
def _lab_step(rhs, n, params, x, tau, h, v1c, v2c, out, work, _probe):  # type: ignore[no-untyped-def]
    """One step from local time ``tau``, split at each event in turn (the module docstring): steering
    events by regula falsi on substeps, encoder pulses in closed form (:func:`lab_pulse`). Returns
    the Runge-Kutta steps it took (:func:`lab_substeps`)."""
    size, width, m = params.shape[0] + EXTRA, v1c.shape[0] + 1, x.shape[0] + 2
    scratch = np.empty(size + 3 * m + 4 + 3 * width)  # one allocation a step for all of these:
    p = scratch[:size]  # the row, and what is fixed over a (sub)step
    cur = scratch[size : size + m]  # the state (TAN_SERVO), its next and a probe
    nxt = scratch[size + m : size + 2 * m]
    probe = scratch[size + 2 * m : size + 3 * m]
    sides = scratch[size + 3 * m : size + 3 * m + 4]  # and the Runge-Kutta steps taken
    coef = scratch[size + 3 * m + 4 :].reshape((3, width))
    p[: params.shape[0]] = params
    cur[:6] = x[:6]
    cur[PSI], cur[ANCHOR] = x[7], x[6]
    cur[HAT:] = x[8:]
    cur[2], cur[COS] = np.tan(x[2]), np.cos(x[2])  # the field's coordinates, back to the layout's at the end
    _lab_step_constants(p)
    cur[TAN_SERVO] = _lab_gate(p, x)
    pulses = p[PULSES] > 0
    t, remaining, which = tau, h, -1
    sides[0] = sides[1] = sides[3] = 0.0
    for _ in range(_MAX_EVENTS):
        sides[3] += 1.0
        phi_s = _lab_servo(p, cur)
        cur[ANCHOR] = _lab_wheel(p, cur[ANCHOR], phi_s)  # the anchor: the wheel angle now
        _lab_constants(p, cur)
        side = -1.0 if abs(cur[3]) > p[LIMIT] else 1.0
        rate = _lab_servo_rate(p, cur, poly(v1c, t), poly(v2c, t))
        direction = 0.0
        if p[BACKLASH] > 0:
            direction = 1.0 if rate > 0 else (-1.0 if rate < 0 else 0.0)
        # Past an event by a rounding error only (|phi_c| at the stop to the last bit, the servo's
        # rate not yet of the other sign), the state would fire it again at once, and again (each
        # time a step of 1e-14 h, under the clock's rounding): it is on the other side.
        if which == 0 and side == sides[0]:
            side = -side
        if which == 2 and direction == sides[1]:
            direction = -direction
        sides[0], sides[1] = side, direction
        gap = direction * (phi_s - cur[ANCHOR])
        # Engaged: the anchor clipped to phi_s -+ b/2 just now, to the rounding of phi_s (a play under
        # it, 1e-300 rad, rounds to none, and would fire its engaging event again and again).
        slack = 1e-12 * 0.5 * p[BACKLASH] + 4.0 * np.finfo(np.float64).eps * abs(phi_s)
        sides[2] = 1.0 if gap >= 0.5 * p[BACKLASH] - slack else 0.0
        which, span = -1, remaining
        if pulses:
            lab_wheel_speed(p, cur, v1c, coef, t)
            which, span = lab_pulse(p, cur, coef, t, remaining)
        _lab_rk(rhs, p, cur, t, span, v1c, v2c, nxt, work)
        first = span
        for j in range(3):
            g_hi = _lab_event(j, p, nxt, t + span, v1c, v2c, sides)
            if not g_hi > 0.0:  # (most substeps: then the start's value is not needed)
                continue
            g_lo = _lab_event(j, p, cur, t, v1c, v2c, sides)
            if not g_lo <= 0.0:
                continue
            state = (p, cur, t, v1c, v2c, probe, work, j, sides)
            hi = locate(_lab_event_after, rhs, state, g_lo, g_hi, span, _LAB_EVENT_TIME * h, False, True)
            if hi < first:
                first, which = hi, j
        if which < 0:
            cur[:] = nxt
            break
        if first < span:
            sides[3] += 1.0
            _lab_rk(rhs, p, cur, t, first, v1c, v2c, probe, work)
            cur[:] = probe
        else:
            cur[:] = nxt
        _lab_jump(which, p, cur)
        t += first
        remaining -= first
        if remaining <= 0.0:
            break
    out[:6] = cur[:6]
    out[6], out[7] = _lab_wheel(p, cur[ANCHOR], _lab_servo(p, cur)), cur[PSI]  # the wheel angle at the end
    out[8:] = cur[HAT:]
    out[2] = np.arctan(cur[2])
    return int(sides[3])


@njit(cache=True, inline="always")
def _lab_chart(params, x):  # type: ignore[no-untyped-def]
    phi_s = _lab_servo(params, x)
    wheel = _lab_wheel(params, x[6], phi_s) + params[OFFSET]
    return max(abs(x[2]), abs(x[10]), abs(phi_s), abs(wheel)) < CHART_LIMIT


LAB_KERNEL = trial_kernel("car-lab", LAB_LAYOUT, __name__, _lab_field, _lab_chart, _lab_step)


@njit(cache=True)
def _substeps(params, x0, durations, steps, v1c, v2c, counts):  # type: ignore[no-untyped-def]
    """:func:`lab_substeps`'s compiled loop: each trial as the kernel runs it, its Runge-Kutta steps counted."""
    n = x0.shape[1]
    x, nxt, probe = np.empty(n), np.empty(n), np.empty(n)
    work = np.empty((STAGES + 1, n))
    for b in range(x0.shape[0]):
        x[:] = x0[b]
        counts[b] = 0
        for i in range(durations.shape[0]):
            h = durations[i] / steps[i]
            for k in range(steps[i]):
                counts[b] += _lab_step(_lab_field, n, params[b], x, k * h, h, v1c[b, i], v2c[b, i], nxt, work, probe)
                if not (np.all(np.isfinite(nxt)) and _lab_chart(params[b], nxt)):
                    break
                x[:] = nxt


def lab_substeps(params: Array, x0: Array, durations: Array, steps: Int, v1: Array, v2: Array) -> Int:
    """The Runge-Kutta steps each trial of a batch takes on :data:`LAB_KERNEL`, to its last step on
    the chart: one a step, one more a substep after each event, and the event locator's probes (what a
    trial costs, counted). The arguments are :func:`~ilc_steering.core.integrate.integrate`'s."""
    params, x0, durations, steps, v1, v2 = checked_batch(LAB_KERNEL, params, x0, durations, steps, v1, v2)
    counts = np.zeros(x0.shape[0], dtype=np.int64)
    _substeps(params, x0, durations, steps, v1, v2, counts)
    return counts
