r"""How far a plant scatters its final pose for one action: the estimate every command and learner shares.

A real robot does not repeat itself: the same coefficients ``c`` end in a pose scattered by its
contacts, its wheels' slip, its localization. Seen from the trials, a final pose (or measured
pose: the two are the same to a learner) is

.. math::

    y_k = F(c_k) + w_k, \qquad w_k \sim N(0, \sigma^2) \text{ per coordinate, independent between trials},

and no learner can bring the error below the scatter for good. :func:`estimate` estimates
:math:`\sigma` from a run's own trials, with no trial of its own, from the residuals
:math:`r_k = y_k - \hat F(c_k)` of a model :math:`\hat F` the caller has (``run``: the nominal
model's eq. 23; a learner: its refit model). Over the trials near the end of the run
(:data:`WINDOW`; those within :data:`SPREAD` times the median measured error of the window, so
that the first, far trials do not count), it takes the residuals' standard deviation about
their mean, per coordinate, pooled within each group of coordinates (a pose's x and y [m]; its
heading [rad]), with ``m - 1`` degrees of freedom per coordinate.

What it assumes: the scatter is independent from trial to trial and of the same size for the
coordinates pooled; the model's error :math:`F - \hat F` is nearly constant over the actions of
the trials used. That holds near convergence, where the actions differ by the scatter's
corrections: a model 10 % off changes its error by a tenth of the pose's change, and the
estimate by about 1 %. Far from it the change of the model's error reads as scatter, and the
estimate is high; hence :data:`SPREAD`, and no estimate while the errors still fall steadily
(:data:`CONVERGING`: a noiseless run that contracts slowly has no scatter to report). Nor may
the learner be far from its fixed point: a learner that oscillates or diverges leaves its own
moves in the residuals. A learner's repeat of an action is a trial like any other here.
Measurement noise and a scattered pose look the same from the trials: both count.

:data:`HOLD` and :data:`FLOOR` are what ``ilc-steering run`` judges a run by: converged when the
last :data:`HOLD` trials are within the tolerance, and a tolerance below :data:`FLOOR` times the
estimated scatter is below the plant's repeatability.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import numpy.typing as npt

from ilc_steering.errors import BadInput

__all__ = [
    "CONVERGING",
    "FLOOR",
    "HOLD",
    "MIN_SCATTER",
    "MIN_TRIALS",
    "SPREAD",
    "WINDOW",
    "estimate",
    "repeatability",
    "repeats",
]

Array = npt.NDArray[np.float64]

HOLD = 3
"""Consecutive trials within the tolerance, at the end of a run, for the run to count as converged.
One trial within it may be a lucky draw of the scatter (a trial that meets the tolerance by chance
with probability 0.3 does so three times in a row with probability 0.027), and a learner that
chases the scatter leaves again; three in a row at the end rule both out at the cost of two trials."""
FLOOR = 3.0
"""The plant's repeatability in units of its scatter ``sigma`` per coordinate: a perfectly aimed
trial lands farther than ``3 sigma`` from the goal with probability exp(-4.5) = 1.1 % in the plane
(x and y) and 0.27 % in the heading, so a tolerance below it cannot be held for :data:`HOLD`
trials by any learner."""
WINDOW = 20
"""The last this many trials (those that stayed in the chart) are the estimate's candidates."""
SPREAD = 4.0
"""A candidate counts if its measured error is at most this times the median of the candidates':
the far trials of the start of a run, where the model's error changes with the action, are left out."""
CONVERGING = 0.7
"""Trials whose measured errors fall by more than 30 % a trial (the slope of their logarithm) are
still converging: no estimate. A scattered plant's errors do not fall (the slope's standard error
over 13 trials is about 0.05, against 0.36 for this bound); eqs. 33-34 contracting by 0.47 a trial
on the saturated car do (0.75)."""
CONSISTENT = 0.25
"""The least mean square of the last trials' measured deviations from the goal, in units of the
estimated scatter's square, for the estimate to be the plant's (:func:`consistent`): a learner at a
plant's floor cannot keep landing nearer than its scatter (a mean square below a quarter of it
over three trials of a pose, nine numbers, has a probability of about 1 %), while an estimate
polluted by the learner's own moves (a model error that changes as the learner travels) is often
far above what the last trials measure."""
MIN_TRIALS = 4
"""Trials that must qualify for an estimate (three degrees of freedom per coordinate)."""
MIN_SCATTER = 1e-7
"""[m or rad] a scatter below this is the integrator's and the model's round-off, not the
plant's: :func:`repeatability` reads it as none (a simulated plant that repeats itself exactly)."""


