"""The car's compiled fields beyond the batched kernel: the car with servo perturbations, section
5's lab robot, and the car in ``(x, y, theta, phi)`` (the kernel :mod:`ilc_steering.core.tangent`
replaced, kept as :data:`ANGLE_KERNEL` for ``benchmarks/throughput.py``). :func:`car_kernel`
picks a car plant's kernel and builds its parameter row.

Steering limit: the steering servo integrates the commanded rate ``u2`` into a commanded angle
``phi_c`` (the fourth state), and the wheel turns to ``phi = clip(phi_c, -steering_limit,
steering_limit)``: at the stop the wheel rests while the command winds on, and it leaves the stop
when the command comes back inside. The controller measures the wheel angle ``phi``. This reading
of the paper's 45-degree case comes close to its seven iterations (eight to 0.5 mm); a stop that
discards the command learns far more slowly. The kink of the field where ``|phi_c|`` crosses the
limit is located inside the step (:func:`~ilc_steering.core.stepper.step_with_stop`).

Servo perturbations (:data:`SERVO_KERNEL`): a misaligned wheel and first-order steering and drive
servos, six states ``(x, y, theta, phi_c, phi_w, omega)``. A lag adds a stable linear mode of rate
``1 / lag``; the fixed step resolves it when ``lag`` is not much below the step (the config
requires ``lag >= max_step``).

The lab robot (:data:`LAB_KERNEL`, section 5's MARIO): the servo perturbations above plus a
steering linkage with play and a controller that dead-reckons its heading from quantized wheel
encoders. Twelve states ``(x, y, theta, phi_c, phi_s, omega, A, psi, x_hat, y_hat, theta_hat,
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
"""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt
from numba import njit

from ilc_steering.core import tangent
from ilc_steering.core.kernels import trial_kernel
from ilc_steering.core.plants import Kernel, KernelLayout
from ilc_steering.core.stepper import CHART_LIMIT, MAX_ITERATIONS, locate, poly, rk_step_on, step_with_stop
from ilc_steering.core.tangent import CAR_LAYOUT

__all__ = ["ANGLE_KERNEL", "LAB_KERNEL", "SERVO_KERNEL", "car_kernel", "closed_loop_velocity"]

Array = npt.NDArray[np.float64]

SERVO_LAYOUT = KernelLayout(
    ("x", "y", "theta", "phi_c", "phi_w", "omega"), (*CAR_LAYOUT.params, "steering_offset", "steering_lag", "speed_lag")
)
LAB_LAYOUT = KernelLayout(
    ("x", "y", "theta", "phi_c", "phi_s", "omega", "A", "psi", "x_hat", "y_hat", "theta_hat", "k"),
    (*SERVO_LAYOUT.params, "steering_backlash", "encoder_pulses"),
)
# Where the fields read their parameters: one layout extends the other, so the indices are shared.
_ELL, _RHO, _TRUE_ELL, _TRUE_RHO, _LIMIT = (LAB_LAYOUT.index(name) for name in CAR_LAYOUT.params)
_OFFSET, _STEERING_LAG, _SPEED_LAG = (LAB_LAYOUT.index(n) for n in ("steering_offset", "steering_lag", "speed_lag"))
_BACKLASH, _PULSES = LAB_LAYOUT.index("steering_backlash"), LAB_LAYOUT.index("encoder_pulses")
_PHI_C = CAR_LAYOUT.state.index("phi_c")
_SIN_HAT, _COS_HAT = len(LAB_LAYOUT.params), len(LAB_LAYOUT.params) + 1  # _lab_step's, past the row
_MAX_EVENTS = 10_000  # events within one step of the lab robot before it gives up locating them
_LAB_EVENT_TIME = 1e-14  # relative to the step: how closely a lab event is located
_MOVING = np.array([0, 1, 2, 3, 4, 5, 7])  # the lab state's entries that move between events


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
    phi = min(max(x[3], -params[_LIMIT]), params[_LIMIT])
    p = params
    dx, dy, dtheta, dphi = closed_loop_velocity(x[2], phi, v1, v2, p[_ELL], p[_RHO], p[_TRUE_ELL], p[_TRUE_RHO])
    out[0] = dx
    out[1] = dy
    out[2] = dtheta
    out[3] = dphi


