r"""The parts the model-based learners share: a trial record, Levenberg-Marquardt on the model
family, Newton's method with backtracking, the Broyden update and the box projections.

``newton_ilc`` and ``robust_ilc`` are compositions of these; each keeps its own policy (which
trials to fit, where Newton starts, when to fall back). Everything here sees only the nominal
model (through a :class:`~ilc_steering.core.family.ModelFamily`) and the measured trials.
"""

from __future__ import annotations

from collections.abc import Callable, Generator, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from ilc_steering.agents.ilc import ILCAgent
from ilc_steering.core.family import ModelFamily
from ilc_steering.core.nominal import NominalModel
from ilc_steering.core.scatter import FLOOR, MIN_SCATTER, MIN_TRIALS, estimate, repeats

__all__ = [
    "BAND",
    "Trial",
    "box",
    "broyden_update",
    "final_chained",
    "gauss_newton",
    "in_scatter_band",
    "law_step",
    "levenberg_marquardt",
    "levenberg_marquardt_many",
    "measure",
    "newton_solve",
    "scatter_groups",
    "shown_to_repeat",
    "trial_scatter",
    "trust_box",
    "within_scatter",
]

Array = npt.NDArray[np.float64]
Mask = npt.NDArray[np.bool_]


@dataclass
class Trial:
    """One measured trial."""

    c: Array
    """The coefficients it ran."""
    z: Array
    """Its measured final chained coordinates (meaningless if it left the chart)."""
    q: Array
    """Its measured final configuration (NaN if it left the chart)."""
    error: float
    """The norm of the measured configuration error [m and rad] (inf if it left the chart)."""
    ok: bool = True
    """Whether it stayed in the chart."""


def measure(model: NominalModel, family: ModelFamily, goal_q: Array, info: Mapping[str, Any]) -> Trial:
    """The :class:`Trial` of a trial's ``info`` (its ``action``, ``error`` and ``left_chart``)."""
    c = np.asarray(info["action"], dtype=np.float64)
    z = model.z_goal - np.asarray(info["error"], dtype=np.float64)
    ok = not bool(info.get("left_chart", False)) and bool(np.all(np.isfinite(z)))
    q = family.to_configuration(z) if ok else np.full(goal_q.shape, np.nan)
    return Trial(c, z, q, float(np.linalg.norm(q - goal_q)) if ok else np.inf, ok)


def final_chained(family: ModelFamily, thetas: Array, c: Array) -> tuple[Array, Mask]:
    """Final chained coordinates of trials ``c`` ``(B, 1 + q)`` on hypotheses ``thetas`` ``(B, size)``
    (NaN where a trial left the chart), and whether each stayed in it."""
    q, ok = family.configurations_many(thetas, c)
    z = np.full_like(q, np.nan)
    z[ok] = family.to_chained(q[ok])
    return z, ok


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


def newton_solve(
    mismatch: Callable[[Array], tuple[Array, Mask]],
    c: Array,
    g: Array,
    project: Callable[[Array], Array],
    steps: Array,
    iterations: int,
    halvings: int,
    tolerance: float,
    rcond: float | None = None,
) -> tuple[Array, Array]:
    """Newton's method on ``mismatch(c) = 0`` from ``c`` (whose mismatch is ``g``) with
    forward-difference derivatives (``steps`` per coefficient, one batched call) and a backtracking
    line search: a step, projected by ``project``, is halved (at most ``halvings`` times) until it
    lowers ``|g|`` and stays in the chart. Least-squares steps (``rcond`` as in ``numpy.linalg.lstsq``)
    for spare coefficients. Returns the last iterate and its mismatch."""
    for _ in range(iterations):
        if not np.all(np.isfinite(g)) or np.linalg.norm(g) < tolerance:
            break
        probes = c + np.vstack([np.zeros_like(c), np.diag(steps)])
        values, probe_ok = mismatch(probes)
        if not np.all(probe_ok):
            break
        J = (values[1:] - values[0]).T / steps
        step = np.linalg.lstsq(J, -values[0], rcond=rcond)[0]
        for _ in range(halvings):
            candidate = project(c + step)
            g_new, ok_new = mismatch(candidate[None])
            if ok_new[0] and np.linalg.norm(g_new[0]) < np.linalg.norm(g):
                c, g = candidate, g_new[0]
                break
            step = 0.5 * step
        else:
            break
    return c, g


