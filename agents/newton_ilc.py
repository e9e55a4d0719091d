r"""``newton_ilc``: re-identify the plant after every trial, then take a Newton step on the refit model.

Eqs. 33-34 are a Newton step with the Jacobian frozen at the nominal model, so on a perturbed
plant the error only contracts by a fixed factor per trial (0.1 on forward parking, 0.47 with the
45-degree limit). This learner removes the cause rather than the symptom. It keeps every trial
``k`` it has run, coefficients :math:`c_k` and measured final configuration :math:`y_k`, and
after each one:

1. **Re-identification.** The nominal structure with free parameters :math:`\theta` (a
   :class:`~ilc_steering.core.family.ModelFamily`: a car's true wheelbase and wheel radius, the
   chained form's input gains) is simulated, on the compiled kernel and at no trial's cost, to fit

   .. math::

       \hat\theta = \arg\min_\theta \sum_k \| q(c_k; \theta) - y_k \|^2 + \mu \|\theta\|^2

   by Levenberg-Marquardt with central-difference derivatives, in configuration coordinates
   (metres and radians, as the robot is measured). One trial gives ``n`` equations for two
   unknowns, so a perturbation inside the family is removed after the first trial. The small
   ridge :math:`\mu` keeps :math:`\theta` at 0 while the trials carry no information on it.
2. **What the structure does not explain**, :math:`d_k = z_k - F(c_k; \hat\theta)` in chained
   coordinates, is kept as an offset with a secant (Broyden) Jacobian :math:`D`: after a step
   :math:`s = c_k - c_{k-1}` with residual change :math:`r = d_k - d_{k-1}` (both under the current
   :math:`\hat\theta`), :math:`D \leftarrow D + (r - D s) s^T / s^T s`.
3. **Newton on the refit model.** The next coefficients solve

   .. math::

       F(c; \hat\theta) + d_k + D (c - c_k) = z^d

   by Newton's method on the simulated family (forward-difference Jacobian, one batched kernel
   call per iteration, backtracking), started from whichever of :math:`c_k`, the eq. 33-34 step
   and the nominal solution the refit model puts nearest the goal, within a trust region of :data:`TRUST_RADIUS` nominal
   action scales of :math:`c_k`, projected onto the action box.
4. **Fall-back.** When a trial did not reduce the measured error below the best so far, the
   next trial is eqs. 33-34 from the best trial (:class:`~ilc_steering.agents.ilc.ILCAgent`),
   and :math:`D` is reset. When that fails too, the step from the best trial is halved, up to
   :data:`FALLBACK_HALVINGS` times (unless the best trial is within :data:`REACHED`, where no
   tolerance fails it); when the smallest step fails as well, the best trial's error was likely
   a lucky draw of the plant's scatter, and the best trial itself is run again (a repeat it asks
   for and counts, ``NewtonILC.repeats``): its measurements are averaged, and the learner goes
   on from the mean; a plant that has measured one action alike twice has no such luck, and the
   step from the best trial halves on. So no failed trial is sent again as it was. When a trial left the chart,
   the next one halves its step from the best trial (eqs. 33-34 from it if there is no best yet).

5. **The plant's scatter.** A robot that does not repeat itself scatters the final pose of one
   action; chasing each draw passes it on whole into the next trial. Once the learner can
   estimate the scatter :math:`\hat\sigma` from its trials' residuals against the refit model
   (:func:`~ilc_steering.agents.scatter_band.trial_scatter`, :mod:`ilc_steering.core.scatter`)
   and a trial lands within :data:`~ilc_steering.agents.scatter_band.BAND` times it, it averages:
   the offset :math:`d` of step 3 is the mean of :math:`d_j` over the band's trials, so the
   :math:`N`-th trial there moves by :math:`1/N` of a new draw (the shrinking gain of
   stochastic-approximation ILC, Saab 2001; Butcher, Karimi, Longchamp 2008), :math:`D = 0`, and
   no trial in the band is a failure to fall back from. The band counts the (at most four)
   trials just before its entry that were within twice it at about the same action (the model
   moves them by less than the scatter): the estimate needs four trials near the goal, those
   before it are draws too, and a first mean of one draw chased it whole. It keeps the last
   estimate while the trials give none. A trial beyond twice the band (a change of the plant,
   not a draw) ends the averaging. It assumes the model's error is constant over the band's
   trials (their steps are of the scatter's size); it cannot hold a tolerance that single draws
   leave (heavy tails: the MuJoCo car's friction draws) nor one below about three times the
   scatter. A plant that repeats itself (every packaged noiseless config) has no scatter to
   estimate, and this step never runs; where a model's misfit reads as one (the trailer with a
   hitch, outside the family), the band's first repeat measures the same outcome and ends it.

On the nominal plant :math:`\hat\theta = 0`, :math:`d = 0` and step 3 is an exact inversion:
one update lands on the goal to the integrator's accuracy (``tests/test_newton_ilc.py``).
The learner sees only the :class:`~ilc_steering.core.nominal.NominalModel` and the measured
trials; the family is built from the nominal model alone.
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from typing import Any

import numpy as np
import numpy.typing as npt

from ilc_steering.agents.base import LearnerContext
from ilc_steering.agents.identifier import local_fit
from ilc_steering.agents.scatter_band import ScatterBand, shown_to_repeat
from ilc_steering.agents.secant import broyden_update
from ilc_steering.agents.solver import law_step, newton_solve, trust_box
from ilc_steering.agents.trial import Trial
from ilc_steering.core.family import ModelFamily
from ilc_steering.core.nominal import NominalModel

__all__ = ["FALLBACK_HALVINGS", "TRUST_RADIUS", "NewtonILC", "make_newton_ilc"]

Array = npt.NDArray[np.float64]

TRUST_RADIUS = 2.0
"""The largest step of one update, in units of ``NominalModel.action_scale()`` per coefficient."""
FALLBACK_HALVINGS = 3
"""Failed fall-backs in a row, each with half the last one's step, before the best trial is run again."""
REACHED = 1e-10
"""[m and rad] a best trial this near the goal is at the integrator's accuracy: no tolerance fails it,
and its fall-back is run as it is, however often."""
_SOLVE_ITERATIONS = 20


