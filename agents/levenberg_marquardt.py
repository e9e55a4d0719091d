"""Levenberg-Marquardt on a model family's residuals, from many starts side by side.

The identifiers of ``newton_ilc`` and ``robust_ilc`` (:mod:`~ilc_steering.agents.identifier`) fit
a :class:`~ilc_steering.core.family.ModelFamily`'s parameters to the measured trials with it. The
residuals are batched, ``(M, size) -> (M, R)``: every start's probes of one round are one call of
the compiled kernel, and each start's fit is bit for bit the fit from that start alone.
"""

from __future__ import annotations

from collections.abc import Callable, Generator

import numpy as np
import numpy.typing as npt

__all__ = ["levenberg_marquardt", "levenberg_marquardt_many"]

Array = npt.NDArray[np.float64]


def levenberg_marquardt(
    residuals: Callable[[Array], Array],
    theta: Array,
    low: Array,
    high: Array,
    iterations: int,
    halvings: int = 8,
    done: Callable[[Array], bool] | None = None,
    stall: float = 0.0,
) -> tuple[Array, Array]:
    r"""Minimize :math:`\|r(\theta)\|^2` by Levenberg-Marquardt with central differences, ``theta``
    kept in ``[low, high]``; returns the estimate and its residual.

    ``residuals`` maps hypotheses ``(M, size)`` to residuals ``(M, R)`` (one batched call per
    iteration for the derivative). The damping starts at 1e-3 of the normal matrix's diagonal,
    is divided by 3 after a step that lowers the cost and multiplied by 4 after one that does not
    (at most ``halvings`` tries per iteration). Stops when no try lowers the cost, the step is
    below 1e-12, or ``done(r)``, or (``stall`` > 0) an iteration lowered the cost by at most ``stall``
    of it. :func:`levenberg_marquardt_many` of one start.
    """
    thetas, r = levenberg_marquardt_many(residuals, theta[None], low, high, iterations, halvings, done, stall)
    return thetas[0], r[0]


def levenberg_marquardt_many(
    residuals: Callable[[Array], Array],
    thetas: Array,
    low: Array,
    high: Array,
    iterations: int,
    halvings: int = 8,
    done: Callable[[Array], bool] | None = None,
    stall: float = 0.0,
) -> tuple[Array, Array]:
    """:func:`levenberg_marquardt` from each start of ``thetas`` ``(S, size)``, the starts side by
    side: each round, one ``residuals`` call holds what every running start asks next (its
    derivative's probes or its next damping try). Each start runs the one start's code
    (:func:`_levenberg_marquardt_start`) on its own rows, so its estimate and residual ``(S, size)``,
    ``(S, R)`` are bit for bit those of :func:`levenberg_marquardt` from it alone, provided a
    hypothesis's residual does not depend on the hypotheses beside it in the call (a simulation's
    does not: ``tests/test_purity.py``). With ``stall`` > 0 a start also stops after an iteration
    that lowers its cost by at most that fraction: at a minimum that does not explain the data
    (a plant outside the family) the iterations left only crawl along a flat valley."""
    runs = [_levenberg_marquardt_start(theta, low, high, iterations, halvings, done, stall) for theta in thetas]
    found: list[tuple[Array, Array]] = [(theta, theta) for theta in thetas]
    asks = {i: next(run) for i, run in enumerate(runs)}
    while asks:
        values = residuals(np.concatenate(list(asks.values())))
        begin, following = 0, {}
        for i, ask in asks.items():
            rows = values[begin : begin + len(ask)].copy()  # a fresh array, as the start alone gets
            begin += len(ask)
            try:
                following[i] = runs[i].send(rows)
            except StopIteration as stop:
                found[i] = stop.value
        asks = following
    return np.array([theta for theta, _ in found]), np.array([r for _, r in found])


def _levenberg_marquardt_start(
    theta: Array,
    low: Array,
    high: Array,
    iterations: int,
    halvings: int,
    done: Callable[[Array], bool] | None,
    stall: float = 0.0,
) -> Generator[Array, Array, tuple[Array, Array]]:
    """:func:`levenberg_marquardt` from ``theta``, as a generator: it yields the hypotheses whose
    residuals it needs next, is sent them, and returns the estimate and its residual."""
    h, damping = 1e-6, 1e-3
    eye = np.eye(theta.size)
    r = (yield theta[None])[0]
    for _ in range(iterations):
        cost = float(r @ r)
        values = yield np.concatenate([theta + h * eye, theta - h * eye])
        J = np.ascontiguousarray((values[: theta.size] - values[theta.size :]).T) / (2 * h)
        gradient, normal = J.T @ r, J.T @ J
        improved = False
        for _ in range(halvings):
            step = -np.linalg.solve(normal + damping * np.diag(np.diag(normal) + 1e-12), gradient)
            candidate = np.clip(theta + step, low, high)
            r_new = (yield candidate[None])[0]
            if r_new @ r_new < r @ r:
                theta, r, damping, improved = candidate, r_new, damping / 3, True
                break
            damping *= 4
        if not improved or np.max(np.abs(step)) < 1e-12 or (done is not None and done(r)):
            break
        if cost - float(r @ r) <= stall * cost:  # at a minimum that does not explain the data: it only crawls on
            break
    return theta, r
