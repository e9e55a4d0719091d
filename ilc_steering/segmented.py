"""One learner per segment of a manoeuvre (:mod:`~ilc_steering.envs.segmented_env`), driven as one.

Each segment's learner is made by the usual factory from its segment's view, exactly the context it
would get on the one-trial env of that segment, so every learner of the registry runs unchanged.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np
import numpy.typing as npt

from ilc_steering.agents.base import Closable, Learner, LearnerContext
from ilc_steering.envs.segmented_env import SegmentView

__all__ = ["SegmentedLearner", "segmented_learner"]

Array = npt.NDArray[np.float64]


class SegmentedLearner:
    """One learner per segment: ``act`` concatenates their actions, ``learn`` hands each its own
    segment's ``info`` (``info["segments"][k]``, without the true errors), ``reset`` resets each."""

    def __init__(self, learners: Sequence[Learner], views: Sequence[SegmentView]) -> None:
        if len(learners) != len(views) or not learners:
            raise ValueError(f"one learner per segment is needed ({len(views)}), got {len(learners)}")
        self.learners = list(learners)
        self.views = list(views)

    def act(self, observation: Any) -> Array:
        """Each segment's learner's action on its own (constant) one-trial observation, concatenated."""
        actions = [learner.act(view.observation.copy()) for learner, view in zip(self.learners, self.views)]
        return np.concatenate([np.asarray(a, dtype=np.float64) for a in actions])

    def learn(self, info: Mapping[str, Any]) -> None:
        """Each segment's learner learns from its own segment's ``info``."""
        for learner, segment in zip(self.learners, info["segments"]):
            learner.learn(segment)

    def reset(self) -> None:
        for learner in self.learners:
            learner.reset()

    def close(self) -> None:
        """Close every learner that declares ``close()`` (:class:`~ilc_steering.agents.base.Closable`)."""
        for learner in self.learners:
            if isinstance(learner, Closable):
                learner.close()


def segmented_learner(
    make: Callable[[LearnerContext], Learner], views: Sequence[SegmentView], seed: int = 0
) -> SegmentedLearner:
    """A :class:`SegmentedLearner` of ``make``'s learners, one per segment view, each seeded apart."""
    learners = [make(LearnerContext.from_env(view, seed=seed + k)) for k, view in enumerate(views)]
    return SegmentedLearner(learners, views)
