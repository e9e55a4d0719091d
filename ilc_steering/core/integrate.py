"""Fixed-step explicit Runge-Kutta over a batch of trials, compiled with numba.

The car without servo perturbations runs on the batched kernel of
:mod:`ilc_steering.core.tangent` (the same ODE in tangent coordinates, vectorized across trials,
four times this module's speed); the kernels below integrate every other plant, and the car in
``(x, y, theta, phi)`` with ``integrate(..., angles=True)``, which ``benchmarks/throughput.py``
times against it. Every kernel takes a row of parameters per trial, so one call may run a batch
of different plants.

The method is the 8th-order, 12-stage Dormand-Prince tableau (the one behind scipy's DOP853),
run with a fixed step: on the paper's tasks a step of 1/32 s lands within 1e-9 of an adaptive
DOP853 reference at rtol = atol = 1e-12 (``tests/test_integrate.py``; ``benchmarks/integrator.py``
measures accuracy and speed against the step).

The inputs are piecewise polynomials in each piece's local time (from an input profile), and
every piece boundary is a step boundary, so no step straddles a jump of ``v1`` or ``v2``.

Steering limit (car only): the steering servo integrates the commanded rate ``u2`` into a
commanded angle ``phi_c`` (the fourth state), and the wheel turns to
``phi = clip(phi_c, -steering_limit, steering_limit)``: at the stop the wheel rests while the
command winds on, and it leaves the stop when the command comes back inside. The controller
measures the wheel angle ``phi``. This reading of the paper's 45-degree case comes close to its
seven iterations (eight to 0.5 mm); a stop that discards the command learns far more slowly. The
kink of the vector field where ``|phi_c|`` crosses the limit is located inside the step by
root finding (Illinois regula falsi), so such a step keeps the method's accuracy.

Servo perturbations (car, :data:`~ilc_steering.core.plants.CAR_SERVO_FIELD`): a misaligned
wheel and first-order steering and drive servos, in a six-state field of their own, so the
unperturbed car keeps its four-state kernel. A lag adds a stable linear mode of rate
``1 / lag``; the fixed step resolves it when ``lag`` is not much below the step (the config
requires ``lag >= max_step``).

The lab robot (car, :data:`~ilc_steering.core.plants.CAR_LAB_FIELD`, section 5's MARIO): the
servo perturbations above plus a steering linkage with play and a controller that dead-reckons
its heading from quantized wheel encoders. Twelve states ``(x, y, theta, phi_c, phi_s, omega, A,
psi, x_hat, y_hat, theta_hat, k)``: the servo's output ``phi_s`` (the lag state, or the clipped
command), the play's anchor ``A``, the wheel's rotation ``psi`` [rad] since the last pulse
(within one pitch, so a pulse is located to rounding; the total is ``2 pi k / N + psi``), the
controller's estimate and its pulse count ``k``. The wheel turns to ``phi_w = clip(A, phi_s - b/2, phi_s + b/2)``: on a
stretch where ``phi_s`` is monotone, that is the play operator exactly, given ``A`` = the wheel
angle at its start; ``A`` is refreshed at every (sub)step. Eqs. 4-5 use ``theta_hat`` and
``phi_s``. Events, each located inside the step by Illinois regula falsi and the step split
there: the steering limit; the play engaging; ``phi_s`` turning back (its rate changes sign, so
the clip formula restarts); and each encoder pulse, ``psi`` leaving ``[0, 2 pi / N]``,
which jumps the estimate by the nominal odometry of an arc of ``2 pi rho_nominal / N``.

The unicycle (:data:`~ilc_steering.core.plants.UNICYCLE_FIELD`) and the car towing a trailer
(:data:`~ilc_steering.core.plants.TRAILER_FIELD`, whose fourth state is the steering command,
limited as the car's) have fields of their own; the trailer's is compiled from the functions of
:mod:`ilc_steering.core.trailer`.

Chart guard: the controller's transform (eqs. 4-5) breaks down as ``|theta|`` or ``|phi|``
approaches ``pi/2`` in the task frame. A step that ends within ``CHART_MARGIN`` rad of it (or
beyond: a stiff step can throw ``theta`` far past it), or with a non-finite state, is discarded
and the trial stops with status ``LEFT_CHART``: the robot halts at its last valid configuration.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

import numba
import numpy as np
import numpy.typing as npt
from numba import njit, prange

from ilc_steering.core import dop853, tangent
from ilc_steering.core.plants import CAR_FIELD as CAR
from ilc_steering.core.plants import CAR_LAB_FIELD as CAR_LAB
from ilc_steering.core.plants import CAR_SERVO_FIELD as CAR_SERVO
from ilc_steering.core.plants import CHAINED_FIELD as CHAINED
from ilc_steering.core.plants import CHART_MARGIN, KERNEL_LAYOUTS
from ilc_steering.core.plants import TRAILER_FIELD as TRAILER
from ilc_steering.core.plants import UNICYCLE_FIELD as UNICYCLE
from ilc_steering.core.trailer import trailer_inputs, trailer_velocity

__all__ = ["LEFT_CHART", "OK", "closed_loop_velocity", "integrate"]

Array = npt.NDArray[np.float64]

OK = 0
LEFT_CHART = 1
_CHART_LIMIT = np.pi / 2 - CHART_MARGIN
_MAX_ITERATIONS = 60  # of the root finder at a steering-limit crossing; it needs about 23
_MAX_EVENTS = 10_000  # events within one step of the lab robot before it gives up locating them
_LAB_EVENT_TIME = 1e-14  # relative to the step: how closely a lab event is located

_SINGLE_LANES = 6  # a last, partial block of the batched car kernel of at most this many trials runs them one by one
_STAGES = dop853.STAGES
_A = np.ascontiguousarray(dop853.A)
_B = np.ascontiguousarray(dop853.B)
_C = np.ascontiguousarray(dop853.C)


@njit(cache=True, inline="always")
def closed_loop_velocity(theta, phi, v1, v2, wheelbase, wheel_radius, true_wheelbase, true_wheel_radius):  # type: ignore[no-untyped-def]
    """Eq. (3) of a car with the true geometry, driven by eqs. (4)-(5) with the nominal one:
    ``(dx, dy, dtheta, dphi)`` [m/s, m/s, rad/s, rad/s].

    Equals ``car_velocity(theta, phi, *chained_inputs(theta, phi, v1, v2, wheelbase,
    wheel_radius), true_wheelbase, true_wheel_radius)`` of :mod:`ilc_steering.core.car` (tested)
    with each sine and cosine evaluated once: this is the integrator's inner loop.
    """
    s, c = np.sin(theta), np.cos(theta)
    s_phi, c_phi = np.sin(phi), np.cos(phi)
    speed = true_wheel_radius / wheel_radius * v1 / c  # true rho times the commanded u1
    dphi = -3.0 / wheelbase * s / (c * c) * s_phi * s_phi * v1 + wheelbase * c * c * c * c_phi * c_phi * v2
    return c * speed, s * speed, s_phi / c_phi * speed / true_wheelbase, dphi


# The helpers are inlined into one function per plant (see _car_trial): with the state
# dimension a constant and the scratch arrays local, the compiler keeps the stages in registers,
# twice as fast as calling them. Each plant's field is its own function, handed down to the
# stepper as an argument, so a plant's trial compiles its own field only (numba does not prune
# the branches of one field function on a constant plant id: one function of three fields
# compiled a quarter slower).
@njit(cache=True, inline="always")
def _poly(coef, tau):  # type: ignore[no-untyped-def]
    acc = 0.0
    for d in range(coef.shape[0] - 1, -1, -1):
        acc = acc * tau + coef[d]
    return acc


@njit(cache=True, inline="always")
def _rhs_car(params, x, v1, v2, out):  # type: ignore[no-untyped-def]
    phi = min(max(x[3], -params[4]), params[4])
    dx, dy, dtheta, dphi = closed_loop_velocity(x[2], phi, v1, v2, params[0], params[1], params[2], params[3])
    out[0] = dx
    out[1] = dy
    out[2] = dtheta
    out[3] = dphi


@njit(cache=True, inline="always")
def _rhs_car_servo(params, x, v1, v2, out):  # type: ignore[no-untyped-def]
    limit, offset, steering_lag, speed_lag = params[4], params[5], params[6], params[7]
    commanded = min(max(x[3], -limit), limit)
    phi = x[4] if steering_lag > 0 else commanded
    s, c = np.sin(x[2]), np.cos(x[2])
    s_phi, c_phi = np.sin(phi), np.cos(phi)
    u1 = v1 / (params[1] * c)
    u2 = -3.0 / params[0] * s / (c * c) * s_phi * s_phi * v1 + params[0] * c * c * c * c_phi * c_phi * v2
    omega = x[5] if speed_lag > 0 else u1
    speed = params[3] * omega
    out[0] = c * speed
    out[1] = s * speed
    out[2] = np.tan(phi + offset) * speed / params[2]
    out[3] = u2
    out[4] = (commanded - x[4]) / steering_lag if steering_lag > 0 else 0.0
    out[5] = (u1 - x[5]) / speed_lag if speed_lag > 0 else 0.0


@njit(cache=True, inline="always")
def _lab_servo(params, x):  # type: ignore[no-untyped-def]
    """The steering servo's output ``phi_s``: the lag state, or the clipped command."""
    if params[6] > 0:
        return x[4]
    return min(max(x[3], -params[4]), params[4])