def broyden_update(D: Array, s: Array, r: Array) -> None:
    """Broyden's rank-one update of the secant ``D`` in place: after a step ``s`` that changed the
    residual by ``r``, ``D <- D + (r - D s) s^T / s^T s`` (the least change with ``D s = r``)."""
    D += np.outer(r - D @ s, s) / (s @ s)


def law_step(model: NominalModel, trial: Trial, nu_a: float = 1.0, nu_b: float = 1.0) -> Array:
    """Eqs. 33-34 from ``trial`` (unprojected)."""
    law = ILCAgent(model, nu_a, nu_b, start=trial.c)
    law.learn({"action": trial.c, "error": model.z_goal - trial.z})
    return law.act()


def box(c: Array, low: Array, high: Array) -> Array:
    """``c`` clipped to the action box."""
    return np.clip(c, low, high)


def trust_box(origin: Array, c: Array, radius: Array, low: Array, high: Array) -> Array:
    """``c`` clipped to the box of half-widths ``radius`` around ``origin``, then to the action box."""
    return np.clip(np.clip(c, origin - radius, origin + radius), low, high)


def gauss_newton(
    residuals: Callable[[Array], Array],
    c: Array,
    low: Array,
    high: Array,
    steps: Array,
    iterations: int,
    tolerance: float = 1e-10,
) -> tuple[Array, Array]:
    """Least squares on ``residuals`` (batched, ``(M, p) -> (M, R)``) from ``c`` in ``[low, high]``
    by Gauss-Newton's minimum-norm step (a pseudo-inverse: where the Jacobian is near-singular, as
    ``W`` is for a symmetric ``v1``, it moves the spare coefficients least), halved until it lowers
    the cost, then Levenberg-Marquardt steps (the oracle's search, on a model instead of the plant).
    Forward differences of ``steps``. Returns the last iterate and its residual."""
    p = c.size
    r = residuals(c[None])[0]
    cost, damping = float(r @ r), 1e-3
    for _ in range(iterations):
        if not np.isfinite(cost) or cost <= tolerance**2:
            break
        values = residuals(c + np.vstack([np.zeros(p), np.diag(steps)]))
        J = (values[1:] - values[0]).T / steps
        if not np.all(np.isfinite(J)):
            break
        newton = -np.linalg.pinv(J) @ r
        gradient, normal = J.T @ r, J.T @ J
        improved = False
        for attempt in range(12):
            if attempt < 6:
                step = newton * 0.5**attempt
            else:
                step = -np.linalg.solve(normal + damping * np.diag(np.diag(normal) + 1e-12), gradient)
                damping *= 4
            candidate = np.clip(c + step, low, high)
            r_new = residuals(candidate[None])[0]
            if float(r_new @ r_new) < cost:
                c, r, cost, damping, improved = candidate, r_new, float(r_new @ r_new), 1e-3, True
                break
        if not improved:
            break
    return c, r


def scatter_groups(model: NominalModel) -> tuple[tuple[int, ...], ...]:
    """The coordinates of a configuration whose scatter is pooled (:func:`ilc_steering.core.scatter.estimate`):
    a pose's x and y [m], then its heading [rad]; without a pose, every chained coordinate."""
    if getattr(model.chained_map, "has_pose", False):
        return ((0, 1), (2,))
    return (tuple(range(model.dimension)),)


def trial_scatter(
    family: ModelFamily, theta: Array, trials: list[Trial], groups: tuple[tuple[int, ...], ...]
) -> Array | None:
    """The plant's scatter per group [m or rad] from the residuals of ``trials`` against the family's
    model ``theta`` (one batched simulation, no trial), or None: too few trials qualify, the errors
    still fall, or the plant repeats itself (two trials of one action measured alike,
    :func:`~ilc_steering.core.scatter.repeats`, or a scatter below
    :data:`~ilc_steering.core.scatter.MIN_SCATTER`)."""
    ok = [t for t in trials if t.ok]
    if not ok or shown_to_repeat(ok):
        return None
    q, inside = family.configurations(theta, np.array([t.c for t in ok]))
    residuals = np.where(inside[:, None], np.array([t.q for t in ok]) - q, np.nan)
    found = estimate(residuals, np.array([t.error for t in ok]), groups)
    if found is None or float(np.min(found[0])) < MIN_SCATTER:
        return None
    return found[0]


