"""``robust_ilc``: identify the plant globally, reach its solution by continuation, guard every step.

:class:`RobustILC` composes four parts, each its own module: an
:class:`~ilc_steering.agents.identifier.Identifier` (global identification in widening families),
the :mod:`~ilc_steering.agents.secant` correction of the refit model, a
:class:`~ilc_steering.agents.solver.Solver` (Newton's method, continuation, damped Gauss-Newton) with
a :class:`~ilc_steering.agents.solver.TrustRegion` on the measured error, and a
:class:`~ilc_steering.agents.scatter_band.ScatterBand` (the plant's scatter, and the averaging in its
band). It keeps the trials, the best of them and what each update may do; the parts hold nothing of
one another. The algorithm, why it converges and where it cannot, is explained in
``docs/learners.md`` (the ``robust_ilc`` section).
"""

from __future__ import annotations

import itertools
import time
from collections.abc import Mapping
from typing import Any

import numpy as np
import numpy.typing as npt

from ilc_steering.agents.base import LearnerContext
from ilc_steering.agents.identifier import Identifier, carried_family
from ilc_steering.agents.scatter_band import ScatterBand
from ilc_steering.agents.secant import SECANT_TRIALS, Secant, chained_scatter, secant_about
from ilc_steering.agents.solver import Solver, TrustRegion
from ilc_steering.agents.trial import Trial, final_chained, measure
from ilc_steering.core.family import ModelFamily
from ilc_steering.core.nominal import NominalModel

__all__ = ["RobustILC", "make_robust_ilc"]

Array = npt.NDArray[np.float64]

BAND_STEPS = 2.0
"""A step in the scatter's band is at most this many times the longest of the last trials' steps."""
STALLED = 4
"""Updates without halving the best error after which the global searches run only every this many."""
REACHED = 1e-10
"""[m or rad] a measured error this small is the integrator's accuracy: the trial is repeated."""


