"""``robust_ilc``'s step 1: the global identification of the plant, in widening families.

A :class:`GlobalIdentification` holds a nominal model's families (the geometry's, then for a car
with a steering servo the geometry with the wheel's offset, then with the servo's lag) and fits
them to the trials run so far: Levenberg-Marquardt from the last estimate, a grid over the whole
family when that does not explain the trials, the servo's families when the geometry does not
either. The derivation, and where it cannot identify, is in :mod:`~ilc_steering.agents.robust_ilc`'s
docstring (its step 1).
"""

from __future__ import annotations

import itertools

import numpy as np
import numpy.typing as npt

from ilc_steering.agents.model_based import Trial, levenberg_marquardt_many
from ilc_steering.core.family import MAX_LOG_RATIO, ModelFamily
from ilc_steering.core.nominal import NominalModel

__all__ = ["CHART_PENALTY", "FIT_TOLERANCE", "GRID", "HALVINGS", "GlobalIdentification"]

Array = npt.NDArray[np.float64]

GRID = 13
"""Grid points per family parameter of the global identification (over ``+-MAX_LOG_RATIO``)."""
GRID_3D = 7
"""The same for a family of three parameters (a car with a trailer)."""
CHART_PENALTY = 10.0
"""[m or rad] residual of a hypothesis that disagrees with a trial about leaving the chart."""
RIDGE = 1e-4
"""[m or rad per unit of theta] the pull of ``theta`` to 0 where the trials say nothing."""
FIT_TOLERANCE = 1e-7
"""[m or rad] a fit that explains every trial this well is not searched for globally."""
GRID_STARTS = 6
"""Grid points the Levenberg-Marquardt refinement starts from."""
FIT_TRIALS = 8
"""The identification uses at most this many trials: the best, the halted ones among the first and the latest."""
ESCALATE = 1e-6
"""[m or rad] a geometry fit that leaves a trial unexplained by more than this calls the servo's families."""
EXPLAINED = 1e-5
"""[m or rad] a servo family is kept only if it explains every trial this well."""
ESCALATIONS = 2
"""Failed escalations to the servo's families after which they are not tried again."""
ACTUATOR_FAMILIES = (("steering_offset",), ("steering_offset", "steering_lag"))
"""The richer families, tried in turn when the geometry alone does not explain the trials."""
ACTUATOR_GRID = {
    "steering_offset": np.linspace(-0.06, 0.06, 7),
    "steering_lag": np.array([1 / 128, 0.02, 0.04, 0.07, 0.1, 0.15]),
}
"""[rad, s] the grids of the servo's parameters in the global identification."""
ACTUATOR_STARTS = 3
"""Grid points of each richer family the Levenberg-Marquardt refinement starts from."""
HALVINGS = 8
"""Step halvings of a Levenberg-Marquardt or Newton step before it is given up."""
_FIT_ITERATIONS = 20


