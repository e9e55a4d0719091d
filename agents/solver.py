"""The solver: the next trial's coefficients on a refit model, and the trust region around the trials.

:class:`Solver` is ``robust_ilc``'s: the refit model, corrected by its
:class:`~ilc_steering.agents.secant.Secant`, brought to a target by Newton's method from the best
trial, by a homotopy from the nominal model at its exact solution, by damped Gauss-Newton
minimum-norm steps and from the identifier's restarts; the paper's eqs. 33-34 where none of them
finds a solution in the model's chart. :class:`TrustRegion` bounds a step from the best trial by
what the measured errors taught. The root finders under them, :func:`newton_solve` and
:func:`gauss_newton`, and the box projections are ``newton_ilc``'s too. The derivation is in
``docs/learners.md`` (``robust_ilc``'s steps 2 and 3); everything here sees only the nominal model
(through a :class:`~ilc_steering.core.family.ModelFamily`) and the measured trials.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import numpy.typing as npt

from ilc_steering.agents.identifier import CHART_PENALTY, HALVINGS
from ilc_steering.agents.ilc import ILCAgent
from ilc_steering.agents.secant import Secant
from ilc_steering.agents.trial import Trial, final_chained
from ilc_steering.core.family import ModelFamily
from ilc_steering.core.nominal import NominalModel

__all__ = [
    "HOMOTOPY_STEPS",
    "LEFT_CHART_SHRINK",
    "SHRINK",
    "SOLVED",
    "Solver",
    "TrustRegion",
    "box",
    "gauss_newton",
    "law_step",
    "newton_solve",
    "trust_box",
]

Array = npt.NDArray[np.float64]
Mask = npt.NDArray[np.bool_]

HOMOTOPY_STEPS = 8
"""Steps of the continuation from the nominal model to the refit one."""
SOLVED = 1e-10
"""[chained units] a model mismatch this small needs no continuation."""
RCOND = 1e-7
"""Singular values of the model's Jacobian below this fraction of the largest are left out of a Newton step: a
symmetric ``v1`` makes ``W`` singular (to round-off), and its near-null direction would leave the box."""
_NEWTON_ITERATIONS = 12
_DAMPED_ITERATIONS = 100

SHRINK = 2.0
"""After a trial worse than the best, the next step from the best is at most this times the failed one's length (the
failed trial has entered the secant: the corrected answer may lie beyond it)."""
LEFT_CHART_SHRINK = 0.5
"""After a trial that left the chart, the next step from the best is at most this times the failed one's length."""


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