class NewtonILC:
    """Re-identification plus a Newton step on the refit model (see the module docstring).

    Parameters
    ----------
    model
        The nominal model (never the plant).
    start
        The first trial's coefficients.
    low, high
        The env's action box [physical units].
    nu_a, nu_b
        Gains of the eq. 33-34 fall-back.
    identify
        Fit the family's parameters (``False``: keep the nominal ones).
    secant
        Broyden updates of what the family does not explain (``False``: the offset alone).
    """

    def __init__(
        self,
        model: NominalModel,
        start: Array,
        low: Array,
        high: Array,
        nu_a: float = 1.0,
        nu_b: float = 1.0,
        identify: bool = True,
        secant: bool = True,
    ) -> None:
        self.model = model
        self.family = ModelFamily(model)
        self.start = np.array(start, dtype=np.float64)
        self.low = np.asarray(low, dtype=np.float64)
        self.high = np.asarray(high, dtype=np.float64)
        self.nu_a, self.nu_b = nu_a, nu_b
        self.identify, self.secant = identify, secant
        self._goal_q = self.family.to_configuration(model.z_goal)
        self._scale = model.action_scale()
        self.band = ScatterBand(model, self._goal_q)
        """The plant's scatter and the trials of its band (step 5)."""
        self.reset()

    def reset(self) -> None:
        self.theta = np.zeros(self.family.size)
        self.update_seconds: list[float] = []
        """Wall time [s] of each model update (identification and Newton solve; a fall-back costs ~0)."""
        self._trials: list[Trial] = []
        self._best: Trial | None = None
        self._D = np.zeros((self.model.dimension, self.start.size))
        self._previous: Trial | None = None  # the last trial of the secant, None after a fall-back
        self._failures = 0  # trials in a row not better than the best
        self._measured: list[Trial] = []  # the best trial's measurements, when it was run again
        self.repeats = 0
        """Trials that ran the best trial's coefficients again, by the learner's choice (see the module)."""
        self.band.reset()
        self._next = self.start.copy()

    @property
    def scatter(self) -> Array | None:
        """The plant's scatter per coordinate group as last estimated (``[m, rad]`` for a pose), or None."""
        return self.band.scatter

    def act(self, observation: Any = None) -> Array:
        return self._next.copy()

    def learn(self, info: Mapping[str, Any]) -> None:
        began = time.perf_counter()
        c = np.asarray(info["action"], dtype=np.float64)
        error = np.asarray(info["error"], dtype=np.float64)
        z = self.model.z_goal - error
        if bool(info.get("left_chart", False)):
            # A halted trial's error says little about the plant: eqs. 33-34 from the best trial
            # (from this one if there is none yet), as the paper's law would; when the step from the
            # best trial was what left the chart, half of it, and so on.
            if self._best is None:
                self._next = self._fallback(Trial(c, z, z, np.inf))
            else:
                self._next = self._best.c + 0.5 * (c - self._best.c)
            return
        q = self.family.to_configuration(z)
        trial = Trial(c, z, q, float(np.linalg.norm(q - self._goal_q)))
        self._trials.append(trial)
        if self.band.update(self.family, self.theta, self._trials, trial):
            self._failures, self._measured = 0, []
            self._best = trial
            if self.identify:
                self.theta = local_fit(self.family, self._trials, self.theta)
            self._D[:] = 0.0
            self._previous = None
            z_model, ok = self._final_z(self.band.actions())
            self._next = self._newton(trial, self.band.offset(z_model, ok) if ok.any() else None)
            self.update_seconds.append(time.perf_counter() - began)
            return
        best = self._best
        if best is not None and self._measured and np.array_equal(c, best.c):
            trial = self._mean(trial)  # the repeat it asked for: the best trial, measured once more
        elif best is not None and trial.error >= best.error:
            self._failures += 1
            self._D[:] = 0.0
            self._previous = None
            if self._failures == 1 or best.error < REACHED:
                self._next = self._fallback(best)
            elif self._failures <= FALLBACK_HALVINGS + 1 or shown_to_repeat(self._trials):
                # (a plant that repeated an action alike has no luck to measure again: the step halves on)
                self._next = best.c + 0.5 ** (self._failures - 1) * (self._fallback(best) - best.c)
            else:  # the smallest step failed too: the best trial's error may be the scatter's luck
                self._measured = self._measured or [best]
                self._failures = 0
                self.repeats += 1
                self._next = best.c.copy()
            return
        else:
            self._measured = []
        self._failures = 0
        self._best = trial
        if self.identify:
            self.theta = local_fit(self.family, self._trials, self.theta)
        self._next = self._newton(trial)
        self.update_seconds.append(time.perf_counter() - began)

    def _mean(self, trial: Trial) -> Trial:
        """The best trial with ``trial``, a repeat of it, among its measurements: their mean."""
        self._measured.append(trial)
        z = np.mean([t.z for t in self._measured], axis=0)
        q = self.family.to_configuration(z)
        return Trial(trial.c, z, q, float(np.linalg.norm(q - self._goal_q)))

    def _fallback(self, trial: Trial) -> Array:
        """Eqs. 33-34 from ``trial``."""
        return self._project(trial.c, law_step(self.model, trial, self.nu_a, self.nu_b))

    def _newton(self, trial: Trial, offset: Array | None = None) -> Array:
        """Solve ``F(c; theta) + d + D (c - c_k) = z^d`` for the next ``c`` from ``c_k``; ``d`` is
        ``offset`` when given (step 5's mean), else the trial's own."""
        z_model, ok = self._final_z(trial.c[None])
        d = trial.z - z_model[0] if ok[0] else np.zeros_like(trial.z)
        if offset is not None and np.all(np.isfinite(offset)):
            d = offset
        previous = self._previous
        if self.secant and previous is not None:
            z_prev, ok_prev = self._final_z(previous.c[None])
            s = trial.c - previous.c
            if ok_prev[0] and s @ s > 0:
                broyden_update(self._D, s, d - (previous.z - z_prev[0]))
        self._previous = trial
        target = self.model.z_goal - d

        def mismatch(cs: Array) -> tuple[Array, npt.NDArray[np.bool_]]:
            z, ok = self._final_z(cs)
            return z + (cs - trial.c) @ self._D.T - target, ok

        # Newton starts from this trial, the eq. 33-34 step after it or the nominal solution, whichever
        # the refit model puts nearest the goal (on a nonsmooth saturated field the first two may
        # lead Newton to a kink, far from any solution).
        starts = np.stack([trial.c, self._fallback(trial), self._project(trial.c, self.model.solve())])
        values, ok = mismatch(starts)
        norms = np.where(ok, np.linalg.norm(values, axis=1), np.inf)
        pick = int(np.argmin(norms))
        c = starts[pick].copy()
        g = values[pick] if ok[pick] else np.full_like(target, np.inf)
        c, _ = newton_solve(
            mismatch, c, g, lambda c: self._project(trial.c, c), 1e-7 * self._scale, _SOLVE_ITERATIONS, 6, 1e-13
        )
        return np.asarray(c, dtype=np.float64)

    def _final_z(self, c: Array) -> tuple[Array, npt.NDArray[np.bool_]]:
        q, ok = self.family.configurations(self.theta, c)
        z = np.full_like(q, np.nan)
        z[ok] = self.family.to_chained(q[ok])
        return z, ok

    def _project(self, origin: Array, c: Array) -> Array:
        """Into the trust region around ``origin`` and the action box."""
        return trust_box(origin, c, TRUST_RADIUS * self._scale, self.low, self.high)


def make_newton_ilc(context: LearnerContext) -> NewtonILC:
    """``compare`` method ``newton_ilc`` (and ``run --learner newton_ilc``), from the context's first trial."""
    low = np.asarray(context.action_space.low, dtype=np.float64)
    high = np.asarray(context.action_space.high, dtype=np.float64)
    return NewtonILC(context.model, context.first_action(), low, high, context.nu_a, context.nu_b)
