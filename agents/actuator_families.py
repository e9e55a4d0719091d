"""The actuators' families of a robot: which the identifier tries, how it searches them, which it keeps.

A car's geometry (its wheelbase and wheel radius) is not all a hobby car gets wrong: its wheel is
misaligned, its steering servo and its drive lag, its steering linkage has play.
:class:`ActuatorFamilies` holds the geometry's :class:`~ilc_steering.core.family.ModelFamily` and,
for a robot whose plant names actuator parameters (``actuator_names``: the car), the richer families
of :data:`ACTUATOR_FAMILIES`; :meth:`ActuatorFamilies.escalate` fits them in turn until one explains
the trials, and :meth:`ActuatorFamilies.simplest` keeps the simplest family that explains them about
as well as any. The identifier (:mod:`~ilc_steering.agents.identifier`) calls them when the geometry
does not explain the trials; the search is explained in ``docs/learners.md`` (``robust_ilc``'s step 1).
"""

from __future__ import annotations

import itertools
from collections.abc import Callable

import numpy as np
import numpy.typing as npt

from ilc_steering.agents.trial import Trial
from ilc_steering.core.family import ModelFamily
from ilc_steering.core.nominal import NominalModel
from ilc_steering.errors import BadInput

__all__ = [
    "ACTUATOR_FAMILIES",
    "ACTUATOR_GRID",
    "ACTUATOR_STARTS",
    "EXPLAINED",
    "FAR_BETTER",
    "GRID_FAMILIES",
    "RICHER_GAIN",
    "ActuatorFamilies",
    "Fit",
    "misfit",
    "spread",
    "squared",
]

Array = npt.NDArray[np.float64]
Fit = tuple[ModelFamily, Array, Array]
"""A fit: its family, its parameters ``theta`` and its residuals (the trials', then the ridge's)."""

ACTUATOR_FAMILIES = (
    ("steering_offset",),
    ("steering_offset", "steering_lag"),
    ("steering_offset", "steering_backlash"),
    ("steering_offset", "steering_backlash", "speed_lag"),
    ("steering_offset", "steering_backlash", "speed_lag", "steering_lag"),
)
"""The richer families, tried in turn when the geometry alone does not explain the trials: a hobby
car's misaligned wheel, lagging steering servo, play in the linkage and lagging drive. A lag-free
servo is not a limit of the lag family its integrator reaches (a lag under a quarter of its step is
stiff, and 1/128 s of lag moves experiment 2's end by 3 cm), so the play and the drive's lag grow
from the offset alone, and the steering lag comes last."""
ACTUATOR_GRID = {
    "steering_offset": np.linspace(-0.06, 0.06, 7),
    "steering_lag": np.array([1 / 128, 0.02, 0.04, 0.07, 0.1, 0.15]),
    "steering_backlash": np.array([0.0, 0.0025, 0.005, 0.01, 0.02]),
    "speed_lag": np.array([1 / 128, 0.03, 0.06, 0.1, 0.15, 0.25]),
}
"""[rad, s] the grids of the actuators' parameters in the global identification."""
GRID_FAMILIES = 2
"""The first this many richer families are searched over the product of their actuators' grids at the
geometry's best fits; each later one from its parents' best fits with the grids of what each lacks."""
ACTUATOR_STARTS = 8
"""Grid points of each richer family the Levenberg-Marquardt refinement starts from (3 found no fit of
one trial of the servo car at half the nominal wheel radius and a 0.0225 rad offset; 8 did)."""
EXPLAINED = 3e-3
"""[m or rad] a family whose fit leaves a root mean square residual below this ends the escalation
(richer families are not fitted): twice the lab's measurement noise (1 mm, 2 mrad), and well inside
the paper's 5 mm tolerance, so a model that explains the trials this well steers as the plant does.
The mean, not the largest: the largest of dozens of noisy numbers is three noises off."""
RICHER_GAIN = 2.0
"""A richer family is taken over a simpler one only if its squared misfit is below the simpler's over
this: one parameter more absorbs about one noise variance of the trials' dozens of numbers, not half."""
FAR_BETTER = 100.0
"""A richer family that does not explain the trials to :data:`EXPLAINED` is still taken if its squared
misfit is this many times below the simpler's (residuals ten times smaller): the right family whose
fit has not yet converged (the servo car's second trial, after a wild first one), not a caricature."""

Residuals = Callable[[Array, list[Trial], ModelFamily], Array]
Fits = Callable[[ModelFamily, Array, list[Trial]], list[Fit]]


def misfit(fit: Fit) -> float:
    """The largest residual of a fit's trials (its ridge left out) [m or rad]."""
    return float(np.max(np.abs(fit[2][: -fit[0].size]), initial=0.0))


def spread(fit: Fit) -> float:
    """The root mean square residual of a fit's trials (its ridge left out) [m or rad]."""
    r = fit[2][: -fit[0].size]
    return float(np.sqrt(r @ r / max(r.size, 1)))


def squared(fit: Fit) -> float:
    """The squared misfit of a fit's trials (its ridge left out)."""
    r = fit[2][: -fit[0].size]
    return float(r @ r)


