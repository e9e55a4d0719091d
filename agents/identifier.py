"""The identifier: a nominal model's families of plants and the estimate fitted to the trials.

:class:`Identifier` is ``robust_ilc``'s: the geometry's family (a
:class:`~ilc_steering.core.family.ModelFamily`: a car's wheelbase and wheel radius, ...), then for a
car the actuators' families (:mod:`~ilc_steering.agents.actuator_families`: the wheel's offset, the
servo's lag, the linkage's play, the drive's lag), fitted to the trials by Levenberg-Marquardt from
the last estimate, from the best points of a grid over the whole family when that does not explain
the trials, and in the actuators' families when the geometry does not either; a new estimate
replaces the last only if it explains the trials clearly better (:meth:`Identifier.refit`). It
proposes other starts for an identified model's last search (:meth:`Identifier.restarts`), and
carries what it identified to another goal of the same robot (:meth:`Identifier.transfer`,
:func:`carried_family`). :func:`local_fit` is ``newton_ilc``'s: the geometry's family fitted from
the last estimate alone. The derivation, and where it cannot identify, is in ``docs/learners.md``
(``robust_ilc``'s step 1). Both see the nominal model and the measured trials only.
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from ilc_steering.agents.actuator_families import EXPLAINED, ActuatorFamilies, spread
from ilc_steering.agents.levenberg_marquardt import levenberg_marquardt, levenberg_marquardt_many
from ilc_steering.agents.trial import Trial
from ilc_steering.core.checks import require
from ilc_steering.core.family import MAX_LOG_RATIO, ModelFamily
from ilc_steering.core.nominal import NominalModel
from ilc_steering.errors import ParameterError

__all__ = [
    "CHART_PENALTY",
    "FIT_TOLERANCE",
    "GRID",
    "HALVINGS",
    "RESTART_FACTORS",
    "STALL",
    "Carried",
    "Identifier",
    "carried_family",
    "local_fit",
]

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
"""[m or rad] a geometry fit that leaves a trial unexplained by more than this calls the actuators' families."""
ESCALATIONS = 2
"""Failed escalations to the actuators' families after which they are not tried again (one counts only
when at least two trials stayed in the chart)."""
HALVINGS = 8
"""Step halvings of a Levenberg-Marquardt or Newton step before it is given up."""
REFIT_GAIN = 0.5
"""A new estimate of ``theta`` is taken only if its squared misfit is below this times the old one's."""
RESTART_FACTORS = (0.25, 0.5, 0.7, 1.4, 2.0, 4.0)
"""The nominal solution's ``v2`` coefficients scaled by these are the starts of the identified
model's last search (:meth:`Identifier.restarts`)."""
STALL = 1e-3
"""A fit stops after an iteration that lowers its squared misfit by at most this fraction (outside
every family all its iterations would otherwise run, each a crawl of well under a per mille)."""
_FIT_ITERATIONS = 20


@dataclass(frozen=True)
class Carried:
    """What another goal's identifier found of the same robot (:func:`carried_family`)."""

    family: ModelFamily
    """The family its estimate is of (the geometry's, when the servo's are not to be tried)."""
    theta: Array
    """Its estimate (log-ratios of the geometry, then the actuators' offset [rad] and lag [s])."""
    servo: bool
    """Whether the servo's families are still to be tried."""


