"""What one segment of a manoeuvre shows its learner, and what an external plant needs to drive one
(:mod:`~ilc_steering.envs.segmented_env`)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import gymnasium as gym
import numpy as np
import numpy.typing as npt

from ilc_steering.config import LearningConfig
from ilc_steering.core.nominal import NominalModel

__all__ = ["Carried", "SegmentTask", "SegmentView"]


@runtime_checkable
class Carried(Protocol):
    """An external plant's optional part for a manoeuvre: ``carry_on()``, after which its next trial
    (the next segment) goes on from where the car stands instead of resetting it."""

    def carry_on(self) -> None: ...


@dataclass(frozen=True)
class SegmentTask:
    """What a learner may read of its segment's config: its name and ``learning`` (the gains, the
    cost, the tolerance), never the plant's true parameters."""

    name: str
    learning: LearningConfig


@dataclass(frozen=True)
class SegmentView:
    """What a learner of one segment may see, shaped as a one-trial env's ``unwrapped`` (so that
    ``LearnerContext.from_env(view)`` builds its context): the segment's name and learning keys
    (``config``), nominal model, action box and observation space."""

    config: SegmentTask
    nominal_model: NominalModel
    action_space: gym.spaces.Box
    observation_space: gym.spaces.Box
    observation: npt.NDArray[np.float32]

    @property
    def unwrapped(self) -> SegmentView:
        return self