@njit(cache=True, inline="always")
def _lab_wheel(params, x, phi_s):  # type: ignore[no-untyped-def]
    """The wheel angle behind the linkage's play ``b``: ``clip(A, phi_s - b/2, phi_s + b/2)``."""
    half = 0.5 * params[8]
    return min(max(x[6], phi_s - half), phi_s + half)


@njit(cache=True, inline="always")
def _lab_inputs(params, x, v1, v2):  # type: ignore[no-untyped-def]
    """Eqs. 4-5 with the nominal geometry at the controller's estimate: ``(u1, u2)``."""
    theta = x[10] if params[9] > 0 else x[2]
    phi = _lab_servo(params, x)
    s, c = np.sin(theta), np.cos(theta)
    s_phi, c_phi = np.sin(phi), np.cos(phi)
    u1 = v1 / (params[1] * c)
    u2 = -3.0 / params[0] * s / (c * c) * s_phi * s_phi * v1 + params[0] * c * c * c * c_phi * c_phi * v2
    return u1, u2


@njit(cache=True, inline="always")
def _lab_servo_rate(params, x, v1, v2):  # type: ignore[no-untyped-def]
    """``d phi_s / dt``."""
    limit = params[4]
    if params[6] > 0:
        return (min(max(x[3], -limit), limit) - x[4]) / params[6]
    if abs(x[3]) >= limit:
        return 0.0
    return _lab_inputs(params, x, v1, v2)[1]