class ActuatorFamilies:
    """The geometry's family of ``model`` and, for a robot with actuator parameters, the richer ones.

    Parameters
    ----------
    model
        The nominal model (never the plant).
    """

    def __init__(self, model: NominalModel) -> None:
        self.families = [ModelFamily(model)]
        """The geometry's family, then (a car) those of :data:`ACTUATOR_FAMILIES`, in order."""
        try:
            self.families += [ModelFamily(model, actuators=names) for names in ACTUATOR_FAMILIES]
        except BadInput:  # a robot without these actuators
            pass

    def escalate(
        self,
        shapes: list[Array],
        family: ModelFamily,
        theta: Array,
        trials: list[Trial],
        residuals: Residuals,
        fits: Fits,
    ) -> list[Fit]:
        """The fits of the actuators' families in turn, until one explains ``trials`` to :data:`EXPLAINED`
        (root mean square).

        The first :data:`GRID_FAMILIES` start from their actuators' grids at the geometry's ``shapes``
        (its best fit, the grid's best points: the geometry's fit to a trial the servo shaped may be
        far from the true geometry) and at the nominal; each later one from its parents' best fits
        (the richest earlier families whose parameters it holds: all four actuators' family from the
        lag's and from the play and drive's) with the grids of the actuators each lacks (the
        product of four actuators' grids would be thousands of hypotheses a trial). ``family`` at
        ``theta`` (the current estimate) starts its own family's search too. ``residuals`` and
        ``fits`` are the identifier's (:meth:`~ilc_steering.agents.identifier.Identifier.residuals`,
        :meth:`~ilc_steering.agents.identifier.Identifier.fits`)."""
        every: list[Fit] = []
        found: dict[int, list[Fit]] = {}
        for k, richer in enumerate(self.families[1:], start=1):
            if k <= GRID_FAMILIES:
                grids = [self._grown(base, 0, k) for base in [*shapes, np.zeros_like(shapes[0])]]
            else:
                grids = [self._grown(fit[1], j, k) for j in self._parents(k) for fit in found.get(j, [])]
            if not grids:
                continue
            grid = np.vstack(grids)
            r = residuals(grid, trials, richer)
            cost = np.einsum("ij,ij->i", r, r)
            starts = grid[np.argsort(cost, kind="stable")[:ACTUATOR_STARTS]]
            if richer is family:
                starts = np.vstack([theta, starts])
            found[k] = fits(richer, starts, trials)
            every += found[k]
            if min(map(spread, found[k])) < EXPLAINED:
                break
        return every

    def nearby(self, theta: Array, family: ModelFamily, trials: list[Trial], fits: Fits) -> list[Fit]:
        """The fits of the other actuators' families from ``theta`` of ``family`` alone (an actuator it
        lacks at its grid's first value): an estimate that explains the trials to the noise's level
        (:data:`EXPLAINED`) needs no grid, and a simpler family may explain them as well or exactly.
        The identifier asks once per family it holds: within its noise the estimate moves little."""
        every: list[Fit] = []
        values = dict(zip(family.names, theta))
        for other in self.families[1:]:
            if other is not family:
                start = [values[name] if name in values else ACTUATOR_GRID[name][0] for name in other.names]
                every += fits(other, np.array([start]), trials)
        return every

    def simplest(self, fits: list[Fit], numbers: int, exact: float) -> Fit:
        """The best fit of the simplest family that explains the trials about as well as any: a richer
        family's best replaces the simpler's only if its squared misfit is below the simpler's over
        :data:`RICHER_GAIN`; it explains them to :data:`EXPLAINED`, or :data:`FAR_BETTER` than the
        simpler (one that does neither would only caricature what it lacks: a segment's errors
        re-based to its via point, highway-env's held actions; one far better is the right family
        whose fit has not converged yet, after a wild trial); and the trials' ``numbers`` (measured
        numbers: four a trial in the chart) determine it: more numbers than parameters, or as many
        and a fit to ``exact`` [m or rad] (a square system always has fits, at chance points of a
        wrong family too; one that has none is the wrong family, or noise; fewer say nothing)."""
        chosen: Fit | None = None
        for family in self.families:
            own = [fit for fit in fits if fit[0] is family]
            if not own:
                continue
            best = min(own, key=squared)
            determined = numbers > family.size or (numbers == family.size and misfit(best) < exact)
            gain = squared(chosen) / max(squared(best), 1e-300) if chosen is not None else 0.0
            explains = spread(best) < EXPLAINED or gain > FAR_BETTER
            if chosen is None or (determined and explains and gain > RICHER_GAIN):
                chosen = best
        if chosen is None:
            raise ValueError("ActuatorFamilies.simplest: no fit of any family")  # a bug: the caller fitted none
        return chosen

    def _parents(self, k: int) -> list[int]:
        """The earlier richer families whose parameters are all among family ``k``'s, none of them
        within another of them (the richest ways to family ``k``; the geometry's for the first ones)."""
        names = [set(family.names) for family in self.families]
        below = [j for j in range(1, k) if names[j] < names[k]]
        return [j for j in below if not any(names[j] < names[i] for i in below)] or [0]

    def _grown(self, theta: Array, parent: int, k: int) -> Array:
        """``theta`` of family ``parent`` as points ``(G, size)`` of family ``k``, each with one point
        of the grids of the actuators ``parent`` lacks."""
        values = dict(zip(self.families[parent].names, theta))
        names = [name for name in self.families[k].names if name not in values]
        grid = np.array(list(itertools.product(*(ACTUATOR_GRID[name] for name in names))))
        points = np.empty((len(grid), self.families[k].size))
        for i, name in enumerate(self.families[k].names):
            points[:, i] = values[name] if name in values else grid[:, names.index(name)]
        return points
