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
servo's response to a polynomial: :func:`_lab_pulse`), so a step with a pulse costs two
Runge-Kutta steps, not seven (``benchmarks/robots.py``).

What a step costs (``benchmarks/robots.py``, docs/speed.md): the field runs in ``tan(theta)`` with
``cos(theta)`` and ``tan(phi_s)`` carried as states (without a lag ``tan(phi_c)``: :func:`_lab_gate`),
so a stage evaluates no trigonometric function, no square root and two divisions; what is fixed
between events is set once per substep (:func:`_lab_constants`) or step, and a Runge-Kutta step runs
on the nine entries that move (:func:`_lab_rk`). Each change is within 1e-13 of the kernel before it
on ``tests/lab_reference.json``, the carried ``tan(phi_c)`` within 2.5e-11 on 512 packaged trials.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ilc_steering.core import dop853
from ilc_steering.core.kernels import trial_kernel
from ilc_steering.core.plants import KernelLayout
from ilc_steering.core.stepper import CHART_LIMIT, MAX_ITERATIONS, STAGES, locate, poly
from ilc_steering.core.tangent import CAR_LAYOUT

__all__ = ["LAB_KERNEL", "LAB_LAYOUT", "SERVO_PARAMS"]

SERVO_PARAMS = (*CAR_LAYOUT.params, "steering_offset", "steering_lag", "speed_lag")
"""The servo car's parameters, which the lab robot's row extends (a servo car runs on this kernel
with its play and encoders off)."""
LAB_LAYOUT = KernelLayout(
    ("x", "y", "theta", "phi_c", "phi_s", "omega", "A", "psi", "x_hat", "y_hat", "theta_hat", "k"),
    (*SERVO_PARAMS, "steering_backlash", "encoder_pulses"),
)
_ELL, _RHO, _TRUE_ELL, _TRUE_RHO, _LIMIT = (LAB_LAYOUT.index(name) for name in CAR_LAYOUT.params)
_OFFSET, _STEERING_LAG, _SPEED_LAG = (LAB_LAYOUT.index(n) for n in ("steering_offset", "steering_lag", "speed_lag"))
_BACKLASH, _PULSES = LAB_LAYOUT.index("steering_backlash"), LAB_LAYOUT.index("encoder_pulses")
# What _lab_step fixes for a step or a substep, past the row (_lab_constants): eq. 4's gain and eq. 5's
# two at the estimate, tan(offset -+ b/2), tan(A + offset), the reciprocals of true_wheelbase and the lags,
# tan(steering_limit), and the |phi_c| past which a servo without a lag carries no tan(phi_c) (_lab_gate).
_EXTRA = 11
_U1, _U2_V1, _U2_V2, _TAN_LO, _TAN_HI, _TAN_REST = range(len(LAB_LAYOUT.params), len(LAB_LAYOUT.params) + 6)
_PER_ELL, _PER_STEERING_LAG, _PER_SPEED_LAG, _TAN_LIMIT, _GATE = range(_TAN_REST + 1, _TAN_REST + 6)
_MAX_EVENTS = 10_000  # events within one step of the lab robot before it gives up locating them
_LAB_EVENT_TIME = 1e-14  # relative to the step: how closely a lab event is located
# _lab_step's state, 14 entries: (x, y, tan(theta), phi_c, phi_s, omega, psi, tan(phi_s), cos(theta), A,
# estimate). The first _MOVING entries move between events; A and the estimate jump.
_PSI, _TAN_SERVO, _COS, _ANCHOR, _HAT = 6, 7, 8, 9, 10
_MOVING = _ANCHOR


_A = np.ascontiguousarray(dop853.A)  # the tableau, as the stepper holds it
_B = np.ascontiguousarray(dop853.B)
_C = np.ascontiguousarray(dop853.C)


@njit(cache=True, inline="always")
def _lab_servo(params, x):  # type: ignore[no-untyped-def]
    """The steering servo's output ``phi_s``: the lag state, or the clipped command."""
    if params[_STEERING_LAG] > 0:
        return x[4]
    return min(max(x[3], -params[_LIMIT]), params[_LIMIT])