@njit(cache=True, inline="always")
def _rhs_car_lab(params, x, v1, v2, out):  # type: ignore[no-untyped-def]
    limit, offset, steering_lag, speed_lag = params[4], params[5], params[6], params[7]
    u1, u2 = _lab_inputs(params, x, v1, v2)
    phi_w = _lab_wheel(params, x, _lab_servo(params, x))
    omega = x[5] if speed_lag > 0 else u1
    speed = params[3] * omega
    out[0] = np.cos(x[2]) * speed
    out[1] = np.sin(x[2]) * speed
    out[2] = np.tan(phi_w + offset) * speed / params[2]
    out[3] = u2
    out[4] = (min(max(x[3], -limit), limit) - x[4]) / steering_lag if steering_lag > 0 else 0.0
    out[5] = (u1 - x[5]) / speed_lag if speed_lag > 0 else 0.0
    out[6] = 0.0
    out[7] = omega
    for i in range(8, 12):
        out[i] = 0.0


# The car-trailer's transformation and kinematics are compiled from the very functions of
# ilc_steering.core.trailer (plain arithmetic and ufuncs), so its derivation lives in one place.
_trailer_inputs = njit(cache=True, inline="always")(trailer_inputs)
_trailer_velocity = njit(cache=True, inline="always")(trailer_velocity)


@njit(cache=True, inline="always")
def _rhs_unicycle(params, x, v1, v2, out):  # type: ignore[no-untyped-def]
    # v = v1 / cos(theta), omega = v2 cos^2(theta) realised by a drive with the true rho~, b~
    k = params[2] / params[0]
    c = np.cos(x[2])
    out[0] = k * v1
    out[1] = k * v1 * np.tan(x[2])
    out[2] = k * params[1] / params[3] * v2 * c * c


@njit(cache=True, inline="always")
def _rhs_trailer(params, x, v1, v2, out):  # type: ignore[no-untyped-def]
    phi = min(max(x[3], -params[4]), params[4])
    u1, u2 = _trailer_inputs(x[2], phi, x[4], v1, v2, params[0], params[1], params[5])
    dx, dy, dtheta, dphi, ddelta = _trailer_velocity(x[2], phi, x[4], u1, u2, params[2], params[3], params[6])
    out[0] = dx
    out[1] = dy
    out[2] = dtheta
    out[3] = dphi
    out[4] = ddelta