class Identifier:
    """The families of ``model`` and the estimate of the plant fitted to the trials.

    Its state is its estimate (:attr:`family`, :attr:`theta`) and what its searches remember; the
    trials, the best of them and whether an update may search globally (``thorough``) are the
    caller's, handed to each call.

    Parameters
    ----------
    model
        The nominal model (never the plant).
    """

    def __init__(self, model: NominalModel) -> None:
        self.model = model
        self.actuators = ActuatorFamilies(model)
        """The geometry's family and (a car) the actuators' families, their search and choice."""
        self.families = self.actuators.families
        """The geometry's family, then (a car) the actuators' families of
        :data:`~ilc_steering.agents.actuator_families.ACTUATOR_FAMILIES`."""
        self.family = self.families[0]
        """The family of the current estimate."""
        self.goal_q = self.family.to_configuration(model.z_goal)
        """The goal's configuration [m, rad]."""
        axis = np.linspace(-MAX_LOG_RATIO, MAX_LOG_RATIO, GRID if self.family.size <= 2 else GRID_3D)
        self._grid = np.array(list(itertools.product(axis, repeat=self.family.size)))
        self.start_error = float(np.linalg.norm(self.family.to_configuration(model.z_start) - self.goal_q))
        """[m and rad] the start's distance from the goal: a trial farther off is wild (it leaves the fit)."""
        self.reset()

    def reset(self, carried: Carried | None = None) -> None:
        """Forget the trials: the geometry's family at the nominal parameters, or the ``carried`` estimate
        (without its ``servo``, the servo's families are not tried: another goal's trials showed that
        none of them explains the robot)."""
        self.forget_estimate()
        self._escalations = 0 if carried is None or carried.servo else ESCALATIONS
        self._outside = False  # whether the last thorough update went on to the grid
        self._nearby: ModelFamily | None = None  # the family whose estimate last refitted the others from itself
        self.restarted: tuple[tuple[str, ...], bytes] | None = None
        """The estimate (family names, ``theta`` bytes) that :meth:`restarts` last searched from."""
        if carried is not None:
            self.family, self.theta = carried.family, carried.theta.copy()

    def forget_estimate(self) -> None:
        """The geometry's family at the nominal parameters."""
        self.family = self.families[0]
        self.theta = np.zeros(self.family.size)

    @property
    def servo(self) -> bool:
        """Whether the servo's families are still tried (not after :data:`ESCALATIONS` failed to explain trials)."""
        return self._escalations < ESCALATIONS

    def transfer(self) -> dict[str, Any]:
        """What it identified of the robot: the family's parameters by name and whether the servo's
        families are still tried (:func:`carried_family` reads it back)."""
        parameters = dict(zip(self.family.names, map(float, self.theta)))
        return {"parameters": parameters, "servo": self.servo}

    def fit_trials(self, trials: list[Trial], best: Trial | None) -> list[Trial]:
        """The trials the estimate is fitted to: at most :data:`FIT_TRIALS` of ``trials``, ``best``
        (the best so far) among them; a wild trial (farther off than the start) is left out once two
        others stayed in the chart."""
        tame = [t for t in trials if not (t.ok and t.error > self.start_error)]
        trials = tame if sum(t.ok for t in tame) >= 2 else trials
        if len(trials) <= FIT_TRIALS:
            return trials
        keep = trials[-(FIT_TRIALS - 1) :]
        if best is not None and all(t is not best for t in keep):
            keep = [best, *keep[1:]]
        return keep

    def residuals(self, thetas: Array, trials: list[Trial], family: ModelFamily | None = None) -> Array:
        """Residuals ``(M, R)`` [m or rad] of hypotheses ``thetas`` ``(M, size)`` of ``family`` (the current
        one by default) against ``trials``."""
        family = self.family if family is None else family
        m, k = thetas.shape[0], len(trials)
        c = np.tile(np.array([t.c for t in trials]), (m, 1))
        q, ok = family.configurations_many(np.repeat(thetas, k, axis=0), c)
        q, ok = q.reshape(m, k, -1), ok.reshape(m, k)
        measured_ok = np.array([t.ok for t in trials])
        y = np.array([t.q if t.ok else np.zeros_like(self.goal_q) for t in trials])
        r = np.where((ok & measured_ok)[..., None], q - y, 0.0)
        r = np.where((ok != measured_ok)[..., None], CHART_PENALTY, r)
        return np.concatenate([r.reshape(m, -1), RIDGE * thetas], axis=1)

    def misfit(self, r: Array) -> float:
        """The largest residual of the trials (the ridge left out) [m or rad]."""
        return float(np.max(np.abs(r[: -self.family.size]), initial=0.0))

    def explains(self, trials: list[Trial], best: Trial | None) -> bool:
        """Whether the estimate explains every trial it is fitted to, to :data:`FIT_TOLERANCE`."""
        return self.misfit(self.residuals(self.theta[None], self.fit_trials(trials, best))[0]) < FIT_TOLERANCE

    def refit(self, trials: list[Trial], best: Trial | None, thorough: bool) -> None:
        """The estimate refitted to ``trials`` (globally if ``thorough``), kept only if it explains the
        trials clearly better (its squared misfit below :data:`REFIT_GAIN` times the old one's): a model
        outside every family has fits of about equal misfit far apart, and a jump between them changes
        the Jacobian the secant was learned against for nothing."""
        family, theta = self._identify(trials, best, thorough)
        if family is self.family and np.array_equal(theta, self.theta):
            self.family, self.theta = family, theta
            return
        fitted = self.fit_trials(trials, best)  # a halted trial counts by its chart penalty
        old, new = (
            float(np.sum(self.residuals(th[None], fitted, fam)[0][: -fam.size] ** 2))
            for fam, th in ((self.family, self.theta), (family, theta))
        )
        if new < REFIT_GAIN * old:
            self.family, self.theta = family, theta

    def _identify(self, trials: list[Trial], best_trial: Trial | None, thorough: bool) -> tuple[ModelFamily, Array]:
        """LM from the last estimate; when that does not explain the trials to :data:`FIT_TOLERANCE`,
        also from the best points of the grid over the whole family; when that does not either, the
        actuators' families in turn until one explains the trials to :data:`EXPLAINED` in root mean
        square (an estimate of theirs that does: the other families from it alone), and the simplest
        family that explains them about as well as any (:meth:`ActuatorFamilies.simplest`) is taken.

        Where the last thorough update went on to the grid (the trials are outside the geometry's
        family), the grid's starts run in lockstep with the last estimate's from the outset: the
        same fits, bit for bit, in fewer and fuller calls of the kernel."""
        trials = self.fit_trials(trials, best_trial)
        family = self.family
        geometry = self.families[0]
        r = self.residuals(self.theta[None], trials)[0]
        if self.misfit(r) < FIT_TOLERANCE:  # the last estimate explains the new trial too
            return family, self.theta
        ahead = family is geometry and thorough and self._outside
        starts = self._grid_starts(trials) if ahead else np.empty((0, family.size))
        fits = self.fits(family, np.vstack([self.theta, starts]), trials)
        _, theta, r = fits[0]
        if self.misfit(r) < FIT_TOLERANCE or not thorough:
            self._outside = self._outside and not thorough
            return family, theta
        if family is geometry:
            self._outside = True
            if not ahead:
                fits += self.fits(family, self._grid_starts(trials), trials)
            best = min(fits, key=lambda fit: float(fit[2] @ fit[2]))
            if self.misfit(best[2]) < ESCALATE or len(self.families) == 1 or self._escalations >= ESCALATIONS:
                return best[0], best[1]
            shapes = [best[1], *self._grid_starts(trials)]
            fits += self.actuators.escalate(shapes, family, theta, trials, self.residuals, self.fits)
        elif spread(fits[0]) < EXPLAINED:  # explained to the noise: the other families from the estimate alone,
            if family is self._nearby:  # once per family (the estimate moves within its noise)
                return family, theta
            self._nearby = family
            fits += self.actuators.nearby(theta, family, trials, self.fits)
        else:
            fits += self.actuators.escalate([theta[: geometry.size]], family, theta, trials, self.residuals, self.fits)
        chosen = self.actuators.simplest(fits, sum(t.ok for t in trials) * self.goal_q.size, FIT_TOLERANCE)
        if chosen[0] is geometry:  # no actuator explains the trials better than the geometry does
            self._escalations += int(sum(t.ok for t in trials) >= 2)
        return chosen[0], chosen[1]

    def restarts(self, target: Array, trials: list[Trial], best: Trial | None, thorough: bool) -> Array:
        """Starts ``(S, 1 + q)`` of a last search for coefficients that bring the refit model to
        ``target`` (chained), once per estimate, on a ``thorough`` update whose estimate explains every
        trial: the nominal solution with its ``v2`` coefficients scaled by :data:`RESTART_FACTORS`.

        An identified model's solvers may end at a local minimum off the goal where the plant's own
        solutions lie on another branch: the continuation from the nominal model folds on the way
        (the car-trailer with half the nominal wheelbase, 16 mm off the goal; the servo car at a
        0.03 rad offset, 6 mm off), and Newton from the trials stays in their basin. The identified
        model is then the plant, and its other branches cost simulations, not trials. None (an
        empty array) where the estimate does not explain the trials: its solutions would be no
        better than its fit."""
        key = (self.family.names, self.theta.tobytes())
        if not thorough or key == self.restarted or not trials:
            return np.empty((0, self.model.solve().size))
        if self.misfit(self.residuals(self.theta[None], self.fit_trials(trials, best))[0]) >= FIT_TOLERANCE:
            return np.empty((0, self.model.solve().size))
        self.restarted = key
        c = self.model.solve(z_goal=target)
        return np.array([np.concatenate([c[:1], factor * c[1:]]) for factor in RESTART_FACTORS])

    def _grid_starts(self, trials: list[Trial]) -> Array:
        """The :data:`GRID_STARTS` points of the geometry's grid that explain ``trials`` best."""
        values = self.residuals(self._grid, trials)
        cost = np.einsum("ij,ij->i", values, values)
        return self._grid[np.argsort(cost, kind="stable")[:GRID_STARTS]]

    def fits(self, family: ModelFamily, starts: Array, trials: list[Trial]) -> list[tuple[ModelFamily, Array, Array]]:
        """The fits ``(family, theta, r)`` of Levenberg-Marquardt to ``trials`` from each of ``starts``
        ``(S, size)``, in lockstep (each bit for bit the fit from that start alone)."""
        thetas, r = levenberg_marquardt_many(
            lambda thetas: self.residuals(thetas, trials, family),
            starts,
            family.low,
            family.high,
            _FIT_ITERATIONS,
            HALVINGS,
            lambda r: float(np.max(np.abs(r[: -family.size]), initial=0.0)) < 1e-3 * FIT_TOLERANCE,
            STALL,
        )
        return [(family, theta, residual) for theta, residual in zip(thetas, r)]


