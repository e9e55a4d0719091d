"""The car's batched kernel: eqs. 3-5 in tangent coordinates, integrated across trials at once.

The closed-loop car (eq. 3 with the true geometry, driven by eqs. 4-5 with the nominal one) is
integrated in the variables ``(x, y, s, w)`` with ``s = tan(theta)`` and ``w = tan(phi)``. With
``k = rho~/rho``, ``r = sqrt(1 + s^2)``, ``ell`` the nominal and ``ell~`` the true wheelbase:

    x' = k v1,   y' = k v1 s,   s' = k v1 w r^3 / ell~,   w' = -(3 / ell) s r w^2 v1 + ell v2 / r^3

(``x' = cos(theta) u1 rho~`` with ``u1 = v1 / (rho cos(theta))``; ``s' = theta' / cos^2(theta)``;
``w' = phi' / cos^2(phi)`` with eq. 5's ``phi'``). One square root and no trigonometry per
evaluation, so the compiler vectorizes the field across trials: the trials of a batch are laid
out lane by lane (:data:`~ilc_steering.core.kernels.LANES` per block) and every stage of the step runs over the block's
lanes at once.

Steering limit: the fourth state is ``sigma``, a C^1 monotone extension of ``tan(phi_c)`` past
the stop at ``|phi_c| = lim``: ``sigma = tan(phi_c)`` inside, ``sign(phi_c) (W + (1 + W^2)
(|phi_c| - lim))`` outside, with ``W = tan(lim)``. The wheel is at ``w = clip(sigma, -W, W)``,
and ``sigma' = w'`` evaluated at that ``w`` holds on both sides (outside, ``phi_c' = u2`` at the
stop and ``d sigma / d phi_c = 1 + W^2 = 1 / cos^2(lim)``). So the servo model of
:mod:`ilc_steering.core.robots.car_fields` (the command winds on at the stop) is the same ODE, in other
coordinates. A step whose ``|sigma|`` crosses ``W`` is redone for that lane alone, split at the
crossing located by Illinois regula falsi, as the angle kernel does.

Chart guard and halting as in :mod:`ilc_steering.core.stepper`: ``|theta|`` or the wheel's
``|phi|`` within ``CHART_MARGIN`` of ``pi/2``, or a non-finite state, halts the lane at its last
valid state with status ``LEFT_CHART``.

Each trial has its own parameters (a row of ``params``), so one call runs a batch of different
plants: the robustness sweep's grid of true geometries is one call per trial index.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
from numba import njit

from ilc_steering.core import dop853
from ilc_steering.core.kernels import LANES, block_kernel
from ilc_steering.core.plants import CHART_MARGIN, KernelLayout
from ilc_steering.core.stepper import LEFT_CHART, OK, locate

# The compiled blocks read their arrays unchecked: they are reached through KERNEL, by
# ilc_steering.core.integrate.integrate, which checks them against CAR_LAYOUT first.
__all__ = ["CAR_LAYOUT", "KERNEL", "LANES"]

Array = npt.NDArray[np.float64]

CAR_LAYOUT = KernelLayout(
    ("x", "y", "theta", "phi_c"), ("wheelbase", "wheel_radius", "true_wheelbase", "true_wheel_radius", "steering_limit")
)
"""The car's state (the angle form; the kernel works in ``(x, y, tan theta, sigma)`` inside) and
parameter row: the nominal geometry (eqs. 4-5), the true one (eq. 3), the stop (``inf``: none)."""
_ELL, _RHO, _TRUE_ELL, _TRUE_RHO, _LIMIT = (CAR_LAYOUT.index(name) for name in CAR_LAYOUT.params)
_T_CHART = float(np.tan(np.pi / 2 - CHART_MARGIN))  # |tan| of the chart's edge
# How closely a crossing of the stop is located, relative to the step: a kink misplaced by ds costs
# O(ds^2), so 1e-10 is below 1e-12 of error (tests/test_integrate.py) and takes half the iterations.
_CROSSING_TIME = 1e-10
_STAGES = dop853.STAGES
_A = np.ascontiguousarray(dop853.A)
_B = np.ascontiguousarray(dop853.B)
_C = np.ascontiguousarray(dop853.C)


@njit(cache=True, inline="always")
def _field(k, a, b3, ell, big_w, s, sigma, v1, v2):  # type: ignore[no-untyped-def]
    """``(x', y', s', sigma')`` of one trial; ``k = rho~/rho``, ``a = k / ell~``, ``b3 = 3 / ell``."""
    w = min(max(sigma, -big_w), big_w)
    r2 = 1.0 + s * s
    r = np.sqrt(r2)
    kv = k * v1
    return kv, kv * s, a * v1 * w * r2 * r, -b3 * s * r * w * w * v1 + ell * v2 / (r2 * r)


# No closures here: numba names a compiled function by its qualified name, so two closures of
# one function (a step of 1 lane and one of 64) compile to the same symbol, and a process that
# loads one from the cache and compiles the other links one in place of the other (heap
# corruption, seen in the wild; ilc_steering.core.kernels names each robot's runners apart). Each
# lane count is its own module-level function around an inlined body, where the count is a
# constant the compiler folds.
@njit(cache=True, inline="always")
def _rk(n, p, x, tau, h, coef1, coef, out, kst, tmp, v1, v2):  # type: ignore[no-untyped-def]
    """One step of length ``h`` from local time ``tau`` of every lane: ``p`` the
    derived parameters ``(6, n)``, ``x`` and ``out`` the states ``(4, n)``, ``coef1`` ``(n, D1)``
    and ``coef`` ``(n, D)`` the piece's inputs ``v1`` and ``v2`` (polynomials in local time,
    lowest degree first); ``kst``, ``tmp``, ``v1`` and ``v2`` scratch. Every inner
    loop runs over the lanes (the compiler vectorizes it), with the four states written out."""
    degree, degree1 = coef.shape[1] - 1, coef1.shape[1] - 1
    for st in range(_STAGES):
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
            tmp[0, j] = x[0, j]
            tmp[1, j] = x[1, j]
            tmp[2, j] = x[2, j]
            tmp[3, j] = x[3, j]
        for m in range(st):
            ah = _A[st, m] * h
            if ah != 0.0:
                for j in range(n):
                    tmp[0, j] += ah * kst[m, 0, j]
                    tmp[1, j] += ah * kst[m, 1, j]
                    tmp[2, j] += ah * kst[m, 2, j]
                    tmp[3, j] += ah * kst[m, 3, j]
        for j in range(n):
            f0, f1, f2, f3 = _field(p[0, j], p[1, j], p[2, j], p[3, j], p[4, j], tmp[2, j], tmp[3, j], v1[j], v2[j])
            kst[st, 0, j] = f0
            kst[st, 1, j] = f1
            kst[st, 2, j] = f2
            kst[st, 3, j] = f3
    for j in range(n):
        out[0, j] = x[0, j]
        out[1, j] = x[1, j]
        out[2, j] = x[2, j]
        out[3, j] = x[3, j]
    for st in range(_STAGES):
        bh = _B[st] * h
        if bh != 0.0:
            for j in range(n):
                out[0, j] += bh * kst[st, 0, j]
                out[1, j] += bh * kst[st, 1, j]
                out[2, j] += bh * kst[st, 2, j]
                out[3, j] += bh * kst[st, 3, j]


@njit(cache=True)
def _rk_one(p, x, tau, h, coef1, coef, out, kst, tmp, v1, v2):  # type: ignore[no-untyped-def]
    """:func:`_rk` of one lane."""
    _rk(1, p, x, tau, h, coef1, coef, out, kst, tmp, v1, v2)


@njit(cache=True)
def _rk_block(p, x, tau, h, coef1, coef, out, kst, tmp, v1, v2):  # type: ignore[no-untyped-def]
    """:func:`_rk` of a block of :data:`LANES` lanes."""
    _rk(LANES, p, x, tau, h, coef1, coef, out, kst, tmp, v1, v2)


@njit(cache=True, inline="always")
def _sigma_after(step, state, s):  # type: ignore[no-untyped-def]
    """``|sigma| - W`` of one lane after a substep of length ``s``."""
    p, x, tau, coef1, coef, probe, kst, tmp, v1, v2, big_w = state
    step(p, x, tau, s, coef1, coef, probe, kst, tmp, v1, v2)
    return abs(probe[3, 0]) - big_w


@njit(cache=True)
def _split_at_limit(p, x, tau, h, coef1, coef, out):  # type: ignore[no-untyped-def]
    """Redo the step of one lane (arrays of one column) from ``x`` to ``out`` whose ``|sigma|``
    crossed the stop ``W``: two steps, split where it crosses."""
    big_w = p[4, 0]
    beyond = abs(x[3, 0]) > big_w
    probe = np.empty((4, 1))
    kst = np.empty((_STAGES, 4, 1))
    tmp = np.empty((4, 1))
    v1 = np.empty(1)
    v2 = np.empty(1)
    g_lo, g_hi = abs(x[3, 0]) - big_w, abs(out[3, 0]) - big_w
    state = (p, x, tau, coef1, coef, probe, kst, tmp, v1, v2, big_w)
    hi = locate(_sigma_after, _rk_one, state, g_lo, g_hi, h, _CROSSING_TIME * h, beyond, False)
    _rk_one(p, x, tau, hi, coef1, coef, probe, kst, tmp, v1, v2)
    _rk_one(p, probe, tau + hi, h - hi, coef1, coef, out, kst, tmp, v1, v2)


@njit(cache=True, inline="always")
def _angle(p, x, lane, dst):  # type: ignore[no-untyped-def]
    """The block state of ``lane`` as ``(x, y, theta, phi_c)`` into ``dst``."""
    big_w = p[4, lane]
    dst[0] = x[0, lane]
    dst[1] = x[1, lane]
    dst[2] = np.arctan(x[2, lane])
    sig = x[3, lane]
    if abs(sig) <= big_w:
        dst[3] = np.arctan(sig)
    else:
        dst[3] = np.sign(sig) * (p[5, lane] + (abs(sig) - big_w) / (1.0 + big_w * big_w))


@njit(cache=True, inline="always")
def _block(n, params, x0, durations, steps, v1c, v2c, out, status, traj, start, stop):  # type: ignore[no-untyped-def]
    """Trials ``start:stop`` (at most ``n``) of a batch, laid out lane by lane: the arguments
    are those of :func:`ilc_steering.core.integrate.integrate`'s kernels, with ``params``
    ``(B, 5)``, a row of :data:`CAR_LAYOUT` per trial. Lanes past ``stop`` repeat its last trial
    and are dropped."""
    p = np.empty((6, n))  # per lane: k, a, b3, ell, W, lim
    x = np.empty((4, n))
    nxt = np.empty((4, n))
    tmp = np.empty((4, n))
    kst = np.empty((_STAGES, 4, n))
    v1 = np.empty(n)
    v2 = np.empty(n)
    coef1 = np.empty((n, v1c.shape[2]))
    coef = np.empty((n, v2c.shape[2]))
    alive = np.empty(n, dtype=np.bool_)
    lane_p = np.empty((6, 1))
    lane_x = np.empty((4, 1))
    lane_out = np.empty((4, 1))
    lane_coef = np.empty((1, v2c.shape[2]))
    lane_coef1 = np.empty((1, v1c.shape[2]))
    record = traj.shape[1] > 0
    used = stop - start
    for j in range(n):
        b = start + min(j, used - 1)
        ell, rho, true_ell, true_rho = params[b, _ELL], params[b, _RHO], params[b, _TRUE_ELL], params[b, _TRUE_RHO]
        lim = params[b, _LIMIT]
        k = true_rho / rho
        big_w = np.tan(lim) if lim < np.pi / 2 else np.inf
        p[0, j], p[1, j], p[2, j], p[3, j], p[4, j], p[5, j] = k, k / true_ell, 3.0 / ell, ell, big_w, lim
        x[0, j], x[1, j], x[2, j] = x0[b, 0], x0[b, 1], np.tan(x0[b, 2])
        phi = x0[b, 3]
        if abs(phi) <= lim:
            x[3, j] = np.tan(phi)
        else:
            x[3, j] = np.sign(phi) * (big_w + (1.0 + big_w * big_w) * (abs(phi) - lim))
        alive[j] = True
    for j in range(used):
        status[start + j] = OK
        if record:
            _angle(p, x, j, traj[start + j, 0])
    row = 1
    for piece in range(durations.shape[0]):
        step_h = durations[piece] / steps[piece]
        for j in range(n):
            b = start + min(j, used - 1)
            for d in range(coef1.shape[1]):
                coef1[j, d] = v1c[b, piece, d]
            for d in range(coef.shape[1]):
                coef[j, d] = v2c[b, piece, d]
        for step in range(steps[piece]):
            tau = step * step_h
            if n == 1:
                _rk_one(p, x, tau, step_h, coef1, coef, nxt, kst, tmp, v1, v2)
            else:
                _rk_block(p, x, tau, step_h, coef1, coef, nxt, kst, tmp, v1, v2)
            for j in range(used):
                if not alive[j]:
                    continue
                big_w = p[4, j]
                if (abs(x[3, j]) > big_w) != (abs(nxt[3, j]) > big_w):
                    for i in range(6):
                        lane_p[i, 0] = p[i, j]
                    for i in range(4):
                        lane_x[i, 0] = x[i, j]
                        lane_out[i, 0] = nxt[i, j]
                    for d in range(coef.shape[1]):
                        lane_coef[0, d] = coef[j, d]
                    for d in range(coef1.shape[1]):
                        lane_coef1[0, d] = coef1[j, d]
                    _split_at_limit(lane_p, lane_x, tau, step_h, lane_coef1, lane_coef, lane_out)
                    for i in range(4):
                        nxt[i, j] = lane_out[i, 0]
                finite = True
                for i in range(4):
                    if not np.isfinite(nxt[i, j]):
                        finite = False
                wheel = min(abs(nxt[3, j]), big_w)
                if finite and abs(nxt[2, j]) < _T_CHART and wheel < _T_CHART:
                    for i in range(4):
                        x[i, j] = nxt[i, j]
                else:
                    alive[j] = False
                    status[start + j] = LEFT_CHART
            if record:
                for j in range(used):
                    _angle(p, x, j, traj[start + j, row])
                row += 1
    for j in range(used):
        _angle(p, x, j, out[start + j])


KERNEL = block_kernel("batched car", CAR_LAYOUT, __name__, _block)
"""The car without servo perturbations, in tangent coordinates."""