@njit(cache=True, inline="always")
def _rhs_chained(params, x, v1, v2, out):  # type: ignore[no-untyped-def]
    w1 = params[0] * v1
    out[0] = w1
    out[1] = params[1] * v2
    for i in range(2, x.shape[0]):
        out[i] = x[i - 1] * w1


@njit(cache=True, inline="always")
def _rk(rhs, n, params, x, tau, h, v1c, v2c, out, work):  # type: ignore[no-untyped-def]
    """One step of length ``h`` from local time ``tau``; ``work`` holds the stages and a scratch row."""
    tmp = work[_STAGES]
    for s in range(_STAGES):
        for i in range(n):
            acc = 0.0
            for j in range(s):
                acc += _A[s, j] * work[j, i]
            tmp[i] = x[i] + h * acc
        t = tau + _C[s] * h
        rhs(params, tmp, _poly(v1c, t), _poly(v2c, t), work[s])
    for i in range(n):
        acc = 0.0
        for s in range(_STAGES):
            acc += _B[s] * work[s, i]
        out[i] = x[i] + h * acc


@njit(cache=True, inline="always")
def _step(rhs, model, n, params, x, tau, h, v1c, v2c, out, work, probe):  # type: ignore[no-untyped-def]
    """One step from local time ``tau``, split where ``|phi_c|`` crosses the steering limit."""
    _rk(rhs, n, params, x, tau, h, v1c, v2c, out, work)
    if model != CAR and model != CAR_SERVO and model != TRAILER:
        return
    limit = params[4]
    beyond = abs(x[3]) > limit
    if (abs(out[3]) > limit) == beyond:
        return
    # Illinois regula falsi on g(s) = |phi_c after a step of length s| - limit, which is smooth in
    # s: the crossing stays bracketed by [lo, hi], narrowed to double precision in about 23
    # sub-steps where bisection takes 54.
    lo, hi = 0.0, h  # the side of the limit changes between lo and hi
    g_lo, g_hi = abs(x[3]) - limit, abs(out[3]) - limit
    side = 0
    for _ in range(_MAX_ITERATIONS):
        if hi - lo <= 4e-16 * h:
            break
        mid = (lo * g_hi - hi * g_lo) / (g_hi - g_lo)
        if not (lo < mid < hi):
            mid = 0.5 * (lo + hi)
        _rk(rhs, n, params, x, tau, mid, v1c, v2c, probe, work)
        g_mid = abs(probe[3]) - limit
        if (g_mid > 0) == beyond:
            lo, g_lo = mid, g_mid
            if side == -1:
                g_hi *= 0.5
            side = -1
        else:
            hi, g_hi = mid, g_mid
            if side == 1:
                g_lo *= 0.5
            side = 1
    _rk(rhs, n, params, x, tau, hi, v1c, v2c, probe, work)
    _rk(rhs, n, params, probe, tau + hi, h - hi, v1c, v2c, out, work)


@njit(cache=True, inline="always")
def _lab_event(j, params, x, tau, v1c, v2c, sides):  # type: ignore[no-untyped-def]
    """Event ``j`` of the lab robot as a value that crosses from <= 0 to > 0 when it fires;
    ``sides`` holds what is fixed over a substep (the side of the limit, the servo's direction)."""
    if j == 0:
        return sides[0] * (abs(x[3]) - params[4])
    if j == 1 or j == 2:
        if sides[1] == 0:
            return -1.0
        phi_s = _lab_servo(params, x)
        if j == 1:
            if sides[2] != 0:  # engaged on the side it moves to: no kink ahead of the next turn
                return -1.0
            return sides[1] * (phi_s - x[6]) - 0.5 * params[8]
        return -sides[1] * _lab_servo_rate(params, x, _poly(v1c, tau), _poly(v2c, tau))
    if j == 3:
        return x[7] - 2.0 * np.pi / params[9]
    return -x[7]


@njit(cache=True, inline="always")
def _lab_jump(j, params, x):  # type: ignore[no-untyped-def]
    """At pulse ``j`` (3 forward, 4 backward): the estimate moves by the nominal odometry of one
    encoder pitch of wheel travel, at the servo's steering angle."""
    if j < 3:
        return
    sign = 1.0 if j == 3 else -1.0
    ds = sign * 2.0 * np.pi * params[1] / params[9]
    dtheta = ds * np.tan(_lab_servo(params, x)) / params[0]
    x[8] += ds * np.cos(x[10] + 0.5 * dtheta)
    x[9] += ds * np.sin(x[10] + 0.5 * dtheta)
    x[10] += dtheta
    x[11] += sign
    x[7] -= sign * 2.0 * np.pi / params[9]