@njit(cache=True, inline="always")
def _servo_field(params, x, v1, v2, out):  # type: ignore[no-untyped-def]
    limit, offset, steering_lag, speed_lag = params[_LIMIT], params[_OFFSET], params[_STEERING_LAG], params[_SPEED_LAG]
    commanded = min(max(x[3], -limit), limit)
    phi = x[4] if steering_lag > 0 else commanded
    s, c = np.sin(x[2]), np.cos(x[2])
    s_phi, c_phi = np.sin(phi), np.cos(phi)
    ell = params[_ELL]
    u1 = v1 / (params[_RHO] * c)
    u2 = -3.0 / ell * s / (c * c) * s_phi * s_phi * v1 + ell * c * c * c * c_phi * c_phi * v2
    omega = x[5] if speed_lag > 0 else u1
    speed = params[_TRUE_RHO] * omega
    out[0] = c * speed
    out[1] = s * speed
    out[2] = np.tan(phi + offset) * speed / params[_TRUE_ELL]
    out[3] = u2
    out[4] = (commanded - x[4]) / steering_lag if steering_lag > 0 else 0.0
    out[5] = (u1 - x[5]) / speed_lag if speed_lag > 0 else 0.0


@njit(cache=True, inline="always")
def _limit_step(rhs, n, params, x, tau, h, v1c, v2c, out, work, probe):  # type: ignore[no-untyped-def]
    step_with_stop(rhs, n, params, x, tau, h, v1c, v2c, out, work, probe, _PHI_C, params[_LIMIT])


@njit(cache=True, inline="always")
def _car_chart(params, x):  # type: ignore[no-untyped-def]
    return abs(x[2]) < CHART_LIMIT and min(abs(x[3]), params[_LIMIT]) < CHART_LIMIT


@njit(cache=True, inline="always")
def _servo_chart(params, x):  # type: ignore[no-untyped-def]
    phi = x[4] if params[_STEERING_LAG] > 0 else min(max(x[3], -params[_LIMIT]), params[_LIMIT])
    return abs(x[2]) < CHART_LIMIT and abs(phi) < CHART_LIMIT and abs(phi + params[_OFFSET]) < CHART_LIMIT


@njit(cache=True, inline="always")
def _lab_servo(params, x):  # type: ignore[no-untyped-def]
    """The steering servo's output ``phi_s``: the lag state, or the clipped command."""
    if params[_STEERING_LAG] > 0:
        return x[4]
    return min(max(x[3], -params[_LIMIT]), params[_LIMIT])


@njit(cache=True, inline="always")
def _lab_wheel(params, x, phi_s):  # type: ignore[no-untyped-def]
    """The wheel angle behind the linkage's play ``b``: ``clip(A, phi_s - b/2, phi_s + b/2)``."""
    half = 0.5 * params[_BACKLASH]
    return min(max(x[6], phi_s - half), phi_s + half)


@njit(cache=True, inline="always")
def _lab_inputs(params, x, v1, v2):  # type: ignore[no-untyped-def]
    """Eqs. 4-5 with the nominal geometry at the controller's estimate: ``(u1, u2)``."""
    if params[_PULSES] > 0:  # the estimate's, fixed between pulses: set by _lab_step past the row
        s, c = params[_SIN_HAT], params[_COS_HAT]
    else:
        s, c = np.sin(x[2]), np.cos(x[2])
    phi = _lab_servo(params, x)
    s_phi, c_phi = np.sin(phi), np.cos(phi)
    ell = params[_ELL]
    u1 = v1 / (params[_RHO] * c)
    u2 = -3.0 / ell * s / (c * c) * s_phi * s_phi * v1 + ell * c * c * c * c_phi * c_phi * v2
    return u1, u2


@njit(cache=True, inline="always")
def _lab_servo_rate(params, x, v1, v2):  # type: ignore[no-untyped-def]
    """``d phi_s / dt``."""
    limit = params[_LIMIT]
    if params[_STEERING_LAG] > 0:
        return (min(max(x[3], -limit), limit) - x[4]) / params[_STEERING_LAG]
    if abs(x[3]) >= limit:
        return 0.0
    return _lab_inputs(params, x, v1, v2)[1]


