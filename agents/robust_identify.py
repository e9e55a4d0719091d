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
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from ilc_steering.agents.model_based import Trial, final_chained, levenberg_marquardt_many
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
    "SECANT_TRIALS",
    "STALL",
    "GlobalIdentification",
    "Secant",
    "carried_family",
    "chained_scatter",
    "fit_secant",
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
"""[m or rad] a geometry fit that leaves a trial unexplained by more than this calls the servo's families."""
EXPLAINED = 1e-5
"""[m or rad] a servo family is kept only if it explains every trial this well."""
ESCALATIONS = 2
"""Failed escalations to the servo's families after which they are not tried again (one counts only
when at least two trials stayed in the chart: one trial's final configuration, four numbers, has
several exact fits among the servo's four parameters and none the fit may find from a wild trial)."""
ACTUATOR_FAMILIES = (("steering_offset",), ("steering_offset", "steering_lag"))
"""The richer families, tried in turn when the geometry alone does not explain the trials."""
ACTUATOR_GRID = {
    "steering_offset": np.linspace(-0.06, 0.06, 7),
    "steering_lag": np.array([1 / 128, 0.02, 0.04, 0.07, 0.1, 0.15]),
}
"""[rad, s] the grids of the servo's parameters in the global identification."""
ACTUATOR_STARTS = 8
"""Grid points of each richer family the Levenberg-Marquardt refinement starts from (3 found no fit of
one trial of the servo car at half the nominal wheel radius and a 0.0225 rad offset; 8 did)."""
HALVINGS = 8
"""Step halvings of a Levenberg-Marquardt or Newton step before it is given up."""
SECANT_TRIALS = 6
"""The trials beside the anchor that the secant correction is fitted to."""
SECANT_SCATTER = (2e-3, 4e-3)
"""[m, rad] the scatter of a measured final configuration the secant assumes: a pose's x and y, its
angles (for a robot without a pose, the first for every coordinate)."""
SECANT_CURVATURE = 0.2
"""[chained units per action scale squared] a step's linearization error over its length squared (1.0
before: the simulated lab robot's first trials, 270 and 160 mm off, then taught the secant too little;
its fifth trial is within the tolerance on 18 of seeds 0-19 from 0.15 to 0.2, 17 at 0.25, 12 at 0.3)."""
SECANT_PRIOR = 1.0
"""[chained units per action scale] the prior size of an entry of the Jacobian's correction ``D`` (3.0
before: where the first trials' steps say little, the refit model's Jacobian is kept; with these two
and ``robust_ilc.SHRINK`` the lab robot's fifth trial lands 3 mm off, median of seeds 0-19, not 10)."""
GAIN_PRIOR = 1.0
"""The prior size of ``A - 1``, the correction of the refit model's gain per chained coordinate."""
MAX_GAIN = 4.0
"""The gains ``A`` stay within this factor of 1."""
REFIT_GAIN = 0.5
"""A new estimate of ``theta`` is taken only if its squared misfit is below this times the old one's."""
RESTART_FACTORS = (0.25, 0.5, 0.7, 1.4, 2.0, 4.0)
"""The nominal solution's ``v2`` coefficients scaled by these are the starts of the identified
model's last search (:meth:`GlobalIdentification.restarts`)."""
STALL = 1e-3
"""A fit stops after an iteration that lowers its squared misfit by at most this fraction (outside
every family all its iterations would otherwise run, each a crawl of well under a per mille)."""
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
        self._scale = model.action_scale()
        self._sigma_z = chained_scatter(self.family, self._goal_q, model)
        self._start_error = float(np.linalg.norm(self.family.to_configuration(model.z_start) - self._goal_q))
        self.reset_identification()

    def reset_identification(self, servo: bool = True) -> None:
        """Forget the trials: the geometry's family at the nominal parameters (without ``servo``, the servo's
        families are not tried: another goal's trials showed that none of them explains the robot)."""
        self.family = self._families[0]
        self.theta = np.zeros(self.family.size)
        self._escalations = 0 if servo else ESCALATIONS
        self._trials: list[Trial] = []
        self._best: Trial | None = None
        self._thorough = True
        self._outside = False  # whether the last thorough update went on to the grid
        self._restarted: tuple[tuple[str, ...], bytes] | None = None  # the estimate restarts() last searched

    @property
    def servo(self) -> bool:
        """Whether the servo's families are still tried (not after :data:`ESCALATIONS` failed to explain trials)."""
        return self._escalations < ESCALATIONS

    def _fit_trials(self) -> list[Trial]:
        tame = [t for t in self._trials if not (t.ok and t.error > self._start_error)]  # a wild trial (step 1)
        trials = tame if sum(t.ok for t in tame) >= 2 else self._trials
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
            geometry = [best[1], *self._grid_starts(trials)]
        else:
            geometry = [theta[: self._families[0].size]]
        for richer in self._families[1:]:
            # The servo's parameters on their own grid, the geometry at its best fit, at the grid's
            # best points (the geometry's fit to a trial the servo shaped may be far from the true
            # geometry) and at the nominal.
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
            self._escalations += int(sum(t.ok for t in trials) >= 2)
        return best[0], best[1]

    def restarts(self, target: Array) -> Array:
        """Starts ``(S, 1 + q)`` of a last search for coefficients that bring the refit model to
        ``target`` (chained), once per estimate, on a thorough update whose estimate explains every
        trial: the nominal solution with its ``v2`` coefficients scaled by :data:`RESTART_FACTORS`.

        An identified model's solvers may end at a local minimum off the goal where the plant's own
        solutions lie on another branch: the continuation from the nominal model folds on the way
        (the car-trailer with half the nominal wheelbase, 16 mm off the goal; the servo car at a
        0.03 rad offset, 6 mm off), and Newton from the trials stays in their basin. The identified
        model is then the plant, and its other branches cost simulations, not trials. None (an
        empty array) where the estimate does not explain the trials: its solutions would be no
        better than its fit."""
        key = (self.family.names, self.theta.tobytes())
        if not self._thorough or key == self._restarted or not self._trials:
            return np.empty((0, self.model.solve().size))
        if self._misfit(self._residuals(self.theta[None], self._fit_trials())[0]) >= FIT_TOLERANCE:
            return np.empty((0, self.model.solve().size))
        self._restarted = key
        c = self.model.solve(z_goal=target)
        return np.array([np.concatenate([c[:1], factor * c[1:]]) for factor in RESTART_FACTORS])

    def _refit(self) -> tuple[ModelFamily, Array]:
        """The identification's new estimate, kept only if it explains the trials clearly better
        (its squared misfit below :data:`REFIT_GAIN` times the old one's): a model outside every
        family has fits of about equal misfit far apart, and a jump between them changes the
        Jacobian the secant was learned against for nothing."""
        family, theta = self._identify()
        if family is self.family and np.array_equal(theta, self.theta):
            return family, theta
        trials = self._fit_trials()  # a halted trial counts by its chart penalty
        old, new = (
            float(np.sum(self._residuals(th[None], trials, fam)[0][: -fam.size] ** 2))
            for fam, th in ((self.family, self.theta), (family, theta))
        )
        return (family, theta) if new < REFIT_GAIN * old else (self.family, self.theta)

    def secant(self, anchor: Trial) -> Secant:
        """The secant correction of the refit model about ``anchor`` (:func:`fit_secant`) from the
        anchor and the last :data:`SECANT_TRIALS` other in-chart trials."""
        n, p = self.model.dimension, self._scale.size
        others = [t for t in self._trials[-SECANT_TRIALS - 1 :] if t.ok and t is not anchor][-SECANT_TRIALS:]
        if not anchor.ok:
            return Secant.none(n, p)
        c = np.array([anchor.c, *[t.c for t in others]])
        F, ok = final_chained(self.family, np.tile(self.theta, (c.shape[0], 1)), c)
        if not np.all(ok):
            return Secant.none(n, p, anchor.z)
        found = fit_secant(F, np.array([anchor.z, *[t.z for t in others]]), (c - c[0]) / self._scale, self._sigma_z)
        return Secant(found.A, found.D / self._scale, found.z)

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
            STALL,
        )
        return [(family, theta, residual) for theta, residual in zip(thetas, r)]