@njit(cache=True, inline="always")
def _lab_step(rhs, model, n, params, x, tau, h, v1c, v2c, out, work, probe):  # type: ignore[no-untyped-def]
    """One step of the lab robot from local time ``tau``, split at each event (see the module
    docstring) in the order they happen."""
    cur = x.copy()
    sides = np.empty(3)
    active = 5 if params[9] > 0 else 3  # the two pulse events only with encoders
    t, remaining = tau, h
    for _ in range(_MAX_EVENTS):
        phi_s = _lab_servo(params, cur)
        cur[6] = _lab_wheel(params, cur, phi_s)  # the anchor: the wheel angle now
        sides[0] = -1.0 if abs(cur[3]) > params[4] else 1.0
        rate = _lab_servo_rate(params, cur, _poly(v1c, t), _poly(v2c, t))
        direction = 0.0
        if params[8] > 0:
            direction = 1.0 if rate > 0 else (-1.0 if rate < 0 else 0.0)
        sides[1] = direction
        gap = direction * (phi_s - cur[6])
        sides[2] = 1.0 if gap >= 0.5 * params[8] * (1.0 - 1e-12) else 0.0
        _rk(rhs, n, params, cur, t, remaining, v1c, v2c, out, work)
        first, which = remaining, -1
        for j in range(active):
            g_lo = _lab_event(j, params, cur, t, v1c, v2c, sides)
            g_hi = _lab_event(j, params, out, t + remaining, v1c, v2c, sides)
            if not (g_lo <= 0.0 < g_hi):
                continue
            # Illinois regula falsi on the event's value after a step of length s.
            lo, hi, side = 0.0, remaining, 0
            for _ in range(_MAX_ITERATIONS):
                if hi - lo <= _LAB_EVENT_TIME * h:
                    break
                mid = (lo * g_hi - hi * g_lo) / (g_hi - g_lo)
                if not (lo < mid < hi):
                    mid = 0.5 * (lo + hi)
                _rk(rhs, n, params, cur, t, mid, v1c, v2c, probe, work)
                g_mid = _lab_event(j, params, probe, t + mid, v1c, v2c, sides)
                if g_mid == 0.0:  # on the event: a hair later it has fired
                    hi = min(mid + _LAB_EVENT_TIME * h, hi)
                    break
                if g_mid < 0.0:
                    lo, g_lo = mid, g_mid
                    if side == -1:
                        g_hi *= 0.5
                    side = -1
                else:
                    hi, g_hi = mid, g_mid
                    if side == 1:
                        g_lo *= 0.5
                    side = 1
            if hi < first:
                first, which = hi, j
        if which < 0:
            return
        _rk(rhs, n, params, cur, t, first, v1c, v2c, probe, work)
        cur[:] = probe
        _lab_jump(which, params, cur)
        t += first
        remaining -= first
        if remaining <= 0.0:
            break
    out[:] = cur


@njit(cache=True, inline="always")
def _in_chart(model, params, x):  # type: ignore[no-untyped-def]
    for value in x:
        if not np.isfinite(value):
            return False
    if model == CAR:
        return abs(x[2]) < _CHART_LIMIT and min(abs(x[3]), params[4]) < _CHART_LIMIT
    if model == CAR_SERVO:
        phi = x[4] if params[6] > 0 else min(max(x[3], -params[4]), params[4])
        return abs(x[2]) < _CHART_LIMIT and abs(phi) < _CHART_LIMIT and abs(phi + params[5]) < _CHART_LIMIT
    if model == CAR_LAB:
        phi_s = _lab_servo(params, x)
        wheel = _lab_wheel(params, x, phi_s) + params[5]
        return max(abs(x[2]), abs(x[10]), abs(phi_s), abs(wheel)) < _CHART_LIMIT
    if model == UNICYCLE:
        return abs(x[2]) < _CHART_LIMIT
    if model == TRAILER:
        return max(abs(x[2]), min(abs(x[3]), params[4]), abs(x[4])) < _CHART_LIMIT
    return True


@njit(cache=True, inline="always")
def _drive(rhs, step, model, n, params, x0, durations, steps, v1c, v2c, out, traj):  # type: ignore[no-untyped-def]
    x = x0.copy()
    nxt = np.empty(n)
    probe = np.empty(n)
    work = np.empty((_STAGES + 1, n))
    record = traj.shape[0] > 0
    if record:
        traj[0] = x
    row = 1
    for i in range(durations.shape[0]):
        h = durations[i] / steps[i]
        for k in range(steps[i]):
            step(rhs, model, n, params, x, k * h, h, v1c[i], v2c[i], nxt, work, probe)
            if not _in_chart(model, params, nxt):
                out[:] = x
                if record:
                    for r in range(row, traj.shape[0]):
                        traj[r] = x
                return LEFT_CHART
            x[:] = nxt
            if record:
                traj[row] = x
                row += 1
    out[:] = x
    return OK


