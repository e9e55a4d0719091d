r"""``robust_ilc``: identify the plant globally, reach its solution by continuation, guard every step.

``newton_ilc`` refits the model family by a local fit from :math:`\theta = 0` and takes one
Newton step from the trial it just ran. Far from the nominal plant both fail: the nominal
solution leaves the chart (a long wheelbase jackknifes, a short one spins), a local fit from 0
finds a wrong minimum, and Newton from the measured trial lands on a kink or off the chart. This
learner keeps the same information (the :class:`~ilc_steering.agents.base.LearnerContext` and
each trial's measured final error, never the plant) and globalizes each of the three:

1. **Global identification, in widening families** (:mod:`~ilc_steering.agents.robust_identify`,
   whose constants are named here). The family's parameters :math:`\theta` (a
   :class:`~ilc_steering.core.family.ModelFamily`: a car's wheelbase and wheel radius, ...) are
   fitted to every trial run so far by a grid over the whole family (``GRID`` points per
   parameter, one compiled call for all of them), then Levenberg-Marquardt from the best grid
   points and from the last estimate. A trial that left the chart is a constraint: a hypothesis
   under which it would have stayed in the chart is penalized by ``CHART_PENALTY``. When the
   geometry leaves a trial unexplained by more than ``ESCALATE``, and the robot has a steering
   servo (the car), the families of ``ACTUATOR_FAMILIES`` are fitted too: the geometry plus the
   wheel's offset, then plus the servo's first-order lag (on grids of ``ACTUATOR_GRID``, then
   Levenberg-Marquardt). The best fit is kept if it explains every trial to ``EXPLAINED``;
   otherwise the geometry's fit is (a servo family that cannot explain the trials would only
   caricature what it lacks), and after ``ESCALATIONS`` such failures the servo's families are
   no longer tried.
   A wild trial (farther from the goal than the start) leaves the fit once two others stayed in the
   chart: near the chart's edge its end moves by metres for changes no fit resolves.
   A new fit replaces the last one only if its squared misfit is below ``REFIT_GAIN`` times the
   last one's: outside every family, fits of about equal misfit lie far apart (parallel parking on
   the simulated lab robot: a wheelbase ratio at the bound 2 and at 0.83), and a jump between them
   would change the Jacobian the secant below was fitted against for nothing.
2. **Continuation on a secant-corrected model.** The next coefficients solve the refit model
   corrected by what the trials teach near the best trial :math:`c_b`,

   .. math::

       A \odot \bigl(F(c; \hat\theta) - F(c_b; \hat\theta)\bigr) + D (c - c_b) + \hat z_b = z^d,

   (:class:`~ilc_steering.agents.robust_identify.Secant`, fitted by
   :func:`~ilc_steering.agents.robust_identify.fit_secant` to the best trial and the last
   ``SECANT_TRIALS`` others): per chained coordinate a weighted ridge regression of what the model
   leaves, :math:`z_i - F(c_i) = b + (A - 1)(F(c_i) - F(c_b)) + D (c_i - c_b)`, with :math:`A` a
   gain (prior 1, within a factor ``MAX_GAIN``), :math:`D` a Jacobian correction (prior 0, of size
   ``SECANT_PRIOR`` per action scale) and :math:`\hat z_b = F(c_b) + b` the best trial's outcome
   as the nearby trials smooth it. A trial's equation is weighted by
   :math:`1/\sqrt{\sigma^2 + (\kappa |s|^2)^2}` (``SECANT_SCATTER`` through the nominal map for
   :math:`\sigma`, ``SECANT_CURVATURE`` for :math:`\kappa`, :math:`s` its step from :math:`c_b` in
   action scales): far trials, where the plant is not linear, and steps within the scatter, which
   measure only its draw, teach little. The equation is solved by Newton's method from the best
   trial; when that leaves a mismatch, by Gauss-Newton's minimum-norm steps on the configuration
   error (the pseudo-inverse moves the spare coefficients least where ``W`` is near-singular, as
   with parallel parking's symmetric ``v1``; :func:`~ilc_steering.agents.model_based.gauss_newton`)
   from the best candidate and from the nominal solution, and then along a homotopy that starts
   where the answer is known: the nominal model at its exact solution (:math:`\theta = 0`, no
   correction), :math:`\theta`, the offset and the correction moved to their estimates in
   :data:`HOMOTOPY_STEPS` steps, each solved from the last. The candidate nearest the goal is kept.
3. **A trust region on the measured error.** A trial whose measured error is not below the best
   one so far is not learned from as a step (it still enters the identification and the secant):
   the next step from the best trial is no longer than ``SHRINK`` times the failed one. A model that explains every
   trial it is fitted to (to ``FIT_TOLERANCE``) lifts the trust region: a region learned
   while the model was wrong would only hold back the identified model's answer. A trial that left
   the chart measured nothing for the secant, and whatever the model: the region shrinks to
   ``LEFT_CHART_SHRINK`` times the smaller of its radius and the failed step. Until some
   trial stays in the chart, the target itself is continued: the next trial aims at a point
   :math:`\lambda` of the way from the start to the goal (:math:`\lambda` halved after each
   halted trial), so that the first in-chart trial identifies the plant; so too while no trial
   nearer the goal than the start has stayed in it.

4. **The plant's scatter.** As ``newton_ilc`` (its step 5): once the scatter can be estimated
   from the trials' residuals against the refit model and a trial lands within
   :data:`~ilc_steering.agents.model_based.BAND` times it, the learner averages. The secant is
   the one fitted on entering the band and kept while in it (steps of the scatter's size would
   fit only its draws); the offset is the mean over the band's trials of what the corrected model
   leaves, no global search runs, and the next trial is the corrected model's Newton solution from
   the last one, with no trust region on the measured error (in the band it is mostly the
   scatter's draw, and a trust region on it would only freeze the learner at its luckiest trial)
   but no longer than ``BAND_STEPS`` times the longest of the last steps. A trial beyond twice the
   band ends the averaging; the band begins with the trials just before it at about the same
   action, and keeps the last estimate while the trials give none (as ``newton_ilc``'s). A plant
   whose residuals vanish never enters it; one that repeats itself outside every family may (its
   model's misfit reads as a scatter), and it then averages on that misfit.

**Why it converges, and where it cannot.** On the nominal plant the residuals are 0, so
:math:`A = 1`, :math:`D = 0`, no offset: one update lands on the goal to the integrator's accuracy,
as ``newton_ilc``'s (``tests/test_robust_ilc.py``). Inside a family (the geometry's, or a car's with
its servo) the trials identify the plant once they give more equations than the family has unknowns
and the grid finds the basin (one in-chart trial for the geometry, two or three for the servo), and
the next trial solves the identified model, the plant: it lands on the goal whenever the model's
solvers find a solution. Outside every family (backlash, dead reckoning, a speed loop, noise) the
secant learns: a multi-secant quasi-Newton iteration on the measured outcome, assuming the plant
close to affine over the last steps (``SECANT_CURVATURE``), the model's Jacobian right up to a gain
per coordinate and a correction of size ``SECANT_PRIOR``, and the trials spanning the directions the
next step takes; it converges linearly until about as many trials near the goal as coefficients
determine the correction. It cannot where the plant's map is not smooth at the trials' scale (the
lab robot's dead-reckoned heading and backlash: the first trials improve by about half each), where
a scatter larger than ``SECANT_SCATTER`` is fitted as a correction (a ridge prior and the band's
frozen secant bound that), where the true plant cannot reach the goal (the oracle's unsolvable
region), and where the corrected model's solvers miss a solution the plant has.
"""