def estimate(residuals: Array, errors: Array, groups: Sequence[Sequence[int]]) -> tuple[Array, int] | None:
    """The scatter ``sigma`` of each group of coordinates ([m or rad], the columns of ``residuals``
    pooled per group) and its degrees of freedom per coordinate, from the residuals ``(m, nq)`` of
    trials ``k`` (measured outcome minus the model's) and their measured error norms ``(m,)``
    (NaN or inf for a trial that left the chart); ``None`` when fewer than :data:`MIN_TRIALS`
    trials qualify."""
    residuals = np.asarray(residuals, dtype=np.float64)
    errors = np.asarray(errors, dtype=np.float64)
    if residuals.ndim != 2 or residuals.shape[0] != errors.shape[0] or errors.ndim != 1:
        raise BadInput(f"estimate: residuals (m, nq) and errors (m,) of one m, got {residuals.shape}, {errors.shape}")
    finite = np.isfinite(errors) & np.all(np.isfinite(residuals), axis=1)
    candidates = np.flatnonzero(finite)[-WINDOW:]
    if candidates.size < MIN_TRIALS:
        return None
    used = candidates[errors[candidates] <= SPREAD * float(np.median(errors[candidates]))]
    if used.size < MIN_TRIALS:
        return None
    trend = np.polyfit(np.arange(used.size), np.log(np.maximum(errors[used], 1e-300)), 1)[0]
    if trend < np.log(CONVERGING):  # the errors still fall: the residuals' changes are the learner's
        return None
    r = residuals[used] - residuals[used].mean(axis=0)
    dof = used.size - 1
    sigma = np.array([np.sqrt(np.sum(r[:, list(g)] ** 2) / (dof * len(g))) for g in groups])
    return sigma, dof


def repeats(actions: Array, outcomes: Array) -> bool:
    """Whether the plant has shown that it repeats itself: two trials of one action ``(m, p)`` whose
    final states ``(m, nq)`` (finite) agree within :data:`MIN_SCATTER` in every coordinate. Such a
    plant has no scatter, whatever a model's residuals say: a model outside the plant's family
    leaves residuals that change with the action, and an estimate from them would call its error
    the plant's floor. One pass over the trials, grouped by action."""
    actions, outcomes = np.asarray(actions, dtype=np.float64), np.asarray(outcomes, dtype=np.float64)
    seen: dict[bytes, Array] = {}
    for action, outcome in zip(actions, outcomes):
        if not np.all(np.isfinite(outcome)):
            continue
        key = action.tobytes()
        if key in seen and np.max(np.abs(outcome - seen[key])) < MIN_SCATTER:
            return True
        seen.setdefault(key, outcome)
    return False


def repeatability(sigma: float | None) -> float | None:
    """The plant's repeatability (:data:`FLOOR` times ``sigma``), or ``None`` when the scatter is
    unknown or below :data:`MIN_SCATTER` (the plant repeats itself)."""
    if sigma is None or not np.isfinite(sigma) or sigma < MIN_SCATTER:
        return None
    return FLOOR * float(sigma)


def consistent(deviations: Array, sigma: Array, groups: Sequence[Sequence[int]]) -> bool:
    """Whether the measured deviations from the goal ``(h, nq)`` of the last trials are of the size
    of the scatter ``sigma`` (one per group): their mean square over the groups' coordinates, in
    units of ``sigma**2``, at least :data:`CONSISTENT`."""
    deviations = np.asarray(deviations, dtype=np.float64)
    scaled = [deviations[:, list(g)] / max(float(s), MIN_SCATTER) for s, g in zip(sigma, groups)]
    return float(np.mean(np.concatenate([x.ravel() for x in scaled]) ** 2)) >= CONSISTENT