@njit(cache=True, inline="always")
def _lab_field(params, x, v1, v2, out):  # type: ignore[no-untyped-def]
    limit, offset, steering_lag, speed_lag = params[_LIMIT], params[_OFFSET], params[_STEERING_LAG], params[_SPEED_LAG]
    u1, u2 = _lab_inputs(params, x, v1, v2)
    phi_w = _lab_wheel(params, x, _lab_servo(params, x))
    omega = x[5] if speed_lag > 0 else u1
    speed = params[_TRUE_RHO] * omega
    out[0] = np.cos(x[2]) * speed
    out[1] = np.sin(x[2]) * speed
    out[2] = np.tan(phi_w + offset) * speed / params[_TRUE_ELL]
    out[3] = u2
    out[4] = (min(max(x[3], -limit), limit) - x[4]) / steering_lag if steering_lag > 0 else 0.0
    out[5] = (u1 - x[5]) / speed_lag if speed_lag > 0 else 0.0
    out[6] = 0.0
    out[7] = omega
    for i in range(8, 12):
        out[i] = 0.0


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
            return sides[1] * (phi_s - x[6]) - 0.5 * params[_BACKLASH]
        return -sides[1] * _lab_servo_rate(params, x, poly(v1c, tau), poly(v2c, tau))
    if j == 3:
        return x[7] - 2.0 * np.pi / params[_PULSES]
    return -x[7]


@njit(cache=True, inline="always")
def _lab_jump(j, params, x):  # type: ignore[no-untyped-def]
    """At pulse ``j`` (3 forward, 4 backward): the estimate moves by the nominal odometry of one
    encoder pitch of wheel travel, at the servo's steering angle."""
    if j < 3:
        return
    sign = 1.0 if j == 3 else -1.0
    ds = sign * 2.0 * np.pi * params[_RHO] / params[_PULSES]
    dtheta = ds * np.tan(_lab_servo(params, x)) / params[_ELL]
    x[8] += ds * np.cos(x[10] + 0.5 * dtheta)
    x[9] += ds * np.sin(x[10] + 0.5 * dtheta)
    x[10] += dtheta
    x[11] += sign
    x[7] -= sign * 2.0 * np.pi / params[_PULSES]


@njit(cache=True, inline="always")
def _lab_event_after(rhs, state, s):  # type: ignore[no-untyped-def]
    """Event ``j``'s value after a substep of length ``s`` from ``cur`` at local time ``t``."""
    params, cur, t, v1c, v2c, probe, work, j, sides = state
    rk_step_on(rhs, _MOVING, params, cur, t, s, v1c, v2c, probe, work)
    return _lab_event(j, params, probe, t + s, v1c, v2c, sides)


@njit(cache=True, inline="always")
def _lab_wheel_speed(params, x, v1c, coef):  # type: ignore[no-untyped-def]
    """Between pulses (the estimate fixed) the driving wheel's speed follows ``k v1(t)``, ``k = 1 /
    (rho cos(theta_hat))`` (eq. 4), through the speed servo: into ``coef[0]`` the polynomial ``q`` its
    speed tends to (``q' + q / lag = k v1 / lag``: ``q = k sum_m (-lag)^m v1^(m)``; ``k v1`` without a
    lag), into ``coef[1]`` its integral from 0 (in local time)."""
    lag, k = params[_SPEED_LAG], 1.0 / (params[_RHO] * np.cos(x[10]))
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


@njit(cache=True, inline="always")
def _lab_turn(params, x, coef, t, s):  # type: ignore[no-untyped-def]
    """The wheel's rotation [rad] over ``s`` [s] from local time ``t`` and its speed [rad/s] then,
    in closed form between pulses (:func:`_lab_wheel_speed`): ``omega = q + (omega_0 - q(t))
    e^(-s / lag)``."""
    lag, q, big_q = params[_SPEED_LAG], coef[0], coef[1]
    rotation = poly(big_q, t + s) - poly(big_q, t)
    if lag <= 0:
        return rotation, poly(q, t + s)
    gap = x[5] - poly(q, t)
    return rotation - gap * lag * np.expm1(-s / lag), poly(q, t + s) + gap * np.exp(-s / lag)