from __future__ import annotations

import itertools
import time
from collections.abc import Mapping
from typing import Any

import numpy as np
import numpy.typing as npt

from ilc_steering.agents.base import LearnerContext
from ilc_steering.agents.model_based import (
    Trial,
    in_scatter_band,
    measure,
)
from ilc_steering.agents.robust_identify import (
    FIT_TOLERANCE,
    SECANT_TRIALS,
    Secant,
    carried_family,
)
from ilc_steering.agents.robust_solve import HOMOTOPY_STEPS, Continuation
from ilc_steering.core.nominal import NominalModel

__all__ = ["HOMOTOPY_STEPS", "RobustILC", "make_robust_ilc"]

Array = npt.NDArray[np.float64]
Mask = npt.NDArray[np.bool_]

SHRINK = 2.0
"""After a trial worse than the best, the next step from the best is at most this times the failed one's length (the
failed trial has entered the secant: the corrected answer may lie beyond it)."""
LEFT_CHART_SHRINK = 0.5
"""After a trial that left the chart, the next step from the best is at most this times the failed one's length."""
BAND_STEPS = 2.0
"""A step in the scatter's band is at most this many times the longest of the last trials' steps."""
STALLED = 4
"""Updates without halving the best error after which the global searches run only every this many."""
REACHED = 1e-10
"""[m or rad] a measured error this small is the integrator's accuracy: the trial is repeated."""


