"""The lab robot's kernel, :data:`LAB_KERNEL`: its trials in lanes of
:data:`~ilc_steering.core.kernels.LANES`, each lane on its own substeps.

A step of the lab robot splits at its events (:mod:`~ilc_steering.core.robots.car_lab_step`), almost
every step at an encoder pulse, each trial's at its own times. So the lanes do not keep step: in a
round every lane takes its next substep, from its own local time and of its own length, and the
Runge-Kutta stages of the round run across the lanes at once (:func:`_lanes_rk`, the same sums as
:func:`~ilc_steering.core.robots.car_lab.lab_rk`, so a lane's substep is the one-by-one kernel's to
the last bit). Between rounds each lane's events stay scalar, the one-by-one kernel's own pieces:
the substep's start (:func:`~ilc_steering.core.robots.car_lab_step.lab_begin`, the next pulse in
closed form) and end (:func:`~ilc_steering.core.robots.car_lab_step.lab_after`, a steering event
located by regula falsi on that lane alone). A lane that ends its step checks the chart, records and
starts its next; a lane that ends its trial leaves the stages, the lanes still running packed into
their first columns (a block's lanes end a quarter of the rounds apart: ``benchmarks/robots.py``'s
trials take 1.24 times their block's mean of substeps). What is fixed for a trial is set once, the
scratch allocated once per block.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ilc_steering.core import dop853
from ilc_steering.core.kernels import block_kernel
from ilc_steering.core.robots.car_lab import lab_chart, lab_field, lab_trial_constants
from ilc_steering.core.robots.car_lab_layout import (
    ANCHOR,
    BACKLASH,
    COS,
    EXTRA,
    GATE,
    LAB_LAYOUT,
    LIMIT,
    MOVING,
    PER_ELL,
    PER_SPEED_LAG,
    PER_STEERING_LAG,
    PSI,
    PULSES,
    SPEED_LAG,
    STEERING_LAG,
    TAN_HI,
    TAN_LIMIT,
    TAN_LO,
    TAN_REST,
    TAN_SERVO,
    TRUE_RHO,
    U1,
    U2_V1,
    U2_V2,
)
from ilc_steering.core.robots.car_lab_step import MAX_EVENTS, lab_after, lab_begin, lab_load, lab_store
from ilc_steering.core.stepper import LEFT_CHART, OK, STAGES, finite

__all__ = ["LAB_KERNEL"]

_A = np.ascontiguousarray(dop853.A)
_B = np.ascontiguousarray(dop853.B)
_C = np.ascontiguousarray(dop853.C)
_STEP = MOVING + 5  # the step state's length (car_lab_layout): the moving entries, the anchor, the estimate
_TERMS = (_A != 0.0).sum(axis=1)  # a stage's nonzero coefficients, and which
_TERM = np.zeros((STAGES, STAGES), dtype=np.int64)
for _s in range(STAGES):
    _TERM[_s, : _TERMS[_s]] = np.flatnonzero(_A[_s])
_READ = (2, 3, 4, 5, TAN_SERVO, COS)  # the moving entries _lanes_field reads
_T, _REMAINING, _H = range(3)  # a lane's clock: its local time [s], what is left of its step, the step
_WHICH, _PIECE, _K, _ROW, _EVENTS = range(5)  # its counts: last event, piece, step, recorded rows, substeps


@njit(cache=True, inline="always")
def _lanes_field(n, p, x, tmp, v1, v2, k):  # type: ignore[no-untyped-def]
    """:func:`~ilc_steering.core.robots.car_lab.lab_field` of every lane at once (the same arithmetic):
    ``p`` the lanes' rows ``(P + EXTRA, n)``, ``tmp`` the stage's moving entries ``(MOVING, n)``,
    ``x`` the substep's start (its anchor), ``v1`` and ``v2`` ``(n,)``; into ``k`` ``(MOVING, n)``."""
    for j in range(n):
        limit, lag, x3 = p[LIMIT, j], p[STEERING_LAG, j], tmp[3, j]
        inside = lag > 0 or abs(x3) < limit
        t = tmp[TAN_SERVO, j] if inside else np.copysign(p[TAN_LIMIT, j], x3)
        cos2 = 1.0 / (1.0 + t * t)
        if p[PULSES, j] > 0:
            u1, u2 = v1[j] * p[U1, j], cos2 * (p[U2_V1, j] * t * t * v1[j] + p[U2_V2, j] * v2[j])
        else:
            z = tmp[2, j]
            secant = np.sqrt(1.0 + z * z)
            u2 = cos2 * (p[U2_V1, j] * z * secant * t * t * v1[j] + p[U2_V2, j] * v2[j] / (secant * secant * secant))
            u1 = v1[j] * secant * p[U1, j]
        commanded = min(max(x3, -limit), limit)
        phi_s = tmp[4, j] if lag > 0 else commanded
        half, anchor = 0.5 * p[BACKLASH, j], x[ANCHOR, j]
        if anchor < phi_s - half:  # the play engaged, the servo pulling the wheel to its side
            tan_wheel = (t + p[TAN_LO, j]) / (1.0 - t * p[TAN_LO, j])
        elif anchor > phi_s + half:
            tan_wheel = (t + p[TAN_HI, j]) / (1.0 - t * p[TAN_HI, j])
        else:
            tan_wheel = p[TAN_REST, j]
        omega = tmp[5, j] if p[SPEED_LAG, j] > 0 else u1
        speed = p[TRUE_RHO, j] * omega
        z, c = tmp[2, j], tmp[COS, j]
        turn = tan_wheel * speed * p[PER_ELL, j]
        k[0, j] = c * speed
        k[1, j] = z * c * speed
        k[2, j] = (1.0 + z * z) * turn
        k[COS, j] = -z * c * turn
        k[3, j] = u2
        k[4, j] = (commanded - tmp[4, j]) * p[PER_STEERING_LAG, j]
        k[5, j] = (u1 - tmp[5, j]) * p[PER_SPEED_LAG, j]
        k[PSI, j] = omega
        if lag > 0:
            k[TAN_SERVO, j] = (1.0 + t * t) * k[4, j]
        else:
            s = tmp[TAN_SERVO, j]
            k[TAN_SERVO, j] = (1.0 + s * s) * u2 if abs(x3) < p[GATE, j] else 0.0


