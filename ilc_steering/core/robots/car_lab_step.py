"""One trial's step of the lab robot (:mod:`~ilc_steering.core.robots.car_lab`), split at each event
in turn: its pieces (a substep's start and end, shared with the kernel that runs trials in lanes,
:mod:`~ilc_steering.core.robots.car_lab_lanes`), :data:`LAB_TRIAL_KERNEL`, which runs a batch's
trials one by one, and :func:`lab_substeps`, what a trial costs in Runge-Kutta steps.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
from numba import njit

from ilc_steering.core.integrate import checked_batch
from ilc_steering.core.kernels import trial_kernel
from ilc_steering.core.robots.car_lab import (
    lab_chart,
    lab_constants,
    lab_event,
    lab_field,
    lab_gate,
    lab_jump,
    lab_rk,
    lab_servo,
    lab_servo_rate,
    lab_trial_constants,
    lab_wheel,
)
from ilc_steering.core.robots.car_lab_layout import (
    ANCHOR,
    BACKLASH,
    COS,
    EXTRA,
    HAT,
    LAB_LAYOUT,
    LIMIT,
    PSI,
    PULSES,
    TAN_SERVO,
)
from ilc_steering.core.robots.car_lab_pulses import lab_pulse, lab_wheel_speed
from ilc_steering.core.stepper import STAGES, locate, poly

__all__ = ["LAB_TRIAL_KERNEL", "lab_after", "lab_begin", "lab_load", "lab_store", "lab_substeps"]

Array = npt.NDArray[np.float64]
Int = npt.NDArray[np.int64]

MAX_EVENTS = 10_000
"""Events within one step of the lab robot before it gives up locating them."""
_LAB_EVENT_TIME = 1e-14  # relative to the step: how closely a lab event is located


@njit(cache=True, inline="always")
def _lab_event_after(rhs, state, s):  # type: ignore[no-untyped-def]
    """Event ``j``'s value after a substep of length ``s`` from ``cur`` at local time ``t``."""
    params, cur, t, v1c, v2c, probe, work, j, sides = state
    sides[3] += 1.0  # the Runge-Kutta steps a step took (_lab_step)
    lab_rk(rhs, params, cur, t, s, v1c, v2c, probe, work)
    return lab_event(j, params, probe, t + s, v1c, v2c, sides)


@njit(cache=True, inline="always")
def lab_load(p, x, cur):  # type: ignore[no-untyped-def]
    """A step's start: ``cur`` (:mod:`~ilc_steering.core.robots.car_lab_layout`'s step state) from the
    layout's state ``x``; ``p`` the row with what :func:`lab_trial_constants` fixed past it."""
    cur[:6] = x[:6]
    cur[PSI], cur[ANCHOR] = x[7], x[6]
    cur[HAT:] = x[8:]
    cur[2], cur[COS] = np.tan(x[2]), np.cos(x[2])  # the field's coordinates, back to the layout's at the end
    cur[TAN_SERVO] = lab_gate(p, x)


@njit(cache=True, inline="always")
def lab_store(p, cur, out):  # type: ignore[no-untyped-def]
    """A step's end: the layout's state from ``cur``, the wheel angle in place of the anchor."""
    out[:6] = cur[:6]
    out[6], out[7] = lab_wheel(p, cur[ANCHOR], lab_servo(p, cur)), cur[PSI]
    out[8:] = cur[HAT:]
    out[2] = np.arctan(cur[2])


@njit(cache=True, inline="always")
def lab_begin(p, cur, sides, coef, t, remaining, which, v1c, v2c):  # type: ignore[no-untyped-def]
    """A substep's start from local time ``t`` with ``remaining`` [s] of the step left, after event
    ``which`` (-1: none): the anchor and what is fixed over the substep refreshed, ``sides`` set (the
    events' sides, whether the play is engaged; ``sides[3]`` counts Runge-Kutta steps), the next
    pulse located. Returns ``(which, span)``: the pulse ending the substep (-1: none) and its length."""
    sides[3] += 1.0
    phi_s = lab_servo(p, cur)
    cur[ANCHOR] = lab_wheel(p, cur[ANCHOR], phi_s)  # the anchor: the wheel angle now
    lab_constants(p, cur)
    side = -1.0 if abs(cur[3]) > p[LIMIT] else 1.0
    rate = lab_servo_rate(p, cur, poly(v1c, t), poly(v2c, t))
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
    if p[PULSES] > 0:
        lab_wheel_speed(p, cur, v1c, coef, t)
        return lab_pulse(p, cur, coef, t, remaining)
    return -1, remaining