class RobustILC(Continuation):
    """Global identification, continuation and a trust region (see the module docstring).

    Parameters
    ----------
    model
        The nominal model (never the plant).
    start
        The first trial's coefficients.
    low, high
        The env's action box [physical units].
    """

    def __init__(
        self, model: NominalModel, start: Array, low: Array, high: Array, carried: Mapping[str, Any] | None = None
    ) -> None:
        super().__init__(model)
        self.start = np.array(start, dtype=np.float64)
        self.low = np.asarray(low, dtype=np.float64)
        self.high = np.asarray(high, dtype=np.float64)
        self._nominal_c = np.clip(model.solve(), self.low, self.high)
        self._carried = None if carried is None else carried_family(self._families, carried)
        self.reset()

    def transfer(self) -> dict[str, Any]:
        """What it identified of the robot, for the next goal's ``robust_ilc`` (``run A B --carry``): the family's
        parameters (log-ratios of the geometry, the actuators' offset [rad] and lag [s]) and whether the servo's
        families are still tried (:func:`~ilc_steering.agents.robust_identify.carried_family` says how they serve)."""
        parameters = dict(zip(self.family.names, map(float, self.theta)))
        return {"robust_ilc": {"parameters": parameters, "servo": self.servo}}

    def reset(self) -> None:
        self.reset_identification(servo=self._carried is None or self._carried[2])
        self.update_seconds: list[float] = []
        """Wall time [s] of each update (identification, continuation and Newton solves)."""
        self._D = Secant.none(self.model.dimension, self.start.size)
        self._radius = np.inf  # the trust region's half-width around the best trial [action scales]
        self._stalled = 0  # updates since the best error last halved
        self._reach = 1.0  # the fraction of the way to the goal aimed at while no trial stays in the chart
        self.scatter: Array | None = None
        """The plant's scatter per coordinate group as last estimated (``[m, rad]`` for a pose), or None."""
        self._band: list[Trial] = []  # the trials since it entered the scatter's band (step 4)
        self._next = self.start.copy()
        if self._carried is not None:  # another goal of the same robot identified it: its model's solution first
            self.family, self.theta = self._carried[0], self._carried[1].copy()
            self._next = self._solve(None, 1.0)

    def act(self, observation: Any = None) -> Array:
        return self._next.copy()

    def learn(self, info: Mapping[str, Any]) -> None:
        began = time.perf_counter()
        trial = measure(self.model, self.family, self._goal_q, info)
        self._trials.append(trial)
        self._update(trial)
        self.update_seconds.append(time.perf_counter() - began)

    def _update(self, trial: Trial) -> None:
        """The next trial from ``trial`` (steps 1-4)."""
        c, ok = trial.c, trial.ok
        if ok and trial.error < REACHED and (self._best is None or trial.error <= self._best.error):
            # At the goal to the integrator's accuracy: nothing left to learn; run it again.
            self._best, self._next = trial, c.copy()
            return
        if ok and self._averaging(trial):
            self._average(trial)
            return
        improved = self._best is None or trial.error < 0.5 * self._best.error
        self._stalled = 0 if improved else self._stalled + 1
        # Stalled, it searches globally only every STALLED-th update: where the plant cannot reach the goal, that is all
        self._thorough = self._stalled < STALLED or self._stalled % STALLED == 0
        self.family, self.theta = self._refit()
        # A model that explains every trial it is fitted to is trusted whole: the trust region guards against one that
        # does not, and one learned before the model changed would only hold back the new model's answer.
        explains = self._misfit(self._residuals(self.theta[None], self._fit_trials())[0]) < FIT_TOLERANCE
        best = self._best
        if best is None and not ok and self._carried is not None and len(self._trials) == 1:  # not this robot's model
            self.family, self.theta, self._next = self._families[0], np.zeros(self._families[0].size), self.start.copy()
        elif not ok and (best is None or best.error > self._start_error):
            # No trial has stayed in the chart yet, or none nearer the goal than the start is (a wild one whose
            # neighbours leave the chart): aim at a point nearer the start.
            self._reach *= 0.5
            self._next = self._solve(None, self._reach)
        elif best is not None and not trial.error < best.error:
            # Outside the trust region: it shrinks to the failed step (SHRINK), and the refit model's
            # answer from the best trial is taken within it, the secant anchored there.
            self._D = self.secant(best)
            if not ok:  # a step that left the chart measured nothing for the secant: the region shrinks within it
                self._radius = LEFT_CHART_SHRINK * min(self._radius, self._length(c - best.c))
            else:
                self._radius = np.inf if explains else SHRINK * self._length(c - best.c)
            self._next = self._within(best.c, self._solve(best, 1.0))
        else:
            if explains:
                self._radius = np.inf
            elif best is not None:
                self._radius = max(self._radius, 2.0 * self._length(c - best.c))
            self._best = trial
            self._D = self.secant(trial)
            self._next = self._within(c, self._solve(trial, 1.0))

    # the scatter ---------------------------------------------------------------------------------

    def _averaging(self, trial: Trial) -> bool:
        """Whether ``trial`` is (still) in the scatter's band, where the learner averages (step 4)."""
        self.scatter, inside = in_scatter_band(
            self.model, self.family, self.theta, self._trials, self._goal_q, self._band, trial, self.scatter
        )
        return inside

    def _average(self, trial: Trial) -> None:
        """The next trial from the mean offset of the band's trials, on the refit model (step 4)."""
        self._thorough = False  # a local refit: the scatter, not the family, is what is left
        self.family, self.theta = self._refit()
        self._best = trial
        if len(self._band) == 1 or self._D.z is None:
            # Entering the band: the secant as the trials before it taught it, kept while in the band
            # (steps of the scatter's size would fit only the scatter's draws).
            self._D = self.secant(trial)
        c = np.array([t.c for t in self._band])
        z, ok = self._final_z(np.tile(self.theta, (c.shape[0], 1)), c)
        if not np.any(ok):
            self._next = self._law(trial)
            return
        local = self._D.A * z + (c - trial.c) @ self._D.D.T  # the refit model with the secant, about this trial
        d = np.mean((np.array([t.z for t in self._band]) - local)[ok], axis=0)
        next_c, g = self._newton(trial.c, self.theta, self.model.z_goal - d, self._D, trial.c)
        if not np.all(np.isfinite(g)):
            self._next = self._law(trial)
            return
        # In the band a step corrects the scatter's draw: no longer than BAND_STEPS times the
        # longest of the last trials' steps (a near-singular corrected Jacobian would send it far).
        recent = [t.c for t in self._trials[-SECANT_TRIALS:]]
        longest = max((self._length(b - a) for a, b in itertools.pairwise(recent)), default=0.0)
        radius = BAND_STEPS * max(longest, 1e-6)
        length = self._length(next_c - trial.c)
        if length > radius:
            next_c = trial.c + (next_c - trial.c) * (radius / length)
        self._next = self._box(next_c)

    def _length(self, step: Array) -> float:
        """The size of a step in action scales (the largest over the coefficients)."""
        return float(np.max(np.abs(step) / self._scale))

    def _within(self, origin: Array, c: Array) -> Array:
        """``c`` pulled back along its step from ``origin`` into the trust region."""
        length = self._length(c - origin)
        if length > self._radius:
            c = origin + (c - origin) * (self._radius / length)
        return self._box(c)


def make_robust_ilc(context: LearnerContext) -> RobustILC:
    """``compare`` method ``robust_ilc`` (and ``run --learner robust_ilc``), from the context's first trial."""
    low = np.asarray(context.action_space.low, dtype=np.float64)
    high = np.asarray(context.action_space.high, dtype=np.float64)
    return RobustILC(context.model, context.first_action(), low, high, context.carried)