@njit(cache=True, inline="always")
def _lanes_rk(n, p, x, tau, h, c1, c2, out, kst, tmp, v1, v2, times):  # type: ignore[no-untyped-def]
    """A Runge-Kutta substep of every lane, lane ``j``'s of length ``h[j]`` from local time ``tau[j]``
    (0: it rests), the moving entries of ``x`` ``(MOVING + 1, n)`` into ``out`` ``(MOVING, n)``;
    ``c1`` and ``c2`` ``(D, n)`` the lanes' inputs; ``kst``, ``tmp``, ``v1``, ``v2``, ``times`` scratch."""
    for s in range(STAGES):
        for j in range(n):  # the inputs at the stage's time, by Horner's rule (poly's sums), lane by lane
            times[j] = tau[j] + _C[s] * h[j]
            v1[j] = 0.0
            v2[j] = 0.0
        for d in range(c1.shape[0] - 1, -1, -1):
            for j in range(n):
                v1[j] = v1[j] * times[j] + c1[d, j]
        for d in range(c2.shape[0] - 1, -1, -1):
            for j in range(n):
                v2[j] = v2[j] * times[j] + c2[d, j]
        for i in _READ:  # a stage's state: the entries the field reads (x, y and psi it does not)
            for j in range(n):
                tmp[i, j] = 0.0
            for m in range(s):
                a = _A[s, m]
                if a != 0.0:
                    for j in range(n):
                        tmp[i, j] += a * kst[m, i, j]
            for j in range(n):
                tmp[i, j] = x[i, j] + h[j] * tmp[i, j]
        _lanes_field(n, p, x, tmp, v1, v2, kst[s])
    for i in range(MOVING):
        for j in range(n):
            out[i, j] = 0.0
    for s in range(STAGES):
        b = _B[s]
        if b != 0.0:
            for i in range(MOVING):
                for j in range(n):
                    out[i, j] += b * kst[s, i, j]
    for i in range(MOVING):
        for j in range(n):
            out[i, j] = x[i, j] + h[j] * out[i, j]


@njit(cache=True, inline="always")
def _start_step(j, slot, b, rows, last, cur, sides, c1, c2, clock, count, durations, steps, v1c, v2c):  # type: ignore[no-untyped-def]
    """Lane ``j`` (trial ``b``, the stages' column ``slot``) at the start of its step ``count[j, _K]`` of
    its piece, from ``last[j]``."""
    q = count[j, _PIECE]
    h = durations[q] / steps[q]
    clock[j, _T], clock[j, _REMAINING], clock[j, _H] = count[j, _K] * h, h, h
    count[j, _WHICH], count[j, _EVENTS] = -1, 0
    sides[j, 0] = sides[j, 1] = sides[j, 3] = 0.0
    lab_load(rows[j], last[j], cur[j])
    for d in range(c1.shape[0]):
        c1[d, slot] = v1c[b, q, d]
    for d in range(c2.shape[0]):
        c2[d, slot] = v2c[b, q, d]


@njit(cache=True, inline="always")
def _end_step(j, b, rows, cur, last, stored, out, status, traj, count, steps, durations, record):  # type: ignore[no-untyped-def]
    """Lane ``j``'s (trial ``b``'s) step ended: its state checked against the chart and recorded, and
    whether the trial goes on (else its final state in ``out`` and its status, ``LEFT_CHART`` off the chart)."""
    lab_store(rows[j], cur[j], stored)
    if not (finite(stored) and lab_chart(rows[j], stored)):
        status[b] = LEFT_CHART
        out[b] = last[j]
        if record:
            for r in range(count[j, _ROW], traj.shape[1]):
                traj[b, r] = last[j]
        return False
    last[j] = stored
    if record:
        traj[b, count[j, _ROW]] = stored
        count[j, _ROW] += 1
    count[j, _K] += 1
    if count[j, _K] == steps[count[j, _PIECE]]:
        count[j, _PIECE] += 1
        count[j, _K] = 0
    if count[j, _PIECE] == durations.shape[0]:
        out[b] = stored
        return False
    return True