class GlobalIdentification:
    """The families of ``model`` and the trials they are fitted to (the learner's own: it appends to
    ``_trials``, and sets ``_best``, the best trial so far, and ``_thorough``, whether this update
    may search globally).

    Parameters
    ----------
    model
        The nominal model (never the plant).
    """

    def __init__(self, model: NominalModel) -> None:
        self.model = model
        self._families = [ModelFamily(model)]
        """The geometry's family, then (a car) with the steering offset, then with the offset and the lag."""
        try:
            self._families += [ModelFamily(model, actuators=names) for names in ACTUATOR_FAMILIES]
        except ValueError:  # a robot without a steering servo
            pass
        self.family = self._families[0]
        self._goal_q = self.family.to_configuration(model.z_goal)
        axis = np.linspace(-MAX_LOG_RATIO, MAX_LOG_RATIO, GRID if self.family.size <= 2 else GRID_3D)
        self._grid = np.array(list(itertools.product(axis, repeat=self.family.size)))
        self.reset_identification()

    def reset_identification(self) -> None:
        """Forget the trials: the geometry's family at the nominal parameters."""
        self.family = self._families[0]
        self.theta = np.zeros(self.family.size)
        self._escalations = 0
        self._trials: list[Trial] = []
        self._best: Trial | None = None
        self._thorough = True
        self._outside = False  # whether the last thorough update went on to the grid

    def _fit_trials(self) -> list[Trial]:
        trials = self._trials
        if len(trials) <= FIT_TRIALS:
            return trials
        keep = trials[-(FIT_TRIALS - 1) :]
        if self._best is not None and all(t is not self._best for t in keep):
            keep = [self._best, *keep[1:]]
        return keep

    def _residuals(self, thetas: Array, trials: list[Trial], family: ModelFamily | None = None) -> Array:
        """Residuals ``(M, R)`` of hypotheses ``thetas`` ``(M, size)`` of ``family`` (the current
        one by default) against ``trials``."""
        family = self.family if family is None else family
        m, k = thetas.shape[0], len(trials)
        c = np.tile(np.array([t.c for t in trials]), (m, 1))
        q, ok = family.configurations_many(np.repeat(thetas, k, axis=0), c)
        q, ok = q.reshape(m, k, -1), ok.reshape(m, k)
        measured_ok = np.array([t.ok for t in trials])
        y = np.array([t.q if t.ok else np.zeros_like(self._goal_q) for t in trials])
        r = np.where((ok & measured_ok)[..., None], q - y, 0.0)
        r = np.where((ok != measured_ok)[..., None], CHART_PENALTY, r)
        return np.concatenate([r.reshape(m, -1), RIDGE * thetas], axis=1)

    def _identify(self) -> tuple[ModelFamily, Array]:
        """LM from the last estimate; when that does not explain the trials to :data:`FIT_TOLERANCE`,
        also from the best points of the grid over the whole family; when that does not either,
        the families with the steering servo's parameters (the best fit of all is kept).

        Where the last thorough update went on to the grid (the trials are outside the geometry's
        family), the grid's starts run in lockstep with the last estimate's from the outset: the
        same fits, bit for bit, in fewer and fuller calls of the kernel."""
        trials = self._fit_trials()
        family = self.family
        r = self._residuals(self.theta[None], trials)[0]
        if self._misfit(r) < FIT_TOLERANCE:  # the last estimate explains the new trial too
            return family, self.theta
        ahead = family is self._families[0] and self._thorough and self._outside
        starts = self._grid_starts(trials) if ahead else np.empty((0, family.size))
        fits = self._levenberg_marquardt(family, np.vstack([self.theta, starts]), trials)
        _, theta, r = fits[0]
        if self._misfit(r) < FIT_TOLERANCE or not self._thorough:
            self._outside = self._outside and not self._thorough
            return family, theta
        if family is self._families[0]:
            self._outside = True
            if not ahead:
                fits += self._levenberg_marquardt(family, self._grid_starts(trials), trials)
            best = min(fits, key=lambda fit: float(fit[2] @ fit[2]))
            if self._misfit(best[2]) < ESCALATE or len(self._families) == 1 or self._escalations >= ESCALATIONS:
                return best[0], best[1]
            geometry = [best[1]]
        else:
            geometry = [theta[: self._families[0].size]]
        for richer in self._families[1:]:
            # The servo's parameters on their own grid, the geometry at its best fit and at the nominal.
            n = richer.size - geometry[0].size
            axes = [ACTUATOR_GRID[name] for name in richer.names[-n:]]
            grid = np.array(
                [
                    np.concatenate([g, a])
                    for g in [*geometry, np.zeros_like(geometry[0])]
                    for a in itertools.product(*axes)
                ]
            )
            values = self._residuals(grid, trials, richer)
            cost = np.einsum("ij,ij->i", values, values)
            starts = grid[np.argsort(cost, kind="stable")[:ACTUATOR_STARTS]]
            if richer is family:
                starts = np.vstack([theta, starts])
            fits += self._levenberg_marquardt(richer, starts, trials)
        best = min(fits, key=lambda fit: float(fit[2] @ fit[2]))
        if best[0] is not self._families[0] and float(np.max(np.abs(best[2][: -best[0].size]))) > EXPLAINED:
            # The servo does not explain the trials either (backlash, noise, another lag): its
            # parameters would only caricature what it lacks; the geometry's fit is kept.
            geometric = [fit for fit in fits if fit[0] is self._families[0]]
            best = min(geometric, key=lambda fit: float(fit[2] @ fit[2])) if geometric else best
            self._escalations += 1
        return best[0], best[1]

    def _grid_starts(self, trials: list[Trial]) -> Array:
        """The :data:`GRID_STARTS` points of the geometry's grid that explain ``trials`` best."""
        values = self._residuals(self._grid, trials)
        cost = np.einsum("ij,ij->i", values, values)
        return self._grid[np.argsort(cost, kind="stable")[:GRID_STARTS]]

    def _misfit(self, r: Array) -> float:
        """The largest residual of the trials (the ridge left out) [m or rad]."""
        return float(np.max(np.abs(r[: -self.family.size]), initial=0.0))

    def _levenberg_marquardt(
        self, family: ModelFamily, starts: Array, trials: list[Trial]
    ) -> list[tuple[ModelFamily, Array, Array]]:
        """The fits ``(family, theta, r)`` of Levenberg-Marquardt from each of ``starts`` ``(S, size)``,
        in lockstep (each bit for bit the fit from that start alone)."""
        thetas, r = levenberg_marquardt_many(
            lambda thetas: self._residuals(thetas, trials, family),
            starts,
            family.low,
            family.high,
            _FIT_ITERATIONS,
            HALVINGS,
            lambda r: float(np.max(np.abs(r[: -family.size]), initial=0.0)) < 1e-3 * FIT_TOLERANCE,
        )
        return [(family, theta, residual) for theta, residual in zip(thetas, r)]