# One compiled trial function per plant field, shared by its serial and parallel loops: each
# compiles on its first use and is cached on its own (numba's cache keys on the Python function),
# so a car run never waits for the chained form's or the servo car's code. Within one, the field
# and the state dimension are constants, so the compiler keeps the state in registers.
@njit(cache=True)
def _car_trial(params, x0, durations, steps, v1c, v2c, out, traj):  # type: ignore[no-untyped-def]
    return _drive(_rhs_car, _step, CAR, 4, params, x0, durations, steps, v1c, v2c, out, traj)


@njit(cache=True)
def _car_servo_trial(params, x0, durations, steps, v1c, v2c, out, traj):  # type: ignore[no-untyped-def]
    return _drive(_rhs_car_servo, _step, CAR_SERVO, 6, params, x0, durations, steps, v1c, v2c, out, traj)


@njit(cache=True)
def _car_lab_trial(params, x0, durations, steps, v1c, v2c, out, traj):  # type: ignore[no-untyped-def]
    return _drive(_rhs_car_lab, _lab_step, CAR_LAB, 12, params, x0, durations, steps, v1c, v2c, out, traj)


@njit(cache=True)
def _unicycle_trial(params, x0, durations, steps, v1c, v2c, out, traj):  # type: ignore[no-untyped-def]
    return _drive(_rhs_unicycle, _step, UNICYCLE, 3, params, x0, durations, steps, v1c, v2c, out, traj)


@njit(cache=True)
def _trailer_trial(params, x0, durations, steps, v1c, v2c, out, traj):  # type: ignore[no-untyped-def]
    return _drive(_rhs_trailer, _step, TRAILER, 5, params, x0, durations, steps, v1c, v2c, out, traj)


@njit(cache=True)
def _chained_trial(params, x0, durations, steps, v1c, v2c, out, traj):  # type: ignore[no-untyped-def]
    return _drive(_rhs_chained, _step, CHAINED, x0.shape[0], params, x0, durations, steps, v1c, v2c, out, traj)


@njit(cache=True)
def _serial_car(params, x0, durations, steps, v1c, v2c, out, status, traj):  # type: ignore[no-untyped-def]
    for b in range(x0.shape[0]):
        status[b] = _car_trial(params[b], x0[b], durations, steps, v1c[b], v2c[b], out[b], traj[b])


@njit(cache=True, parallel=True)
def _parallel_car(params, x0, durations, steps, v1c, v2c, out, status, traj):  # type: ignore[no-untyped-def]
    for b in prange(x0.shape[0]):
        status[b] = _car_trial(params[b], x0[b], durations, steps, v1c[b], v2c[b], out[b], traj[b])


@njit(cache=True)
def _serial_car_servo(params, x0, durations, steps, v1c, v2c, out, status, traj):  # type: ignore[no-untyped-def]
    for b in range(x0.shape[0]):
        status[b] = _car_servo_trial(params[b], x0[b], durations, steps, v1c[b], v2c[b], out[b], traj[b])


@njit(cache=True, parallel=True)
def _parallel_car_servo(params, x0, durations, steps, v1c, v2c, out, status, traj):  # type: ignore[no-untyped-def]
    for b in prange(x0.shape[0]):
        status[b] = _car_servo_trial(params[b], x0[b], durations, steps, v1c[b], v2c[b], out[b], traj[b])


@njit(cache=True)
def _serial_car_lab(params, x0, durations, steps, v1c, v2c, out, status, traj):  # type: ignore[no-untyped-def]
    for b in range(x0.shape[0]):
        status[b] = _car_lab_trial(params[b], x0[b], durations, steps, v1c[b], v2c[b], out[b], traj[b])


@njit(cache=True, parallel=True)
def _parallel_car_lab(params, x0, durations, steps, v1c, v2c, out, status, traj):  # type: ignore[no-untyped-def]
    for b in prange(x0.shape[0]):
        status[b] = _car_lab_trial(params[b], x0[b], durations, steps, v1c[b], v2c[b], out[b], traj[b])