@njit(cache=True, inline="always")
def _lab_block(n, params, x0, durations, steps, v1c, v2c, out, status, traj, start, stop):  # type: ignore[no-untyped-def]
    """Trials ``start:stop`` (at most ``n``) of a batch, a lane each: the arguments of
    :func:`ilc_steering.core.integrate.integrate`'s kernels. The stages run on the first ``m`` columns,
    the lanes still running (``order``: column -> lane), packed as lanes end."""
    size, used, record = params.shape[1] + EXTRA, stop - start, traj.shape[1] > 0
    rows = np.empty((n, size))  # each lane's row and what is fixed past it, for its scalar pieces
    p = np.empty((size, n))  # the same, column by column, for the stages
    cur = np.empty((n, _STEP))  # each lane's step state, its substep's end, its state at the step's start
    nxt = np.empty((n, _STEP))
    last = np.empty((n, x0.shape[1]))
    x = np.empty((MOVING + 1, n))  # the round's start (the moving entries and the anchor), its end
    end = np.empty((MOVING, n))
    kst = np.empty((STAGES, MOVING, n))
    tmp = np.empty((MOVING, n))
    sides = np.zeros((n, 4))
    coef = np.empty((n, 3, v1c.shape[2] + 1))
    c1 = np.empty((v1c.shape[2], n))  # the lanes' inputs, coefficient by coefficient
    c2 = np.empty((v2c.shape[2], n))
    v1, v2, tau, h, times = np.empty(n), np.empty(n), np.empty(n), np.zeros(n), np.empty(n)
    clock = np.empty((n, 3))  # each lane's local time, what is left of its step, its step's length
    count = np.zeros((n, 5), dtype=np.int64)  # its last event, piece, step, recorded rows, substeps
    order = np.arange(n)
    stored, probe, work = np.empty(x0.shape[1]), np.empty(_STEP), np.empty((STAGES + 1, _STEP))
    for j in range(used):
        b = start + j
        rows[j, : params.shape[1]] = params[b]
        lab_trial_constants(rows[j])
        p[:, j] = rows[j]
        last[j] = x0[b]
        status[b] = OK
        if record:
            traj[b, 0] = x0[b]
        count[j, _ROW] = 1
        _start_step(j, j, b, rows, last, cur, sides, c1, c2, clock, count, durations, steps, v1c, v2c)
    m = used
    while m > 0:
        for s in range(m):  # each lane's substep: its start, its length
            j = order[s]
            b, q, t = start + j, count[j, _PIECE], clock[j, _T]
            count[j, _WHICH], h[s] = lab_begin(
                rows[j], cur[j], sides[j], coef[j], t, clock[j, _REMAINING], count[j, _WHICH], v1c[b, q], v2c[b, q]
            )
            tau[s] = t
            for i in range(MOVING + 1):
                x[i, s] = cur[j, i]
            for i in (U1, U2_V1, U2_V2, TAN_REST):  # what lab_begin may have moved
                p[i, s] = rows[j, i]
        _lanes_rk(m, p, x, tau, h, c1, c2, end, kst, tmp, v1, v2, times)
        kept = 0
        for s in range(m):  # each lane's substep's end: its events, and its step's end
            j = order[s]
            b, q = start + j, count[j, _PIECE]
            for i in range(MOVING):
                nxt[j, i] = end[i, s]
            for i in range(MOVING, _STEP):
                nxt[j, i] = cur[j, i]
            which, advance = lab_after(
                lab_field,
                rows[j],
                cur[j],
                nxt[j],
                probe,
                work,
                sides[j],
                tau[s],
                h[s],
                count[j, _WHICH],
                clock[j, _H],
                v1c[b, q],
                v2c[b, q],
            )
            count[j, _WHICH] = which
            clock[j, _T] += advance
            clock[j, _REMAINING] -= advance
            count[j, _EVENTS] += 1
            running = True
            if which < 0 or clock[j, _REMAINING] <= 0.0 or count[j, _EVENTS] >= MAX_EVENTS:
                running = _end_step(j, b, rows, cur, last, stored, out, status, traj, count, steps, durations, record)
                if running:
                    _start_step(j, s, b, rows, last, cur, sides, c1, c2, clock, count, durations, steps, v1c, v2c)
            if running:  # packed into the first columns, in order
                if kept != s:
                    order[kept] = j
                    p[:, kept] = p[:, s]
                    c1[:, kept] = c1[:, s]
                    c2[:, kept] = c2[:, s]
                kept += 1
        m = kept


LAB_KERNEL = block_kernel("car-lab", LAB_LAYOUT, __name__, _lab_block, "numpy", packs=True)
"""The lab robot's kernel (a servo car's too, its play and encoders off)."""
