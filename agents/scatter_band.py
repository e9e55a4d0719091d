"""The scatter band: the plant's scatter from repeated trials, and the averaging of the trials in its band.

A robot that does not repeat itself scatters the final pose of one action; a learner that chased
each draw would pass it on whole into the next trial. :func:`trial_scatter` estimates the scatter
from the residuals of the trials against a refit model (:mod:`ilc_steering.core.scatter`), unless
the plant has shown that it repeats itself (:func:`shown_to_repeat`); a :class:`ScatterBand` holds
the trials since one landed within :data:`BAND` times it (:func:`within_scatter`), and their mean
offset from the model (:meth:`ScatterBand.offset`) is what the learner then corrects, so that the
N-th trial in the band moves by 1/N of a new draw. ``newton_ilc`` (its step 5) and ``robust_ilc``
(its step 4, ``docs/learners.md``) both average so.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from ilc_steering.agents.trial import Trial
from ilc_steering.core.family import ModelFamily
from ilc_steering.core.nominal import NominalModel
from ilc_steering.core.scatter import FLOOR, MIN_SCATTER, MIN_TRIALS, estimate, repeats

__all__ = ["BAND", "ScatterBand", "scatter_groups", "shown_to_repeat", "trial_scatter", "within_scatter"]

Array = npt.NDArray[np.float64]
Mask = npt.NDArray[np.bool_]


def scatter_groups(model: NominalModel) -> tuple[tuple[int, ...], ...]:
    """The coordinates of a configuration whose scatter is pooled (:func:`ilc_steering.core.scatter.estimate`):
    a pose's x and y [m], then its heading [rad]; without a pose, every chained coordinate."""
    if getattr(model.chained_map, "has_pose", False):
        return ((0, 1), (2,))
    return (tuple(range(model.dimension)),)


def trial_scatter(
    family: ModelFamily, theta: Array, trials: list[Trial], groups: tuple[tuple[int, ...], ...]
) -> Array | None:
    """The plant's scatter per group [m or rad] from the residuals of ``trials`` against the family's
    model ``theta`` (one batched simulation, no trial), or None: too few trials qualify, the errors
    still fall, or the plant repeats itself (two trials of one action measured alike,
    :func:`~ilc_steering.core.scatter.repeats`, or a scatter below
    :data:`~ilc_steering.core.scatter.MIN_SCATTER`)."""
    ok = [t for t in trials if t.ok]
    if not ok or shown_to_repeat(ok):
        return None
    q, inside = family.configurations(theta, np.array([t.c for t in ok]))
    residuals = np.where(inside[:, None], np.array([t.q for t in ok]) - q, np.nan)
    found = estimate(residuals, np.array([t.error for t in ok]), groups)
    if found is None or float(np.min(found[0])) < MIN_SCATTER:
        return None
    return found[0]


def shown_to_repeat(trials: list[Trial]) -> bool:
    """Whether two of ``trials`` ran one action and were measured alike: the plant repeats itself,
    and what a model leaves of its trials is the model's error, not a scatter to average."""
    return len(trials) > 1 and repeats(np.array([t.c for t in trials]), np.array([t.q for t in trials]))


def within_scatter(q: Array, goal_q: Array, sigma: Array, groups: tuple[tuple[int, ...], ...], factor: float) -> bool:
    """Whether the configuration ``q`` is within ``factor`` times the scatter of ``goal_q`` in every
    group (the norm of the group's error against ``factor * sigma * sqrt(len(group))``)."""
    return all(
        float(np.linalg.norm((q - goal_q)[list(g)])) <= factor * float(s) * np.sqrt(len(g))
        for s, g in zip(sigma, groups)
    )


BAND = FLOOR
"""A learner that knows the scatter averages once a trial lands within this many times it (per
coordinate): there, what it measures is mostly the scatter, which no step can take back."""


class ScatterBand:
    """The plant's scatter as last estimated and the trials of its band.

    Parameters
    ----------
    model
        The nominal model (its coordinate groups, :func:`scatter_groups`).
    goal_q
        The goal's configuration [m, rad].
    """

    def __init__(self, model: NominalModel, goal_q: Array) -> None:
        self.groups = scatter_groups(model)
        self.goal_q = goal_q
        self.reset()

    def reset(self) -> None:
        """No estimate, no band."""
        self.scatter: Array | None = None
        """The plant's scatter per coordinate group as last estimated (``[m, rad]`` for a pose), or None."""
        self.trials: list[Trial] = []
        """The band's trials, oldest first (empty: out of the band)."""

    def update(self, family: ModelFamily, theta: Array, trials: list[Trial], trial: Trial) -> bool:
        """The scatter estimated from ``trials`` on the refit model ``theta`` of ``family`` (into
        :attr:`scatter`), and whether ``trial`` (the last of ``trials``) is (still) in its band: within
        :data:`BAND` times it, or within twice that once the band has begun. ``trial`` joins the band's
        :attr:`trials`, or the band is emptied.

        A band begins with the trials just before ``trial`` (at most
        :data:`~ilc_steering.core.scatter.MIN_TRIALS` of them) that were within twice :data:`BAND` too
        and that the refit model puts within the scatter of ``trial``'s outcome (about the same
        action): the scatter is estimated only from the fourth trial near the goal on, and those
        before it are draws of it as well, so that the band's first mean is not a single draw (a
        learner that stepped to correct one draw in full left a tolerance of four times the scatter on
        the MuJoCo car). Trials farther apart in action are left out: outside the model's family its
        error changes with the action, and their offsets would bias the mean (``newton_ilc`` on the
        simulated lab robot held a heading bias of 6-9 mrad). Once the band has begun, the last
        estimate stands in when the trials give none (not once two trials of one action were
        measured alike: that plant has no scatter, and the band ends): a few lucky draws in a row read as
        errors that still fall, and a band ended by them sent the learner to chase the next draw."""
        groups, goal_q, band = self.groups, self.goal_q, self.trials
        scatter = trial_scatter(family, theta, trials, groups)
        if scatter is None and band and not shown_to_repeat([t for t in trials if t.ok]):
            scatter = self.scatter
        inside = scatter is not None and (
            within_scatter(trial.q, goal_q, scatter, groups, BAND)
            or (bool(band) and within_scatter(trial.q, goal_q, scatter, groups, 2 * BAND))
        )
        if inside and not band and scatter is not None:
            earlier = [t for t in trials if t is not trial and t.ok][-MIN_TRIALS:]
            q, ok = family.configurations(theta, np.array([trial.c, *[t.c for t in earlier]]))
            for t, q_t, ok_t in reversed(list(zip(earlier, q[1:], ok[1:]))):
                # a draw of the scatter at about the same action: the model moves it by less than the scatter
                if not (ok[0] and ok_t and within_scatter(t.q, goal_q, scatter, groups, 2 * BAND)):
                    break
                if not within_scatter(q_t, q[0], scatter, groups, 1.0):
                    break
                band.insert(0, t)
        if inside:
            band.append(trial)
        else:
            band.clear()
        self.scatter = scatter
        return inside

    def actions(self) -> Array:
        """The coefficients of the band's trials ``(N, 1 + q)``."""
        return np.array([t.c for t in self.trials])

    def offset(self, predicted: Array, ok: Mask) -> Array:
        """The mean over the band's trials that the model keeps in its chart (``ok``, at least one) of
        what they measured less what the model ``predicted`` of them ``(N, n)`` [chained units]: the
        offset the learner corrects, each draw of the scatter counted 1/N."""
        mean: Array = np.mean((np.array([t.z for t in self.trials]) - predicted)[ok], axis=0)
        return mean