@njit(cache=True, inline="always")
def _lab_wheel(params, anchor, phi_s):  # type: ignore[no-untyped-def]
    """The wheel angle behind the linkage's play ``b``: ``clip(A, phi_s - b/2, phi_s + b/2)``."""
    half = 0.5 * params[_BACKLASH]
    return min(max(anchor, phi_s - half), phi_s + half)


@njit(cache=True, inline="always")
def _lab_step_constants(params):  # type: ignore[no-untyped-def]
    """Into ``params`` past the row: what is fixed over a step (:data:`_EXTRA`)."""
    offset, half, limit, lag = params[_OFFSET], 0.5 * params[_BACKLASH], params[_LIMIT], params[_STEERING_LAG]
    params[_TAN_LO], params[_TAN_HI] = np.tan(offset - half), np.tan(offset + half)
    params[_PER_ELL], params[_PER_STEERING_LAG] = 1.0 / params[_TRUE_ELL], (1.0 / lag if lag > 0 else 0.0)
    params[_PER_SPEED_LAG] = 1.0 / params[_SPEED_LAG] if params[_SPEED_LAG] > 0 else 0.0
    gate = 0.5 * (limit + 0.5 * np.pi)  # halfway from the stop to the chart's edge
    params[_TAN_LIMIT], params[_GATE] = (np.tan(limit), gate) if limit < 0.5 * np.pi else (np.inf, np.inf)


@njit(cache=True, inline="always")
def _lab_constants(params, x):  # type: ignore[no-untyped-def]
    """Into ``params`` past the row, fixed over a substep from ``x``: eq. 4's gain and eq. 5's at the
    estimate (with no encoder, the nominal geometry's; :func:`_lab_inputs`), ``tan(A + offset)``."""
    ell = params[_ELL]
    if params[_PULSES] > 0:
        s, c = np.sin(x[_HAT + 2]), np.cos(x[_HAT + 2])
        params[_U1], params[_U2_V1] = 1.0 / (params[_RHO] * c), -3.0 / ell * s / (c * c)
        params[_U2_V2] = ell * c * c * c
    else:
        params[_U1], params[_U2_V1], params[_U2_V2] = 1.0 / params[_RHO], -3.0 / ell, ell
    params[_TAN_REST] = np.tan(x[_ANCHOR] + params[_OFFSET])


@njit(cache=True, inline="always")
def _lab_gate(params, x):  # type: ignore[no-untyped-def]
    """The carried ``tan(phi_s)`` at a step's start; without a lag ``tan(phi_c)``, moving past the stop
    (a stage of a step resting there may look inside) up to a gate halfway to ``pi/2``."""
    if params[_STEERING_LAG] > 0:
        return np.tan(x[4])
    return np.tan(min(max(x[3], -params[_GATE]), params[_GATE]))


@njit(cache=True, inline="always")
def _lab_inputs(params, x, v1, v2):  # type: ignore[no-untyped-def]
    """Eqs. 4-5 with the nominal geometry at the controller's estimate (:func:`_lab_constants`; with
    no encoder, at the true heading, ``x[2] = tan(theta)``): ``(u1, u2, tan(phi_s))``."""
    inside = params[_STEERING_LAG] > 0 or abs(x[3]) < params[_LIMIT]
    t = x[_TAN_SERVO] if inside else np.copysign(params[_TAN_LIMIT], x[3])  # at the stop: its own tangent
    cos2 = 1.0 / (1.0 + t * t)  # cos(phi_s)^2, and sin(phi_s)^2 = t^2 cos2
    if params[_PULSES] > 0:
        return v1 * params[_U1], cos2 * (params[_U2_V1] * t * t * v1 + params[_U2_V2] * v2), t
    secant = np.sqrt(1.0 + x[2] * x[2])  # 1 / cos(theta), no division by a cosine that may be 0
    u2 = cos2 * (params[_U2_V1] * x[2] * secant * t * t * v1 + params[_U2_V2] * v2 / (secant * secant * secant))
    return v1 * secant * params[_U1], u2, t