class Solver:
    """The solvers of the next trial on a refit model (``robust_ilc``'s step 2).

    Parameters
    ----------
    model
        The nominal model (never the plant).
    low, high
        The env's action box [physical units].
    """

    def __init__(self, model: NominalModel, low: Array, high: Array) -> None:
        self.model = model
        self.low = np.asarray(low, dtype=np.float64)
        self.high = np.asarray(high, dtype=np.float64)
        self.scale = model.action_scale()
        """The action scale of each coefficient [its units]: the finite differences' steps are 1e-7 of it."""
        self.goal_q = model.chained_map.from_chained(model.z_goal)
        """The goal's configuration [m, rad]."""
        self.nominal_c = np.clip(model.solve(), self.low, self.high)
        """The nominal model's solution in the box: the anchor of a solve from no trial."""

    def solve(
        self,
        family: ModelFamily,
        theta: Array,
        secant: Secant,
        trial: Trial | None,
        reach: float,
        thorough: bool,
        restarts: Callable[[Array], Array],
    ) -> Array:
        """Coefficients that bring the refit model ``theta`` of ``family``, corrected by ``secant`` about
        ``trial`` (plus that trial's residual; None: the nominal solution, uncorrected), to the point
        ``reach`` of the way from the start to the goal. Only a ``thorough`` update goes on from a
        Newton step to the continuation, and from there to the damped searches and the ``restarts``
        (starts ``(S, 1 + q)`` for a target, :meth:`~ilc_steering.agents.identifier.Identifier.restarts`)."""
        model = self.model
        target = model.z_start + reach * (model.z_goal - model.z_start)
        if trial is None:
            d, anchor, D = np.zeros_like(target), self.nominal_c, Secant.none(*secant.D.shape)
        else:
            z, ok = final_chained(family, theta[None], trial.c[None])
            z_a = trial.z if secant.z is None else secant.z
            d = z_a - secant.A * z[0] if ok[0] else np.zeros_like(target)
            anchor, D = trial.c, secant

        candidates = []
        if trial is not None:
            candidates.append(self.newton(family, trial.c, theta, target - d, D, anchor))
            if np.linalg.norm(candidates[0][1]) < SOLVED or not thorough:
                return self.box(candidates[0][0]) if np.all(np.isfinite(candidates[0][1])) else self.law(trial)
        # The homotopy from the nominal model at its exact solution.
        c = self.box(model.solve(z_goal=model.z_start + reach * (model.z_goal - model.z_start)))
        for s in np.linspace(0.0, 1.0, HOMOTOPY_STEPS + 1)[1:]:
            c, _ = self.newton(family, c, s * theta, target - s * d, D.part(s), anchor)
        candidates.append((c, self.mismatch(family, c[None], theta, target - d, D, anchor)[0][0]))
        norms = [float(np.linalg.norm(g)) if np.all(np.isfinite(g)) else np.inf for _, g in candidates]
        pick = int(np.argmin(norms))
        if norms[pick] > SOLVED:
            # Newton stalls where W is near-singular (a symmetric v1) or the branch folds: Gauss-Newton's
            # minimum-norm steps on the configuration error, from the best candidate, then (a thorough
            # update) along the homotopy from the nominal solution, and (an exact model) from its restarts.
            c_gn = self.damped(family, candidates[pick][0], theta, target - d, D, anchor)
            candidates.append((c_gn, self.mismatch(family, c_gn[None], theta, target - d, D, anchor)[0][0]))
            if thorough and np.linalg.norm(candidates[-1][1]) > SOLVED:
                c_gn = self.damped(family, self.box(model.solve(z_goal=target)), theta, target - d, D, anchor)
                candidates.append((c_gn, self.mismatch(family, c_gn[None], theta, target - d, D, anchor)[0][0]))
            if thorough and min(np.linalg.norm(g) for _, g in candidates[-2:]) > SOLVED:
                c_gn = self.box(model.solve(z_goal=target))
                for s in np.linspace(0.0, 1.0, HOMOTOPY_STEPS + 1)[1:]:
                    c_gn = self.damped(family, c_gn, s * theta, target - s * d, D.part(s), anchor)
                candidates.append((c_gn, self.mismatch(family, c_gn[None], theta, target - d, D, anchor)[0][0]))
            solved = any(np.linalg.norm(g) <= SOLVED for _, g in candidates)
            starts = np.empty((0, self.nominal_c.size)) if solved else restarts(target)
            for c_gn in [self.damped(family, self.box(c0), theta, target - d, D, anchor) for c0 in starts]:
                candidates.append((c_gn, self.mismatch(family, c_gn[None], theta, target - d, D, anchor)[0][0]))
            norms = [float(np.linalg.norm(g)) if np.all(np.isfinite(g)) else np.inf for _, g in candidates]
            pick = int(np.argmin(norms))
        if not np.isfinite(norms[pick]):
            return self.box(c) if trial is None else self.law(trial)
        return self.box(candidates[pick][0])

    def damped(self, family: ModelFamily, c: Array, theta: Array, target: Array, D: Secant, anchor: Array) -> Array:
        """Gauss-Newton on the model's configuration error (metres and radians, better conditioned
        than chained coordinates far from the goal) from ``c``, within the box."""

        def residuals(cs: Array) -> Array:
            g, ok = self.mismatch(family, cs, theta, target, D, anchor)
            q = family.to_configuration(np.where(ok[:, None], g + self.model.z_goal, self.model.z_goal))
            return np.where(ok[:, None], q - self.goal_q, CHART_PENALTY)

        return gauss_newton(residuals, c, self.low, self.high, 1e-7 * self.scale, _DAMPED_ITERATIONS)[0]

    def law(self, trial: Trial) -> Array:
        """Eqs. 33-34 from ``trial``: the step when the refit model has no solution in its chart."""
        return self.box(law_step(self.model, trial))

    def mismatch(
        self, family: ModelFamily, cs: Array, theta: Array, target: Array, D: Secant, anchor: Array
    ) -> tuple[Array, Mask]:
        z, ok = final_chained(family, np.tile(theta, (cs.shape[0], 1)), cs)
        return D.A * z + (cs - anchor) @ D.D.T - target, ok

    def newton(
        self, family: ModelFamily, c: Array, theta: Array, target: Array, D: Secant, anchor: Array
    ) -> tuple[Array, Array]:
        """Newton's method on ``F(c; theta) + D (c - anchor) = target`` from ``c``, staying in the
        model's chart; returns the last iterate and its mismatch."""

        def mismatch(cs: Array) -> tuple[Array, Mask]:
            return self.mismatch(family, cs, theta, target, D, anchor)

        values, ok = mismatch(c[None])
        g = values[0] if ok[0] else np.full_like(target, np.inf)
        return newton_solve(
            mismatch, c, g, self.box, 1e-7 * self.scale, _NEWTON_ITERATIONS, HALVINGS, 1e-2 * SOLVED, RCOND
        )

    def box(self, c: Array) -> Array:
        """``c`` clipped to the action box."""
        return box(c, self.low, self.high)