@njit(cache=True, inline="always")
def lab_after(rhs, p, cur, nxt, probe, work, sides, t, span, which, h, v1c, v2c):  # type: ignore[no-untyped-def]
    """A substep's end, given ``nxt``, the Runge-Kutta step of length ``span`` from ``cur`` at local
    time ``t``: a steering event inside it located (a step of length ``h`` locates to 1e-14 h) and
    ``cur`` moved to the first event or pulse, its jump made, or to ``nxt``. Returns ``(which,
    advance)``: the event there (-1: none, the step's end) and the time advanced [s]."""
    first = span
    # Each event's value at the end, written out (a loop over them costs twice as much: its branches
    # are not folded); most substeps fire none, and then the start's values are not needed.
    end0 = lab_event(0, p, nxt, t + span, v1c, v2c, sides)
    end1 = lab_event(1, p, nxt, t + span, v1c, v2c, sides)
    end2 = lab_event(2, p, nxt, t + span, v1c, v2c, sides)
    if end0 > 0.0 or end1 > 0.0 or end2 > 0.0:
        ends = (end0, end1, end2)
        which, first = _lab_steering_event(p, cur, nxt, probe, work, sides, t, span, which, h, v1c, v2c, ends)
    else:
        cur[:] = nxt
    lab_jump(which, p, cur)
    return which, first


@njit(cache=True)
def _lab_steering_event(p, cur, nxt, probe, work, sides, t, span, which, h, v1c, v2c, ends):  # type: ignore[no-untyped-def]
    """:func:`lab_after`'s rare branch, a steering event at the substep's end (``ends``, each event's
    value there): the first located and ``cur`` moved to it, or to ``nxt``. Returns ``(which, first)``.
    Compiled once, not inlined: every variant of both kernels calls it (half of their compile time)."""
    first = span
    for j in range(3):
        g_hi = ends[j]
        if not g_hi > 0.0:
            continue
        g_lo = lab_event(j, p, cur, t, v1c, v2c, sides)
        if not g_lo <= 0.0:
            continue
        state = (p, cur, t, v1c, v2c, probe, work, j, sides)
        hi = locate(_lab_event_after, lab_field, state, g_lo, g_hi, span, _LAB_EVENT_TIME * h, False, True)
        if hi < first:
            first, which = hi, j
    if which >= 0 and first < span:
        sides[3] += 1.0
        lab_rk(lab_field, p, cur, t, first, v1c, v2c, probe, work)
        cur[:] = probe
    else:
        cur[:] = nxt
    return which, first


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
    lab_trial_constants(p)
    lab_load(p, x, cur)
    t, remaining, which = tau, h, -1
    sides[0] = sides[1] = sides[3] = 0.0
    for _ in range(MAX_EVENTS):
        which, span = lab_begin(p, cur, sides, coef, t, remaining, which, v1c, v2c)
        lab_rk(rhs, p, cur, t, span, v1c, v2c, nxt, work)
        which, advance = lab_after(rhs, p, cur, nxt, probe, work, sides, t, span, which, h, v1c, v2c)
        t += advance
        remaining -= advance
        if which < 0 or remaining <= 0.0:
            break
    lab_store(p, cur, out)
    return int(sides[3])


@njit(cache=True)
def _lab_step_once(params, x, tau, h, v1c, v2c, out, work):  # type: ignore[no-untyped-def]
    """:func:`_lab_step` of the lab robot's field, compiled once for the one-by-one kernel and
    :func:`lab_substeps` (each would otherwise compile the whole step again)."""
    return _lab_step(lab_field, x.shape[0], params, x, tau, h, v1c, v2c, out, work, out)


@njit(cache=True, inline="always")
def _lab_step_called(rhs, n, params, x, tau, h, v1c, v2c, out, work, _probe):  # type: ignore[no-untyped-def]
    return _lab_step_once(params, x, tau, h, v1c, v2c, out, work)


LAB_TRIAL_KERNEL = trial_kernel("car-lab-trials", LAB_LAYOUT, __name__, lab_field, lab_chart, _lab_step_called)
"""The lab robot's kernel that runs a batch's trials one by one (the lanes' is ``car_lab_lanes.LAB_KERNEL``)."""


@njit(cache=True)
def _substeps(params, x0, durations, steps, v1c, v2c, counts):  # type: ignore[no-untyped-def]
    """:func:`lab_substeps`'s compiled loop: each trial as the kernel runs it, its Runge-Kutta steps counted."""
    n = x0.shape[1]
    x, nxt = np.empty(n), np.empty(n)
    work = np.empty((STAGES + 1, n))
    for b in range(x0.shape[0]):
        x[:] = x0[b]
        counts[b] = 0
        for i in range(durations.shape[0]):
            h = durations[i] / steps[i]
            for k in range(steps[i]):
                counts[b] += _lab_step_once(params[b], x, k * h, h, v1c[b, i], v2c[b, i], nxt, work)
                if not (np.all(np.isfinite(nxt)) and lab_chart(params[b], nxt)):
                    break
                x[:] = nxt


def lab_substeps(params: Array, x0: Array, durations: Array, steps: Int, v1: Array, v2: Array) -> Int:
    """The Runge-Kutta steps each trial of a batch takes (on either kernel of the lab robot), to its
    last step on the chart: one a step, one more a substep after each event, and the event locator's
    probes (what a trial costs, counted). The arguments are
    :func:`~ilc_steering.core.integrate.integrate`'s."""
    params, x0, durations, steps, v1, v2 = checked_batch(LAB_TRIAL_KERNEL, params, x0, durations, steps, v1, v2)
    counts = np.zeros(x0.shape[0], dtype=np.int64)
    _substeps(params, x0, durations, steps, v1, v2, counts)
    return counts