@njit(cache=True, inline="always")
def _lab_servo_rate(params, x, v1, v2):  # type: ignore[no-untyped-def]
    """``d phi_s / dt``."""
    limit = params[_LIMIT]
    if params[_STEERING_LAG] > 0:
        return (min(max(x[3], -limit), limit) - x[4]) * params[_PER_STEERING_LAG]
    if abs(x[3]) >= limit:
        return 0.0
    return _lab_inputs(params, x, v1, v2)[1]


@njit(cache=True, inline="always")
def _lab_field(params, x, v1, v2, out):  # type: ignore[no-untyped-def]
    """The lab robot's field with ``x[2] = z = tan(theta)`` (so ``z' = (1 + z^2) theta'``): one tangent
    a stage, ``tan(phi_s)``; the wheel's ``tan(phi_w + offset)`` from it by the addition formula."""
    limit = params[_LIMIT]
    u1, u2, t = _lab_inputs(params, x, v1, v2)
    phi_s, half, anchor = _lab_servo(params, x), 0.5 * params[_BACKLASH], x[_ANCHOR]
    if anchor < phi_s - half:  # the play engaged, the servo pulling the wheel to its side
        tan_wheel = (t + params[_TAN_LO]) / (1.0 - t * params[_TAN_LO])
    elif anchor > phi_s + half:
        tan_wheel = (t + params[_TAN_HI]) / (1.0 - t * params[_TAN_HI])
    else:  # the wheel rests at the anchor
        tan_wheel = params[_TAN_REST]
    omega = x[5] if params[_SPEED_LAG] > 0 else u1
    speed = params[_TRUE_RHO] * omega
    z, c = x[2], x[_COS]
    turn = tan_wheel * speed * params[_PER_ELL]  # theta'
    out[0] = c * speed
    out[1] = z * c * speed
    out[2] = (1.0 + z * z) * turn
    out[_COS] = -z * c * turn
    out[3] = u2
    out[4] = (min(max(x[3], -limit), limit) - x[4]) * params[_PER_STEERING_LAG]  # 0 without a lag
    out[5] = (u1 - x[5]) * params[_PER_SPEED_LAG]
    out[_PSI] = omega
    if params[_STEERING_LAG] > 0:  # tan(phi_s)'; without a lag tan(phi_c)' (_lab_gate)
        out[_TAN_SERVO] = (1.0 + t * t) * out[4]
    else:
        out[_TAN_SERVO] = (1.0 + x[_TAN_SERVO] * x[_TAN_SERVO]) * u2 if abs(x[3]) < params[_GATE] else 0.0


@njit(cache=True, inline="always")
def _lab_event(j, params, x, tau, v1c, v2c, sides):  # type: ignore[no-untyped-def]
    """Event ``j`` of the lab robot as a value that crosses from <= 0 to > 0 when it fires;
    ``sides`` holds what is fixed over a substep (the side of the limit, the servo's direction)."""
    if j == 0:
        return sides[0] * (abs(x[3]) - params[_LIMIT])
    if j == 1 or j == 2:
        if sides[1] == 0:
            return -1.0
        phi_s = _lab_servo(params, x)
        if j == 1:
            if sides[2] != 0:  # engaged on the side it moves to: no kink ahead of the next turn
                return -1.0
            return sides[1] * (phi_s - x[_ANCHOR]) - 0.5 * params[_BACKLASH]
        return -sides[1] * _lab_servo_rate(params, x, poly(v1c, tau), poly(v2c, tau))
    if j == 3:
        return x[_PSI] - 2.0 * np.pi / params[_PULSES]
    return -x[_PSI]


