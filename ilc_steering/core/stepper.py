"""The integrator's compiled core, shared by every robot's field: one Runge-Kutta step, one event
locator, one driver.

The method is the 8th-order, 12-stage Dormand-Prince tableau (the one behind scipy's DOP853),
run with a fixed step: on the paper's tasks a step of 1/32 s lands within 1e-9 of an adaptive
DOP853 reference at rtol = atol = 1e-12 (``tests/test_integrate.py``; ``benchmarks/integrator.py``
measures accuracy and speed against the step). The inputs are piecewise polynomials in each
piece's local time (from an input profile), and every piece boundary is a step boundary, so no
step straddles a jump of ``v1`` or ``v2``.

Everything here is ``inline="always"``: :mod:`ilc_steering.core.kernels` compiles a robot's
runners from these pieces and the robot's own field, chart test and step, so that a field, its
state dimension and its layout are constants of one compiled function and the compiler keeps the
state in registers. The field, step and chart functions are handed to the pieces as arguments;
numba inlines them at compile time, so no function value reaches numba's cache (where a second
process would misread it).

Chart guard: a step that ends outside the robot's chart (for the car: ``|theta|`` or ``|phi|``
within ``CHART_MARGIN`` of ``pi/2``, where eqs. 4-5 break down; a stiff step can throw ``theta``
far past it), or with a non-finite state, is discarded and the trial stops with status
``LEFT_CHART``: the robot halts at its last valid configuration.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

import numba
import numpy as np
from numba import njit

from ilc_steering.core import dop853
from ilc_steering.core.plants import CHART_MARGIN

__all__ = [
    "CHART_LIMIT",
    "LEFT_CHART",
    "OK",
    "announce_compile",
    "drive",
    "finite",
    "lanes_rk",
    "locate",
    "poly",
    "rk_step",
    "rk_step_on",
    "step_with_stop",
]

OK = 0
LEFT_CHART = 1
CHART_LIMIT = np.pi / 2 - CHART_MARGIN
"""[rad] the largest ``|angle|`` a chart test lets a trial reach."""
MAX_ITERATIONS = 60
"""Of the event locator; a crossing of the steering limit needs about 23."""
STAGES = dop853.STAGES
_A = np.ascontiguousarray(dop853.A)
_B = np.ascontiguousarray(dop853.B)
_C = np.ascontiguousarray(dop853.C)


@njit(cache=True, inline="always")
def poly(coef, tau):  # type: ignore[no-untyped-def]
    """The polynomial ``coef`` (lowest degree first) at ``tau``, by Horner's rule."""
    acc = 0.0
    for d in range(coef.shape[0] - 1, -1, -1):
        acc = acc * tau + coef[d]
    return acc


@njit(cache=True, inline="always")
def rk_step(rhs, n, params, x, tau, h, v1c, v2c, out, work):  # type: ignore[no-untyped-def]
    """One step of length ``h`` from local time ``tau`` of ``x' = rhs(params, x, v1, v2)`` into
    ``out``; ``work`` ``(STAGES + 1, n)`` holds the stages and a scratch row."""
    tmp = work[STAGES]
    for s in range(STAGES):
        for i in range(n):
            acc = 0.0
            for j in range(s):
                acc += _A[s, j] * work[j, i]
            tmp[i] = x[i] + h * acc
        t = tau + _C[s] * h
        rhs(params, tmp, poly(v1c, t), poly(v2c, t), work[s])
    for i in range(n):
        acc = 0.0
        for s in range(STAGES):
            acc += _B[s] * work[s, i]
        out[i] = x[i] + h * acc


@njit(cache=True, inline="always")
def rk_step_on(rhs, moving, params, x, tau, h, v1c, v2c, out, work):  # type: ignore[no-untyped-def]
    """:func:`rk_step` of a field whose entries outside ``moving`` (an array of indices) have zero
    derivative (the lab robot's estimate, between its jumps): those are carried over as they are,
    the others combined exactly as :func:`rk_step` combines them."""
    tmp = work[STAGES]
    for i in range(x.shape[0]):
        tmp[i] = x[i]
        out[i] = x[i]
    for s in range(STAGES):
        for i in moving:
            acc = 0.0
            for j in range(s):
                acc += _A[s, j] * work[j, i]
            tmp[i] = x[i] + h * acc
        t = tau + _C[s] * h
        rhs(params, tmp, poly(v1c, t), poly(v2c, t), work[s])
    for i in moving:
        acc = 0.0
        for s in range(STAGES):
            acc += _B[s] * work[s, i]
        out[i] = x[i] + h * acc


