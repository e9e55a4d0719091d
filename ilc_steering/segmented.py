"""One learner per segment of a manoeuvre (:mod:`~ilc_steering.envs.segmented_env`), driven as one.

Each segment's learner is made by the usual factory from its segment's view, exactly the context it
would get on the one-trial env of that segment, so every learner of the registry runs unchanged.
Its task is named ``NAME.k`` (segment ``k`` of config ``NAME``): an RL learner's hyperparameters
(``configs/rl``) are looked up under that name and, as for any config the table does not name,
fall back to the prior's ``default``.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np
import numpy.typing as npt

from ilc_steering.agents.base import Closable, Learner, LearnerContext, transferred
from ilc_steering.core.nominal import NominalModel
from ilc_steering.envs.segmented_env import SegmentView
from ilc_steering.errors import BadInput

__all__ = ["SegmentedLearner", "rebased", "segmented_learner"]

Array = npt.NDArray[np.float64]


class SegmentedLearner:
    """One learner per segment: ``act`` concatenates their actions, ``learn`` hands each its own
    segment's ``info`` (``info["segments"][k]``, without the true errors) if that segment ran,
    ``reset`` resets each, ``transfer`` hands on the last segment's learning (learning carried
    from goal to goal, ``ilc-steering run A B --carry``)."""

    def __init__(self, learners: Sequence[Learner], views: Sequence[SegmentView]) -> None:
        if len(learners) != len(views) or not learners:
            raise BadInput(f"one learner per segment is needed ({len(views)}), got {len(learners)}")
        self.learners = list(learners)
        self.views = list(views)

    def act(self, observation: Any) -> Array:
        """Each segment's learner's action on its own (constant) one-trial observation, concatenated."""
        actions = [learner.act(view.observation.copy()) for learner, view in zip(self.learners, self.views)]
        return np.concatenate([np.asarray(a, dtype=np.float64) for a in actions])

    def learn(self, info: Mapping[str, Any]) -> None:
        """Each segment's learner learns from its own segment's ``info``, its error re-based to the
        segment's nominal start (:func:`rebased`). A segment that was not run (``ran`` false: an
        earlier one halted) produced nothing of its action: its learner skips the trial, keeps its
        state and repeats its action."""
        for learner, view, segment in zip(self.learners, self.views, info["segments"]):
            if segment["ran"]:
                learner.learn(rebased(segment, view.nominal_model))

    def transfer(self) -> dict[str, Any] | None:
        """What the manoeuvre's learners carry to the next goal (:class:`~ilc_steering.agents.base.Transferable`):
        that of the last segment whose learner carries anything. Every segment drove the same robot,
        so each learner's identification is of the same parameters; the last segment's ran the
        trials that ended at the goal, and it ran whenever an earlier one did not halt."""
        for learner in reversed(self.learners):
            carried = transferred(learner)
            if carried is not None:
                return carried
        return None

    def reset(self) -> None:
        for learner in self.learners:
            learner.reset()

    def close(self) -> None:
        """Close every learner that declares ``close()`` (:class:`~ilc_steering.agents.base.Closable`),
        each even when an earlier one raised; then raise the first error."""
        errors = []
        for learner in self.learners:
            if isinstance(learner, Closable):
                try:
                    learner.close()
                except Exception as error:
                    errors.append(error)
        if errors:
            raise errors[0]


def rebased(segment: Mapping[str, Any], model: NominalModel) -> dict[str, Any]:
    r"""A segment's ``info`` with the error it would have had from its nominal start.

    The segment began at ``z_start`` (``segment["z_start"]``, measured: where the last segment really
    ended), not at the via point ``z_v`` its learner was built for. By eq. 23 (with eq. 12) the
    nominal ``z(T)`` is ``F(z0, c) = (z0_1 + Delta z_1(c11), V(c11) z0_b + W(c11) c_2)``, so the
    start's share of the error is ``F(z_start, c) - F(z_v, c) = (Delta z0_1, V(c11) Delta z0_b)``,
    and the learner is handed ``e + F(z_start, c) - F(z_v, c)``: the error "as if it had begun at the
    via point", exact on the nominal chained form, first order otherwise. It is the cyclic law's
    feedforward of the measured start (eq. 39, :mod:`~ilc_steering.agents.cyclic_ilc`), moved from
    the action to the error, so that every one-trial learner runs unchanged. Only the nominal model is
    used, never the plant.
    """
    out = dict(segment)
    c = np.asarray(segment["action"], dtype=np.float64)
    shift = model.final_state(c, np.asarray(segment["z_start"], dtype=np.float64)) - model.final_state(c)
    out["error"] = np.asarray(segment["error"], dtype=np.float64) + shift
    out["error_norm"] = float(np.linalg.norm(out["error"]))
    return out


def segmented_learner(
    make: Callable[[LearnerContext], Learner], views: Sequence[SegmentView], seed: int = 0
) -> SegmentedLearner:
    """A :class:`SegmentedLearner` of ``make``'s learners, one per segment view, each seeded apart."""
    learners = [make(LearnerContext.from_env(view, seed=seed + k)) for k, view in enumerate(views)]
    return SegmentedLearner(learners, views)