@njit(cache=True, inline="always")
def _lab_jump(j, params, x):  # type: ignore[no-untyped-def]
    """At pulse ``j`` (3 forward, 4 backward): the estimate moves by the nominal odometry of one
    encoder pitch of wheel travel, at the servo's steering angle."""
    if j < 3:
        return
    sign = 1.0 if j == 3 else -1.0
    ds = sign * 2.0 * np.pi * params[_RHO] / params[_PULSES]
    dtheta = ds * np.tan(_lab_servo(params, x)) / params[_ELL]
    x[_HAT] += ds * np.cos(x[_HAT + 2] + 0.5 * dtheta)
    x[_HAT + 1] += ds * np.sin(x[_HAT + 2] + 0.5 * dtheta)
    x[_HAT + 2] += dtheta
    x[_HAT + 3] += sign
    x[_PSI] -= sign * 2.0 * np.pi / params[_PULSES]


@njit(cache=True, inline="always")
def _lab_rk(rhs, params, x, tau, h, v1c, v2c, out, work):  # type: ignore[no-untyped-def]
    """:func:`~ilc_steering.core.stepper.rk_step` on the first :data:`_MOVING` entries (the rest carried
    over), the stages combined across entries in rk_step's order (the same sums), past the zeros."""
    tmp = work[STAGES]
    tmp[_ANCHOR] = x[_ANCHOR]
    for s in range(STAGES):
        for i in range(_MOVING):
            tmp[i] = 0.0
        for j in range(s):
            a = _A[s, j]
            if a != 0.0:
                for i in range(_MOVING):
                    tmp[i] += a * work[j, i]
        for i in range(_MOVING):
            tmp[i] = x[i] + h * tmp[i]
        t = tau + _C[s] * h
        rhs(params, tmp, poly(v1c, t), poly(v2c, t), work[s])
    for i in range(_MOVING):
        out[i] = 0.0
    for s in range(STAGES):
        b = _B[s]
        if b != 0.0:
            for i in range(_MOVING):
                out[i] += b * work[s, i]
    for i in range(_MOVING):
        out[i] = x[i] + h * out[i]
    for i in range(_MOVING, x.shape[0]):
        out[i] = x[i]


@njit(cache=True, inline="always")
def _lab_event_after(rhs, state, s):  # type: ignore[no-untyped-def]
    """Event ``j``'s value after a substep of length ``s`` from ``cur`` at local time ``t``."""
    params, cur, t, v1c, v2c, probe, work, j, sides = state
    _lab_rk(rhs, params, cur, t, s, v1c, v2c, probe, work)
    return _lab_event(j, params, probe, t + s, v1c, v2c, sides)


@njit(cache=True, inline="always")
def _lab_wheel_speed(params, x, v1c, coef, t):  # type: ignore[no-untyped-def]
    """Between pulses (the estimate fixed) the driving wheel's speed follows ``k v1(t)``, ``k = 1 /
    (rho cos(theta_hat))`` (eq. 4), through the speed servo: into ``coef[0]`` the polynomial ``q`` its
    speed tends to (``q' + q / lag = k v1 / lag``: ``q = k sum_m (-lag)^m v1^(m)``; ``k v1`` without a
    lag), into ``coef[1]`` its integral from 0 (in local time), into ``coef[2, :2]`` both at ``t``."""
    lag, k = params[_SPEED_LAG], params[_U1]  # 1 / (rho cos(theta_hat)), from _lab_constants
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
    in closed form between pulses (:func:`_lab_wheel_speed`; ``coef[2, :2]`` holds ``Q(t)`` and
    ``q(t)``): ``omega = q + (omega_0 - q(t)) e^(-s / lag)``."""
    q, big_q = coef[0], coef[1]
    rotation = poly(big_q, t + s) - coef[2, 0]
    if params[_SPEED_LAG] <= 0:
        return rotation, poly(q, t + s)
    gap, decay = x[5] - coef[2, 1], np.expm1(-s * params[_PER_SPEED_LAG])  # e^(-s / lag) - 1
    return rotation - gap * params[_SPEED_LAG] * decay, poly(q, t + s) + gap * (1.0 + decay)


@njit(cache=True, inline="always")
def _lab_pulse(params, x, coef, t, span):  # type: ignore[no-untyped-def]
    """The encoder pulse within ``span`` [s] of local time ``t``: ``(3, s)`` forward, ``(4, s)`` backward,
    or ``(-1, span)``; Newton's method, bracketed, on the closed-form rotation (:func:`_lab_turn`)."""
    pitch, psi = 2.0 * np.pi / params[_PULSES], x[_PSI]
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