def shown_to_repeat(trials: list[Trial]) -> bool:
    """Whether two of ``trials`` ran one action and were measured alike: the plant repeats itself,
    and what a model leaves of its trials is the model's error, not a scatter to average."""
    return len(trials) > 1 and repeats(np.array([t.c for t in trials]), np.array([t.q for t in trials]))


def within_scatter(q: Array, goal_q: Array, sigma: Array, groups: tuple[tuple[int, ...], ...], factor: float) -> bool:
    """Whether the configuration ``q`` is within ``factor`` times the scatter of ``goal_q`` in every
    group (the norm of the group's error against ``factor * sigma * sqrt(len(group))``)."""
    return all(
        float(np.linalg.norm((q - goal_q)[list(g)])) <= factor * float(s) * np.sqrt(len(g))
        for s, g in zip(sigma, groups)
    )


BAND = FLOOR
"""A learner that knows the scatter averages once a trial lands within this many times it (per
coordinate): there, what it measures is mostly the scatter, which no step can take back."""


def in_scatter_band(
    model: NominalModel,
    family: ModelFamily,
    theta: Array,
    trials: list[Trial],
    goal_q: Array,
    band: list[Trial],
    trial: Trial,
    last: Array | None = None,
) -> tuple[Array | None, bool]:
    """The scatter estimated from ``trials`` on the refit model (None: no estimate yet), and
    whether ``trial`` is (still) in its band: within :data:`BAND` times it, or within twice that
    once the band has begun. ``band`` holds the band's trials: ``trial`` is appended, or the band
    is emptied. A band begins with the trials just before ``trial`` (the last of ``trials``; at most
    :data:`~ilc_steering.core.scatter.MIN_TRIALS` of them) that were within twice :data:`BAND` too
    and that the refit model puts within the scatter of ``trial``'s outcome (about the same
    action): the scatter is estimated only from the fourth trial near the goal on, and those
    before it are draws of it as well, so that the band's first mean is not a single draw (a
    learner that stepped to correct one draw in full left a tolerance of four times the scatter on
    the MuJoCo car). Trials farther apart in action are left out: outside the model's family its
    error changes with the action, and their offsets would bias the mean (``newton_ilc`` on the
    simulated lab robot held a heading bias of 6-9 mrad). Once the band has begun, ``last`` (the estimate the
    learner last had) stands in when the trials give none (not once two trials of one action were
    measured alike: that plant has no scatter, and the band ends): a few lucky draws in a row read as
    errors that still fall, and a band ended by them sent the learner to chase the next draw."""
    groups = scatter_groups(model)
    scatter = trial_scatter(family, theta, trials, groups)
    if scatter is None and band and not shown_to_repeat([t for t in trials if t.ok]):
        scatter = last
    inside = scatter is not None and (
        within_scatter(trial.q, goal_q, scatter, groups, BAND)
        or (bool(band) and within_scatter(trial.q, goal_q, scatter, groups, 2 * BAND))
    )
    if inside and not band and scatter is not None:
        earlier = [t for t in trials if t is not trial and t.ok][-MIN_TRIALS:]
        q, ok = family.configurations(theta, np.array([trial.c, *[t.c for t in earlier]]))
        for t, q_t, ok_t in reversed(list(zip(earlier, q[1:], ok[1:]))):
            # a draw of the scatter at about the same action: the model moves it by less than the scatter
            if not (ok[0] and ok_t and within_scatter(t.q, goal_q, scatter, groups, 2 * BAND)):
                break
            if not within_scatter(q_t, q[0], scatter, groups, 1.0):
                break
            band.insert(0, t)
    if inside:
        band.append(trial)
    else:
        band.clear()
    return scatter, inside