def carried_family(families: list[ModelFamily], carried: Mapping[str, Any]) -> tuple[ModelFamily, Array, bool]:
    """The family of ``families``, the parameters another goal's ``robust_ilc`` identified (its
    ``transfer()``) and whether the servo's families are still to be tried (true if not said);
    ``ValueError`` naming what does not fit. The next goal's first trial is the carried model's
    plan; one that leaves the chart (or is refused) is dropped, and the nominal plan is next.

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
            return family, theta, servo
    names = [list(f.names) for f in families]
    raise ParameterError("context.carried", f"parameters {list(values)} are none of this robot's families {names}")


@dataclass(frozen=True)
class Secant:
    """What the trials teach about the refit model ``F`` near a trial ``c_a``: the measured outcome
    is ``z_a + A * (F(c) - F(c_a)) + D (c - c_a)``, ``A`` a gain per chained coordinate, ``D`` a
    correction of the Jacobian, ``z_a`` the anchor's outcome as the fit smooths it (None: as
    measured)."""

    A: Array
    D: Array
    z: Array | None = None

    @staticmethod
    def none(n: int, p: int, z: Array | None = None) -> Secant:
        """No correction (``n`` chained coordinates, ``p`` coefficients)."""
        return Secant(np.ones(n), np.zeros((n, p)), z)

    def part(self, s: float) -> Secant:
        """The fraction ``s`` of the correction (the homotopy's)."""
        return Secant(1.0 + s * (self.A - 1.0), s * self.D, self.z)


def fit_secant(F: Array, z: Array, S: Array, sigma: Array) -> Secant:
    """The :class:`Secant` about trial 0 from trials ``(m,)``: the refit model's outcomes ``F`` and
    the measured ones ``z`` ``(m, n)``, the steps ``S`` ``(m, p)`` from trial 0 (in action scales,
    ``S[0] = 0``) and the assumed scatter ``sigma`` ``(n,)`` of each chained coordinate. ``D`` is in
    chained units per action scale.

    Per chained coordinate ``j``, a weighted ridge regression of what the model leaves,
    ``z - F = b + (A - 1) (F - F_0) + D s``: ``b`` free (it smooths the anchor's scatter: every
    trial near it counts), ``A - 1`` and ``D`` pulled to 0 by :data:`GAIN_PRIOR` and
    :data:`SECANT_PRIOR`. A trial's equation has the scatter's error and the linearization's,
    which grows as the step's square: weight ``1 / sqrt(sigma^2 + (SECANT_CURVATURE |s|^2)^2)``, so
    the near trials set the Jacobian the next step needs and steps within the scatter set nothing.
    """
    m, n = F.shape
    p = S.shape[1]
    curvature = SECANT_CURVATURE * np.sum(S**2, axis=1)
    weights = 1.0 / np.hypot(sigma[None, :], curvature[:, None])  # (m, n)
    prior = np.diag([0.0, GAIN_PRIOR**-2, *([SECANT_PRIOR**-2] * p)])
    A, D, b = np.ones(n), np.zeros((n, p)), np.zeros(n)
    for j in range(n):
        X = np.column_stack([np.ones(m), F[:, j] - F[0, j], S]) * weights[:, j : j + 1]
        beta = np.linalg.solve(X.T @ X + prior, X.T @ ((z[:, j] - F[:, j]) * weights[:, j]))
        b[j], A[j], D[j] = beta[0], 1.0 + beta[1], beta[2:]
    return Secant(np.clip(A, 1.0 / MAX_GAIN, MAX_GAIN), D, F[0] + b)


def chained_scatter(family: ModelFamily, goal_q: Array, model: NominalModel) -> Array:
    """[chained units] the scatter of each chained coordinate that :func:`fit_secant` assumes:
    :data:`SECANT_SCATTER` of the configuration through the nominal map's Jacobian at the goal."""
    h = 1e-7
    z0 = family.to_chained(goal_q)
    J = np.array([(family.to_chained(goal_q + h * e) - z0) / h for e in np.eye(goal_q.size)]).T
    if getattr(model.chained_map, "has_pose", False):
        sigma_q = np.array([SECANT_SCATTER[0] if k < 2 else SECANT_SCATTER[1] for k in range(goal_q.size)])
    else:
        sigma_q = np.full(goal_q.size, SECANT_SCATTER[0])
    return np.asarray(np.sqrt((J**2) @ sigma_q**2))