@njit(cache=True, inline="always")
def _lab_step(rhs, n, params, x, tau, h, v1c, v2c, out, work, _probe):  # type: ignore[no-untyped-def]
    """One step from local time ``tau``, split at each event in turn (the module docstring): steering
    events by regula falsi on substeps, encoder pulses in closed form (:func:`_lab_pulse`)."""
    size, width, m = params.shape[0] + _EXTRA, v1c.shape[0] + 1, x.shape[0] + 2
    scratch = np.empty(size + 3 * m + 3 + 3 * width)  # one allocation a step for all of these:
    p = scratch[:size]  # the row, and what is fixed over a (sub)step
    cur = scratch[size : size + m]  # the state (_TAN_SERVO), its next and a probe
    nxt = scratch[size + m : size + 2 * m]
    probe = scratch[size + 2 * m : size + 3 * m]
    sides = scratch[size + 3 * m : size + 3 * m + 3]
    coef = scratch[size + 3 * m + 3 :].reshape((3, width))
    p[: params.shape[0]] = params
    cur[:6] = x[:6]
    cur[_PSI], cur[_ANCHOR] = x[7], x[6]
    cur[_HAT:] = x[8:]
    cur[2], cur[_COS] = np.tan(x[2]), np.cos(x[2])  # the field's coordinates, back to the layout's at the end
    _lab_step_constants(p)
    cur[_TAN_SERVO] = _lab_gate(p, x)
    pulses = p[_PULSES] > 0
    t, remaining, which = tau, h, -1
    sides[0] = sides[1] = 0.0
    for _ in range(_MAX_EVENTS):
        phi_s = _lab_servo(p, cur)
        cur[_ANCHOR] = _lab_wheel(p, cur[_ANCHOR], phi_s)  # the anchor: the wheel angle now
        _lab_constants(p, cur)
        side = -1.0 if abs(cur[3]) > p[_LIMIT] else 1.0
        rate = _lab_servo_rate(p, cur, poly(v1c, t), poly(v2c, t))
        direction = 0.0
        if p[_BACKLASH] > 0:
            direction = 1.0 if rate > 0 else (-1.0 if rate < 0 else 0.0)
        # Past an event by a rounding error only (|phi_c| at the stop to the last bit, the servo's
        # rate not yet of the other sign), the state would fire it again at once, and again (each
        # time a step of 1e-14 h, under the clock's rounding): it is on the other side.
        if which == 0 and side == sides[0]:
            side = -side
        if which == 2 and direction == sides[1]:
            direction = -direction
        sides[0], sides[1] = side, direction
        gap = direction * (phi_s - cur[_ANCHOR])
        sides[2] = 1.0 if gap >= 0.5 * p[_BACKLASH] * (1.0 - 1e-12) else 0.0
        which, span = -1, remaining
        if pulses:
            _lab_wheel_speed(p, cur, v1c, coef, t)
            which, span = _lab_pulse(p, cur, coef, t, remaining)
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
    out[6], out[7] = _lab_wheel(p, cur[_ANCHOR], _lab_servo(p, cur)), cur[_PSI]  # the wheel angle at the end
    out[8:] = cur[_HAT:]
    out[2] = np.arctan(cur[2])


@njit(cache=True, inline="always")
def _lab_chart(params, x):  # type: ignore[no-untyped-def]
    phi_s = _lab_servo(params, x)
    wheel = _lab_wheel(params, x[6], phi_s) + params[_OFFSET]
    return max(abs(x[2]), abs(x[10]), abs(phi_s), abs(wheel)) < CHART_LIMIT


LAB_KERNEL = trial_kernel("car-lab", LAB_LAYOUT, __name__, _lab_field, _lab_chart, _lab_step)