@njit(cache=True, inline="always")
def locate(event, step, state, g_lo, g_hi, span, tolerance, start_positive, zero_fires):  # type: ignore[no-untyped-def]
    """Where an event happens within a step: Illinois regula falsi on ``g(s) = event(step, state, s)``
    (the event's value after a substep of length ``s``), from ``g(0) = g_lo`` and ``g(span) = g_hi``
    on either side of it.

    A point is on the start's side when ``(g > 0) == start_positive``; the bracket ``[lo, hi]``
    keeps the change of side and narrows to ``tolerance`` [s] (at most :data:`MAX_ITERATIONS`
    iterations; about 23 where bisection takes 54). With ``zero_fires``, a point where ``g`` is 0
    is on the event, and the event a hair (``tolerance``) later. Returns ``hi``, the first substep
    length found past the event.
    """
    lo, hi, side = 0.0, span, 0
    for _ in range(MAX_ITERATIONS):
        if hi - lo <= tolerance:
            break
        mid = (lo * g_hi - hi * g_lo) / (g_hi - g_lo)
        if not (lo < mid < hi):
            mid = 0.5 * (lo + hi)
        g_mid = event(step, state, mid)
        if zero_fires and g_mid == 0.0:
            return min(mid + tolerance, hi)
        if (g_mid > 0) == start_positive:
            lo, g_lo = mid, g_mid
            if side == -1:
                g_hi *= 0.5
            side = -1
        else:
            hi, g_hi = mid, g_mid
            if side == 1:
                g_lo *= 0.5
            side = 1
    return hi


@njit(cache=True, inline="always")
def _stop_event(rhs, state, s):  # type: ignore[no-untyped-def]
    """``|x[index]| - limit`` after a substep of length ``s``."""
    n, params, x, tau, v1c, v2c, probe, work, index, limit = state
    rk_step(rhs, n, params, x, tau, s, v1c, v2c, probe, work)
    return abs(probe[index]) - limit


@njit(cache=True, inline="always")
def step_with_stop(rhs, n, params, x, tau, h, v1c, v2c, out, work, probe, index, limit):  # type: ignore[no-untyped-def]
    """One step from local time ``tau``, split where ``|x[index]|`` (a steering command) crosses
    ``limit`` (the stop, where the field has a kink), so such a step keeps the method's accuracy."""
    rk_step(rhs, n, params, x, tau, h, v1c, v2c, out, work)
    beyond = abs(x[index]) > limit
    if (abs(out[index]) > limit) == beyond:
        return
    state = (n, params, x, tau, v1c, v2c, probe, work, index, limit)
    g_lo, g_hi = abs(x[index]) - limit, abs(out[index]) - limit
    hi = locate(_stop_event, rhs, state, g_lo, g_hi, h, 4e-16 * h, beyond, False)
    rk_step(rhs, n, params, x, tau, hi, v1c, v2c, probe, work)
    rk_step(rhs, n, params, probe, tau + hi, h - hi, v1c, v2c, out, work)


