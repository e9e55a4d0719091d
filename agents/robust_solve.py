"""``robust_ilc``'s step 2: the next trial's coefficients from the refit model, by Newton's method
from the best trial, a homotopy from the nominal model at its exact solution, Gauss-Newton's
minimum-norm steps and the identification's restarts (the derivation is :mod:`~ilc_steering.agents.robust_ilc`'s)."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from ilc_steering.agents.model_based import Trial, box, final_chained, gauss_newton, law_step, newton_solve
from ilc_steering.agents.robust_identify import CHART_PENALTY, HALVINGS, GlobalIdentification, Secant

__all__ = ["HOMOTOPY_STEPS", "SOLVED", "Continuation"]

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


class Continuation(GlobalIdentification):
    """The solvers of the next trial on the refit model (``robust_ilc``'s step 2)."""

    start: Array
    low: Array
    high: Array
    _nominal_c: Array
    _D: Secant

    def _solve(self, trial: Trial | None, reach: float) -> Array:
        """Coefficients that bring the refit model (plus the best trial's residual, if any) to the
        point ``reach`` of the way from the start to the goal."""
        model = self.model
        target = model.z_start + reach * (model.z_goal - model.z_start)
        if trial is None:
            d, anchor, D = np.zeros_like(target), self._nominal_c, Secant.none(*self._D.D.shape)
        else:
            z, ok = self._final_z(self.theta[None], trial.c[None])
            z_a = trial.z if self._D.z is None else self._D.z
            d = z_a - self._D.A * z[0] if ok[0] else np.zeros_like(target)
            anchor, D = trial.c, self._D

        candidates = []
        if trial is not None:
            candidates.append(self._newton(trial.c, self.theta, target - d, D, anchor))
            if np.linalg.norm(candidates[0][1]) < SOLVED or not self._thorough:
                return self._box(candidates[0][0]) if np.all(np.isfinite(candidates[0][1])) else self._law(trial)
        # The homotopy from the nominal model at its exact solution.
        c = self._box(model.solve(z_goal=model.z_start + reach * (model.z_goal - model.z_start)))
        for s in np.linspace(0.0, 1.0, HOMOTOPY_STEPS + 1)[1:]:
            c, _ = self._newton(c, s * self.theta, target - s * d, D.part(s), anchor)
        candidates.append((c, self._mismatch(c[None], self.theta, target - d, D, anchor)[0][0]))
        norms = [float(np.linalg.norm(g)) if np.all(np.isfinite(g)) else np.inf for _, g in candidates]
        pick = int(np.argmin(norms))
        if norms[pick] > SOLVED:
            # Newton stalls where W is near-singular (a symmetric v1) or the branch folds: Gauss-Newton's
            # minimum-norm steps on the configuration error, from the best candidate, then (a thorough
            # update) along the homotopy from the nominal solution, and (an exact model) from its restarts.
            c_gn = self._damped(candidates[pick][0], self.theta, target - d, D, anchor)
            candidates.append((c_gn, self._mismatch(c_gn[None], self.theta, target - d, D, anchor)[0][0]))
            if self._thorough and np.linalg.norm(candidates[-1][1]) > SOLVED:
                c_gn = self._damped(self._box(model.solve(z_goal=target)), self.theta, target - d, D, anchor)
                candidates.append((c_gn, self._mismatch(c_gn[None], self.theta, target - d, D, anchor)[0][0]))
            if self._thorough and min(np.linalg.norm(g) for _, g in candidates[-2:]) > SOLVED:
                c_gn = self._box(model.solve(z_goal=target))
                for s in np.linspace(0.0, 1.0, HOMOTOPY_STEPS + 1)[1:]:
                    c_gn = self._damped(c_gn, s * self.theta, target - s * d, D.part(s), anchor)
                candidates.append((c_gn, self._mismatch(c_gn[None], self.theta, target - d, D, anchor)[0][0]))
            solved = any(np.linalg.norm(g) <= SOLVED for _, g in candidates)
            starts = np.empty((0, self.start.size)) if solved else self.restarts(target)
            for c_gn in [self._damped(self._box(c0), self.theta, target - d, D, anchor) for c0 in starts]:
                candidates.append((c_gn, self._mismatch(c_gn[None], self.theta, target - d, D, anchor)[0][0]))
            norms = [float(np.linalg.norm(g)) if np.all(np.isfinite(g)) else np.inf for _, g in candidates]
            pick = int(np.argmin(norms))
        if not np.isfinite(norms[pick]):
            return self._box(c) if trial is None else self._law(trial)
        return self._box(candidates[pick][0])

    def _damped(self, c: Array, theta: Array, target: Array, D: Secant, anchor: Array) -> Array:
        """Gauss-Newton on the model's configuration error (metres and radians, better conditioned
        than chained coordinates far from the goal) from ``c``, within the box."""

        def residuals(cs: Array) -> Array:
            g, ok = self._mismatch(cs, theta, target, D, anchor)
            q = self.family.to_configuration(np.where(ok[:, None], g + self.model.z_goal, self.model.z_goal))
            return np.where(ok[:, None], q - self._goal_q, CHART_PENALTY)

        return gauss_newton(residuals, c, self.low, self.high, 1e-7 * self._scale, _DAMPED_ITERATIONS)[0]

    def _law(self, trial: Trial) -> Array:
        """Eqs. 33-34 from ``trial``: the step when the refit model has no solution in its chart."""
        return self._box(law_step(self.model, trial))

    def _mismatch(self, cs: Array, theta: Array, target: Array, D: Secant, anchor: Array) -> tuple[Array, Mask]:
        z, ok = self._final_z(np.tile(theta, (cs.shape[0], 1)), cs)
        return D.A * z + (cs - anchor) @ D.D.T - target, ok

    def _newton(self, c: Array, theta: Array, target: Array, D: Secant, anchor: Array) -> tuple[Array, Array]:
        """Newton's method on ``F(c; theta) + D (c - anchor) = target`` from ``c``, staying in the
        model's chart; returns the last iterate and its mismatch."""

        def mismatch(cs: Array) -> tuple[Array, Mask]:
            return self._mismatch(cs, theta, target, D, anchor)

        values, ok = mismatch(c[None])
        g = values[0] if ok[0] else np.full_like(target, np.inf)
        return newton_solve(
            mismatch, c, g, self._box, 1e-7 * self._scale, _NEWTON_ITERATIONS, HALVINGS, 1e-2 * SOLVED, RCOND
        )

    def _final_z(self, thetas: Array, c: Array) -> tuple[Array, Mask]:
        return final_chained(self.family, thetas, c)

    def _box(self, c: Array) -> Array:
        return box(c, self.low, self.high)