class RobustILC:
    """Global identification, continuation and a trust region (``docs/learners.md``, ``robust_ilc``).

    Parameters
    ----------
    model
        The nominal model (never the plant).
    start
        The first trial's coefficients.
    low, high
        The env's action box [physical units].
    carried
        What another goal's ``robust_ilc`` identified of the robot (its :meth:`transfer`), or None.
    """

    def __init__(
        self, model: NominalModel, start: Array, low: Array, high: Array, carried: Mapping[str, Any] | None = None
    ) -> None:
        self.model = model
        self.start = np.array(start, dtype=np.float64)
        self.low = np.asarray(low, dtype=np.float64)
        self.high = np.asarray(high, dtype=np.float64)
        self.identifier = Identifier(model)
        """The families and the estimate fitted to the trials (step 1)."""
        self.solver = Solver(model, self.low, self.high)
        """The next trial's coefficients on the refit model (step 2)."""
        self.trust = TrustRegion(self.solver.scale, self.low, self.high)
        """The region around the best trial a step may not leave (step 3)."""
        self.band = ScatterBand(model, self.identifier.goal_q)
        """The plant's scatter and the trials of its band (step 4)."""
        self._sigma_z = chained_scatter(self.identifier.family, self.identifier.goal_q, model)
        self._carried = None if carried is None else carried_family(self.identifier.families, carried)
        self.reset()

    @property
    def family(self) -> ModelFamily:
        """The family of the identifier's estimate."""
        return self.identifier.family

    @property
    def theta(self) -> Array:
        """The identifier's estimate of the family's parameters."""
        return self.identifier.theta

    @property
    def servo(self) -> bool:
        """Whether the servo's families are still tried (the identifier's)."""
        return self.identifier.servo

    @property
    def scatter(self) -> Array | None:
        """The plant's scatter per coordinate group as last estimated (``[m, rad]`` for a pose), or None."""
        return self.band.scatter

    def transfer(self) -> dict[str, Any]:
        """What it identified of the robot, for the next goal's ``robust_ilc`` (``run A B --carry``): the family's
        parameters (log-ratios of the geometry, the actuators' offset [rad] and lag [s]) and whether the servo's
        families are still tried (:func:`~ilc_steering.agents.identifier.carried_family` says how they serve)."""
        return {"robust_ilc": self.identifier.transfer()}

    def reset(self) -> None:
        self.identifier.reset(self._carried)
        self.trials: list[Trial] = []
        """The measured trials, in order."""
        self.best: Trial | None = None
        """The trial of the least measured error so far (the trust region's centre)."""
        self.update_seconds: list[float] = []
        """Wall time [s] of each update (identification, continuation and Newton solves)."""
        self.secant = Secant.none(self.model.dimension, self.start.size)
        """The secant correction of the refit model about the best trial."""
        self.trust.reset()
        self.band.reset()
        self._stalled = 0  # updates since the best error last halved
        self._reach = 1.0  # the fraction of the way to the goal aimed at while no trial stays in the chart
        self._next = self.start.copy()
        if self._carried is not None:  # another goal of the same robot identified it: its model's solution first
            self._next = self._solve(None, 1.0, thorough=True)

    def act(self, observation: Any = None) -> Array:
        return self._next.copy()

    def learn(self, info: Mapping[str, Any]) -> None:
        began = time.perf_counter()
        trial = measure(self.model, self.identifier.family, self.identifier.goal_q, info)
        self.trials.append(trial)
        self._update(trial)
        self.update_seconds.append(time.perf_counter() - began)

    def _update(self, trial: Trial) -> None:
        """The next trial from ``trial`` (steps 1-4)."""
        c, ok = trial.c, trial.ok
        if ok and trial.error < REACHED and (self.best is None or trial.error <= self.best.error):
            # At the goal to the integrator's accuracy: nothing left to learn; run it again.
            self.best, self._next = trial, c.copy()
            return
        if ok and self.band.update(self.identifier.family, self.identifier.theta, self.trials, trial):
            self._average(trial)
            return
        improved = self.best is None or trial.error < 0.5 * self.best.error
        self._stalled = 0 if improved else self._stalled + 1
        # Stalled, it searches globally only every STALLED-th update: where the plant cannot reach the goal, that is all
        thorough = self._stalled < STALLED or self._stalled % STALLED == 0
        self.identifier.refit(self.trials, self.best, thorough)
        # A model that explains every trial it is fitted to is trusted whole: the trust region guards against one that
        # does not, and one learned before the model changed would only hold back the new model's answer.
        explains = self.identifier.explains(self.trials, self.best)
        best = self.best
        if best is None and not ok and self._carried is not None and len(self.trials) == 1:  # not this robot's model
            self.identifier.forget_estimate()
            self._next = self.start.copy()
        elif not ok and (best is None or best.error > self.identifier.start_error):
            # No trial has stayed in the chart yet, or none nearer the goal than the start is (a wild one whose
            # neighbours leave the chart): aim at a point nearer the start.
            self._reach *= 0.5
            self._next = self._solve(None, self._reach, thorough)
        elif best is not None and not trial.error < best.error:
            # Outside the trust region: it shrinks to the failed step (SHRINK), and the refit model's
            # answer from the best trial is taken within it, the secant anchored there.
            self.secant = self._secant(best)
            self.trust.failed(c - best.c, not ok, explains)
            self._next = self.trust.within(best.c, self._solve(best, 1.0, thorough))
        else:
            self.trust.improved(None if best is None else c - best.c, explains)
            self.best = trial
            self.secant = self._secant(trial)
            self._next = self.trust.within(c, self._solve(trial, 1.0, thorough))

    def _solve(self, trial: Trial | None, reach: float, thorough: bool) -> Array:
        """The solver's coefficients on the identifier's estimate with the secant (:meth:`Solver.solve
        <ilc_steering.agents.solver.Solver.solve>`)."""
        identifier = self.identifier

        def restarts(target: Array) -> Array:
            return identifier.restarts(target, self.trials, self.best, thorough)

        return self.solver.solve(identifier.family, identifier.theta, self.secant, trial, reach, thorough, restarts)

    def _secant(self, anchor: Trial) -> Secant:
        """The secant correction of the refit model about ``anchor`` from the last trials."""
        family, theta = self.identifier.family, self.identifier.theta
        return secant_about(anchor, self.trials, family, theta, self.solver.scale, self._sigma_z)

    def _average(self, trial: Trial) -> None:
        """The next trial from the mean offset of the band's trials, on the refit model (step 4)."""
        # a local refit: the scatter, not the family, is what is left
        self.identifier.refit(self.trials, self.best, thorough=False)
        family, theta = self.identifier.family, self.identifier.theta
        self.best = trial
        if len(self.band.trials) == 1 or self.secant.z is None:
            # Entering the band: the secant as the trials before it taught it, kept while in the band
            # (steps of the scatter's size would fit only the scatter's draws).
            self.secant = self._secant(trial)
        c = self.band.actions()
        z, ok = final_chained(family, np.tile(theta, (c.shape[0], 1)), c)
        if not np.any(ok):
            self._next = self.solver.law(trial)
            return
        local = self.secant.A * z + (c - trial.c) @ self.secant.D.T  # the refit model with the secant, about trial
        d = self.band.offset(local, ok)
        next_c, g = self.solver.newton(family, trial.c, theta, self.model.z_goal - d, self.secant, trial.c)
        if not np.all(np.isfinite(g)):
            self._next = self.solver.law(trial)
            return
        # In the band a step corrects the scatter's draw: no longer than BAND_STEPS times the
        # longest of the last trials' steps (a near-singular corrected Jacobian would send it far).
        recent = [t.c for t in self.trials[-SECANT_TRIALS:]]
        longest = max((self.trust.length(b - a) for a, b in itertools.pairwise(recent)), default=0.0)
        self._next = self.trust.within(trial.c, next_c, BAND_STEPS * max(longest, 1e-6))


def make_robust_ilc(context: LearnerContext) -> RobustILC:
    """``compare`` method ``robust_ilc`` (and ``run --learner robust_ilc``), from the context's first trial."""
    low = np.asarray(context.action_space.low, dtype=np.float64)
    high = np.asarray(context.action_space.high, dtype=np.float64)
    return RobustILC(context.model, context.first_action(), low, high, context.carried)