@njit(cache=True)
def _serial_chained(params, x0, durations, steps, v1c, v2c, out, status, traj):  # type: ignore[no-untyped-def]
    for b in range(x0.shape[0]):
        status[b] = _chained_trial(params[b], x0[b], durations, steps, v1c[b], v2c[b], out[b], traj[b])


@njit(cache=True, parallel=True)
def _parallel_chained(params, x0, durations, steps, v1c, v2c, out, status, traj):  # type: ignore[no-untyped-def]
    for b in prange(x0.shape[0]):
        status[b] = _chained_trial(params[b], x0[b], durations, steps, v1c[b], v2c[b], out[b], traj[b])


@njit(cache=True)
def _serial_unicycle(params, x0, durations, steps, v1c, v2c, out, status, traj):  # type: ignore[no-untyped-def]
    for b in range(x0.shape[0]):
        status[b] = _unicycle_trial(params[b], x0[b], durations, steps, v1c[b], v2c[b], out[b], traj[b])


@njit(cache=True, parallel=True)
def _parallel_unicycle(params, x0, durations, steps, v1c, v2c, out, status, traj):  # type: ignore[no-untyped-def]
    for b in prange(x0.shape[0]):
        status[b] = _unicycle_trial(params[b], x0[b], durations, steps, v1c[b], v2c[b], out[b], traj[b])


@njit(cache=True)
def _serial_trailer(params, x0, durations, steps, v1c, v2c, out, status, traj):  # type: ignore[no-untyped-def]
    for b in range(x0.shape[0]):
        status[b] = _trailer_trial(params[b], x0[b], durations, steps, v1c[b], v2c[b], out[b], traj[b])


@njit(cache=True, parallel=True)
def _parallel_trailer(params, x0, durations, steps, v1c, v2c, out, status, traj):  # type: ignore[no-untyped-def]
    for b in prange(x0.shape[0]):
        status[b] = _trailer_trial(params[b], x0[b], durations, steps, v1c[b], v2c[b], out[b], traj[b])


_KERNELS = {
    CAR: (_serial_car, _parallel_car),
    CAR_SERVO: (_serial_car_servo, _parallel_car_servo),
    CAR_LAB: (_serial_car_lab, _parallel_car_lab),
    CHAINED: (_serial_chained, _parallel_chained),
    UNICYCLE: (_serial_unicycle, _parallel_unicycle),
    TRAILER: (_serial_trailer, _parallel_trailer),
}


def integrate(
    model: int,
    params: Array,
    x0: Array,
    durations: Array,
    steps: npt.NDArray[np.int64],
    v1: Array,
    v2: Array,
    record: bool = False,
    parallel: bool = False,
    angles: bool = False,
) -> tuple[Array, npt.NDArray[np.int64], Array | None]:
    """Integrate a batch of trials.

    ``x0`` is ``(B, nx)``; ``params`` is ``(P,)`` for every trial or ``(B, P)``, a plant per
    trial; ``v1`` and ``v2`` are ``(B, p, D)`` piecewise polynomials from an input profile.
    Returns the final states ``(B, nx)``, the status of each trial (``OK`` or ``LEFT_CHART``)
    and, with ``record``, the states at every step ``(B, 1 + sum(steps), nx)``.

    The car (:data:`~ilc_steering.core.plants.CAR_FIELD`) runs on the batched kernel of
    :mod:`ilc_steering.core.tangent`; ``angles=True`` runs it on this module's kernel in
    ``(x, y, theta, phi)`` instead, the one it replaced (kept for ``benchmarks/throughput.py``).
    """
    # One layout for every caller (C order, float64, writeable): a read-only or strided view would
    # compile a second specialization of the kernel, which costs as long as the first.
    x0, params, durations, v1, v2 = (_layout(a, np.float64) for a in (x0, params, durations, v1, v2))
    steps = _layout(steps, np.int64)
    params = _check_arrays(model, params, x0, durations, steps, v1, v2)
    batch, n = x0.shape
    out = np.empty((batch, n))
    status = np.empty(batch, dtype=np.int64)
    rows = 1 + int(steps.sum()) if record else 0
    traj = np.empty((batch, rows, n))
    args = (params, x0, durations, steps, v1, v2, out, status, traj)
    if model == CAR and not angles:
        lanes = tangent.LANES
        full = batch - batch % lanes if batch % lanes <= _SINGLE_LANES else batch
        if parallel and full > lanes:
            _announce_compile(tangent.parallel_batch)
            tangent.parallel_batch(*args, full)
        elif full:
            _announce_compile(tangent.block_full)
            for start in range(0, full, lanes):
                tangent.block_full(*args, start, min(full, start + lanes))
        if full < batch:
            _announce_compile(tangent.block_one)
            for start in range(full, batch):
                tangent.block_one(*args, start, start + 1)
    else:
        kernel = _KERNELS[model][1 if parallel else 0]
        _announce_compile(kernel)
        kernel(*args)
    return out, status, traj if record else None