@njit(cache=True, inline="always")
def lanes_rk(field, nx, n, p, x, tau, h, coef1, coef, out, kst, tmp, v1, v2):  # type: ignore[no-untyped-def]
    """One step of length ``h`` from local time ``tau`` of ``n`` trials at once, laid out lane by lane:
    ``x`` and ``out`` ``(nx, n)``, ``p`` the lanes' parameters ``(P, n)``, ``coef1`` ``(n, D1)`` and
    ``coef`` ``(n, D)`` the piece's inputs ``v1`` and ``v2`` (lowest degree first); ``kst``
    ``(STAGES, nx, n)``, ``tmp`` ``(nx, n)``, ``v1`` and ``v2`` ``(n,)`` scratch.
    ``field(p, j, state, v1, v2, k)`` writes lane ``j``'s derivative into ``k[:, j]``. Every inner
    loop runs over the lanes, so a field without transcendental functions vectorizes."""
    degree, degree1 = coef.shape[1] - 1, coef1.shape[1] - 1
    for st in range(STAGES):
        t = tau + _C[st] * h
        for j in range(n):
            acc = coef[j, degree]
            for d in range(degree - 1, -1, -1):
                acc = acc * t + coef[j, d]
            v2[j] = acc
            acc = coef1[j, degree1]
            for d in range(degree1 - 1, -1, -1):
                acc = acc * t + coef1[j, d]
            v1[j] = acc
        for i in range(nx):
            for j in range(n):
                tmp[i, j] = x[i, j]
        for m in range(st):
            ah = _A[st, m] * h
            if ah != 0.0:
                for i in range(nx):
                    for j in range(n):
                        tmp[i, j] += ah * kst[m, i, j]
        k = kst[st]
        for j in range(n):
            field(p, j, tmp, v1[j], v2[j], k)
    for i in range(nx):
        for j in range(n):
            out[i, j] = x[i, j]
    for st in range(STAGES):
        bh = _B[st] * h
        if bh != 0.0:
            for i in range(nx):
                for j in range(n):
                    out[i, j] += bh * kst[st, i, j]


@njit(cache=True, inline="always")
def finite(x):  # type: ignore[no-untyped-def]
    """Whether every entry of ``x`` is finite."""
    for value in x:
        if not np.isfinite(value):
            return False
    return True


@njit(cache=True, inline="always")
def drive(rhs, step, chart, n, params, x0, durations, steps, v1c, v2c, out, traj):  # type: ignore[no-untyped-def]
    """One trial of the field ``rhs`` from ``x0`` (``n`` states), stepped by ``step(rhs, n, params,
    x, tau, h, v1c, v2c, out, work, probe)`` over ``steps[i]`` equal steps of each piece ``i``; a
    step whose end fails ``chart(params, x)`` or is not finite halts the trial at its last state.
    Writes the final state to ``out`` (and every step's to ``traj``, unless it has no rows) and
    returns ``OK`` or ``LEFT_CHART``."""
    x = x0.copy()
    nxt = np.empty(n)
    probe = np.empty(n)
    work = np.empty((STAGES + 1, n))
    record = traj.shape[0] > 0
    if record:
        traj[0] = x
    row = 1
    for i in range(durations.shape[0]):
        h = durations[i] / steps[i]
        for k in range(steps[i]):
            step(rhs, n, params, x, k * h, h, v1c[i], v2c[i], nxt, work, probe)
            if not (finite(nxt) and chart(params, nxt)):
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


_READY: set[Any] = set()  # compiled functions this process has run: no announcement to consider
_ANNOUNCED: set[str] = set()  # simulators whose compilation this process has said


def announce_compile(function: Any, name: str) -> None:
    """Say so on stderr when the first call of ``function`` (a compiled entry point; anything else
    is ignored) will compile, because numba's cache of this install has none yet: it takes 5-20 s
    once, then about 0.2 s per process. ``name`` says which simulator."""
    if function in _READY or not hasattr(function, "py_func"):
        return
    _READY.add(function)
    if function.overloads:  # compiled (or loaded) in this process already
        return
    cached = function.py_func.__qualname__
    module = Path(function.py_func.__code__.co_filename)
    cache_dir = getattr(numba.config, "CACHE_DIR", "")
    folder = Path(cache_dir) if cache_dir else module.parent / "__pycache__"
    if folder.is_dir() and any(folder.rglob(f"{module.stem}.{cached}-*.nbi")):
        return
    if name in _ANNOUNCED:  # another entry point of the same simulator (its serial and its batched runners)
        return
    _ANNOUNCED.add(name)
    print(
        f"ilc-steering: compiling the {name} simulator once for this install (numba), then it is cached ...",
        file=sys.stderr,
        flush=True,
    )