class TrustRegion:
    """A region of half-width :attr:`radius` [action scales] around the best trial, which a step from
    it may not leave (``robust_ilc``'s step 3), within the action box.

    Parameters
    ----------
    scale
        The action scale of each coefficient [its units] (``NominalModel.action_scale()``).
    low, high
        The env's action box [physical units].
    """

    def __init__(self, scale: Array, low: Array, high: Array) -> None:
        self.scale = scale
        self.low = np.asarray(low, dtype=np.float64)
        self.high = np.asarray(high, dtype=np.float64)
        self.radius = np.inf
        """The half-width around the best trial [action scales]."""

    def reset(self) -> None:
        """No bound."""
        self.radius = np.inf

    def length(self, step: Array) -> float:
        """The size of a step in action scales (the largest over the coefficients)."""
        return float(np.max(np.abs(step) / self.scale))

    def within(self, origin: Array, c: Array, radius: float | None = None) -> Array:
        """``c`` pulled back along its step from ``origin`` to the region's radius (or ``radius``), then
        clipped to the action box."""
        radius = self.radius if radius is None else radius
        length = self.length(c - origin)
        if length > radius:
            c = origin + (c - origin) * (radius / length)
        return box(c, self.low, self.high)

    def failed(self, step: Array, left_chart: bool, explains: bool) -> None:
        """After a trial ``step`` from the best one that measured no better: the region shrinks to
        :data:`SHRINK` times the step, or within it (:data:`LEFT_CHART_SHRINK`) if the trial left the
        chart; a model that ``explains`` every trial lifts it."""
        if left_chart:  # a step that left the chart measured nothing for the secant: the region shrinks within it
            self.radius = LEFT_CHART_SHRINK * min(self.radius, self.length(step))
        else:
            self.radius = np.inf if explains else SHRINK * self.length(step)

    def improved(self, step: Array | None, explains: bool) -> None:
        """After a trial ``step`` from the best one (None: the first best) that measured better: the
        region grows to twice the step at least; a model that ``explains`` every trial lifts it."""
        if explains:
            self.radius = np.inf
        elif step is not None:
            self.radius = max(self.radius, 2.0 * self.length(step))