def carried_family(families: list[ModelFamily], carried: Mapping[str, Any]) -> Carried:
    """The family of ``families``, the parameters another goal's ``robust_ilc`` identified (its
    ``transfer()``) and whether the servo's families are still to be tried (true if not said), as a
    :class:`Carried`; :class:`~ilc_steering.errors.ParameterError` naming what does not fit. The next
    goal's first trial is the carried model's plan; one that leaves the chart (or is refused) is
    dropped, and the nominal plan is next.

    A robot that none of the servo's families explained on one goal (:data:`ESCALATIONS` failures:
    highway-env's car, whose actions are held 0.2 s and whose speed is a loop) is not expected to
    be explained by them on the next, and trying them again costs a trial: one trial's four numbers
    are fitted exactly by the servo's four parameters at a chance point of a wrong family, whose
    Jacobian sends the second trial off; the geometry's two are overdetermined by one trial. Such a
    goal carries its geometry alone; docs/highway.md measures what carrying gains."""
    found = carried.get("robust_ilc") if isinstance(carried, Mapping) else None
    ok = isinstance(found, Mapping) and isinstance(found.get("parameters"), Mapping)
    require(
        ok, "context.carried", f"is not robust_ilc's transfer() ({{'robust_ilc': {{'parameters': ...}}}}): {carried!r}"
    )
    values, servo = found["parameters"], found.get("servo", True)  # type: ignore[index,union-attr]
    require(isinstance(servo, bool), "context.carried", f"robust_ilc's 'servo' must be true or false, got {servo!r}")
    for family in families:
        if list(family.names) == list(values):
            theta = np.array([values[name] for name in family.names], dtype=np.float64)
            inside = np.all(np.isfinite(theta)) and np.all(theta >= family.low) and np.all(theta <= family.high)
            require(bool(inside), "context.carried", f"robust_ilc's {dict(values)} lie outside the family's bounds")
            if not servo:  # the servo's parameters of a family that did not explain the robot: the geometry's only
                family, theta = families[0], theta[: families[0].size]
            return Carried(family, theta, servo)
    names = [list(f.names) for f in families]
    raise ParameterError("context.carried", f"parameters {list(values)} are none of this robot's families {names}")


def local_fit(family: ModelFamily, trials: list[Trial], theta: Array) -> Array:
    """``newton_ilc``'s fit: Levenberg-Marquardt from ``theta`` on every trial's configuration residual
    [m or rad] plus the ridge :data:`RIDGE`, all trials of a hypothesis in one kernel call (a trial
    the model halts is a poor fit, a residual of 1, not a NaN)."""
    c = np.array([t.c for t in trials])
    y = np.array([t.q for t in trials])

    def residuals(thetas: Array) -> Array:  # every hypothesis's trials in one kernel call
        m, k = thetas.shape[0], c.shape[0]
        q, ok = family.configurations_many(np.repeat(thetas, k, axis=0), np.tile(c, (m, 1)))
        r = np.where(ok[:, None], q - np.tile(y, (m, 1)), 1.0)  # a halted model trial is a poor fit, not a NaN
        return np.concatenate([r.reshape(m, -1), RIDGE * thetas], axis=1)

    bound = np.full(theta.size, MAX_LOG_RATIO)
    return levenberg_marquardt(residuals, theta, -bound, bound, _FIT_ITERATIONS)[0]