def _check_arrays(
    model: int, params: Array, x0: Array, durations: Array, steps: npt.NDArray[np.int64], v1: Array, v2: Array
) -> Array:
    """``ValueError`` unless the arrays fit the layout of field ``model`` and one another: the compiled
    code reads them by position and checks nothing. Returns the parameter table ``(B, P)``."""
    layout = KERNEL_LAYOUTS.get(model)
    if layout is None:
        raise ValueError(f"no compiled field has id {model!r}; known: {sorted(KERNEL_LAYOUTS)}")
    if x0.ndim != 2 or x0.shape[0] < 1:
        raise ValueError(f"x0 must be a batch of states (B, nx) with B >= 1, got shape {x0.shape}")
    batch = x0.shape[0]
    if params.ndim == 1:
        params = np.ascontiguousarray(np.broadcast_to(params, (batch, params.shape[0])))
    if params.ndim != 2 or params.shape[0] != batch:
        raise ValueError(f"{batch} trials need {batch} rows of plant parameters, one per trial; got {params.shape}")
    if params.shape[1] != len(layout.params):
        raise ValueError(
            f"a parameter row of this field has {len(layout.params)} entries {list(layout.params)}, "
            f"got {params.shape[1]}"
        )
    if np.isnan(params).any():
        raise ValueError("plant parameters must not be NaN")
    sizes = {layout.state_size(row) for row in params} if not layout.state else {len(layout.state)}
    if sizes != {x0.shape[1]}:
        raise ValueError(f"the state of this field has {sorted(sizes)} entries, got states of {x0.shape[1]}")
    if not np.isfinite(x0).all():
        raise ValueError("start states x0 must be finite")
    pieces = durations.shape[0] if durations.ndim == 1 else -1
    if pieces < 1 or not np.all(durations > 0) or not np.isfinite(durations).all():
        raise ValueError(f"durations must be a vector of finite piece lengths > 0 [s], got {durations.tolist()}")
    if steps.shape != (pieces,) or not np.all(steps >= 1):
        raise ValueError(f"steps must give each of the {pieces} pieces at least 1 step, got {steps.tolist()}")
    for name, v in (("v1", v1), ("v2", v2)):
        if v.ndim != 3 or v.shape[:2] != (batch, pieces) or v.shape[2] < 1:
            raise ValueError(
                f"{name} must be polynomials (B, pieces, D) = ({batch}, {pieces}, D >= 1) for {batch} trials "
                f"of {pieces} pieces, got shape {v.shape}"
            )
        if not np.isfinite(v).all():
            raise ValueError(f"{name} coefficients must be finite")
    return params


def _layout(a: Any, dtype: Any) -> Any:
    if isinstance(a, np.ndarray) and a.dtype == dtype and a.flags.c_contiguous and a.flags.writeable:
        return a
    return np.require(a, dtype, ["C", "W"])


_READY: set[Any] = set()  # kernels this process has run: no announcement to consider


def _announce_compile(kernel: Any) -> None:
    """Say so on stderr when the first call will compile (no numba cache of ``kernel`` for this
    install yet): it takes 5-20 s once, then about 0.2 s per process."""
    if kernel in _READY:
        return
    _READY.add(kernel)
    if kernel.overloads:  # compiled (or loaded) in this process already
        return
    name = kernel.py_func.__name__
    cached = kernel.py_func.__qualname__.replace("<locals>", "locals")  # numba's file name: a factory's kernels too
    module = Path(kernel.py_func.__code__.co_filename).stem
    cache_dir = getattr(numba.config, "CACHE_DIR", "")
    folder = Path(cache_dir) if cache_dir else Path(__file__).parent / "__pycache__"
    if folder.is_dir() and any(folder.rglob(f"{module}.{cached}-*.nbi")):
        return
    what = "batched car" if module == "tangent" else name.removeprefix("_").replace("_", " ", 1).replace("_", "-")
    print(
        f"ilc-steering: compiling the {what} simulator once for this install (numba), then it is cached ...",
        file=sys.stderr,
        flush=True,
    )