@njit(cache=True, inline="always")
def _lab_pulse(params, x, coef, t, span):  # type: ignore[no-untyped-def]
    """The encoder pulse within ``span`` [s] of local time ``t``: ``(3, s)`` forward (``psi`` reaching
    one pitch) or ``(4, s)`` backward (``psi`` falling below 0) at ``s``, or ``(-1, span)``. The
    wheel's rotation is known in closed form (:func:`_lab_turn`), so the pulse is found by Newton's
    method on it, bracketed, to rounding: no Runge-Kutta substep is spent on locating it."""
    pitch, psi = 2.0 * np.pi / params[_PULSES], x[7]
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
        if abs(nxt - s) <= 1e-12 * span or g == 0.0:  # the rotation is known to about 1e-14 rad
            return which, nxt
        s = nxt
    return which, hi


@njit(cache=True, inline="always")
def _lab_step(rhs, n, params, x, tau, h, v1c, v2c, out, work, probe):  # type: ignore[no-untyped-def]
    """One step of the lab robot from local time ``tau``, split at each event (see the module
    docstring) in the order they happen: the steering events located by regula falsi on Runge-Kutta
    substeps, the encoder pulses in closed form (:func:`_lab_pulse`)."""
    cur = x.copy()
    sides = np.empty(3)
    coef = np.empty((2, v1c.shape[0] + 1))
    p = np.empty(params.shape[0] + 2)  # the row, and the estimate's sine and cosine
    p[: params.shape[0]] = params
    pulses = p[_PULSES] > 0
    t, remaining, which = tau, h, -1
    sides[0] = sides[1] = 0.0
    for _ in range(_MAX_EVENTS):
        p[_SIN_HAT], p[_COS_HAT] = np.sin(cur[10]), np.cos(cur[10])
        phi_s = _lab_servo(p, cur)
        cur[6] = _lab_wheel(p, cur, phi_s)  # the anchor: the wheel angle now
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
        gap = direction * (phi_s - cur[6])
        sides[2] = 1.0 if gap >= 0.5 * p[_BACKLASH] * (1.0 - 1e-12) else 0.0
        which, span = -1, remaining
        if pulses:
            _lab_wheel_speed(p, cur, v1c, coef)
            which, span = _lab_pulse(p, cur, coef, t, remaining)
        rk_step_on(rhs, _MOVING, p, cur, t, span, v1c, v2c, out, work)
        first = span
        for j in range(3):
            g_lo = _lab_event(j, p, cur, t, v1c, v2c, sides)
            g_hi = _lab_event(j, p, out, t + span, v1c, v2c, sides)
            if not (g_lo <= 0.0 < g_hi):
                continue
            state = (p, cur, t, v1c, v2c, probe, work, j, sides)
            hi = locate(_lab_event_after, rhs, state, g_lo, g_hi, span, _LAB_EVENT_TIME * h, False, True)
            if hi < first:
                first, which = hi, j
        if which < 0:
            return
        if first < span:
            rk_step_on(rhs, _MOVING, p, cur, t, first, v1c, v2c, probe, work)
            cur[:] = probe
        else:
            cur[:] = out
        _lab_jump(which, p, cur)
        t += first
        remaining -= first
        if remaining <= 0.0:
            break
    out[:] = cur


@njit(cache=True, inline="always")
def _lab_chart(params, x):  # type: ignore[no-untyped-def]
    phi_s = _lab_servo(params, x)
    wheel = _lab_wheel(params, x, phi_s) + params[_OFFSET]
    return max(abs(x[2]), abs(x[10]), abs(phi_s), abs(wheel)) < CHART_LIMIT


ANGLE_KERNEL = trial_kernel("car (angles)", CAR_LAYOUT, __name__, _car_field, _car_chart, _limit_step)
"""The car without servo perturbations in ``(x, y, theta, phi_c)``: the kernel the batched one replaced."""
SERVO_KERNEL = trial_kernel("car-servo", SERVO_LAYOUT, __name__, _servo_field, _servo_chart, _limit_step)
LAB_KERNEL = trial_kernel("car-lab", LAB_LAYOUT, __name__, _lab_field, _lab_chart, _lab_step)


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
    if plant.lab:
        lab = dict(steering_backlash=plant.steering_backlash, encoder_pulses=float(plant.encoder_pulses))
        return LAB_KERNEL, LAB_LAYOUT.row(**values, **servo, **lab)
    if plant.servo:
        return SERVO_KERNEL, SERVO_LAYOUT.row(**values, **servo)
    return tangent.KERNEL, CAR_LAYOUT.row(**values)
