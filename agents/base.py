"""The :class:`Learner` protocol, and what a learner is built from.

A learner proposes the coefficients of the next trial and learns from the trial's ``info``::

    observation, _ = env.reset(seed=0)
    action = learner.act(observation)
    observation, reward, terminated, truncated, info = env.step(action)
    learner.learn(info)

:func:`ilc_steering.loop.run_trials` is that loop, the only one in the library. Every learner
the comparison runs, users' own included, is made by a :data:`LearnerFactory` from a
:class:`LearnerContext`, which holds the *nominal* model and nothing of the true plant.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import numpy as np
import numpy.typing as npt
from gymnasium import spaces

from ilc_steering.core.nominal import NominalModel

__all__ = ["Learner", "LearnerContext", "LearnerFactory"]

Array = npt.NDArray[np.float64]


@runtime_checkable
class Learner(Protocol):
    """What drives an env trial after trial (``tests/test_protocols.py`` checks every learner).

    - ``act(observation)``: the action ``c`` of the next trial, in the env's physical units;
    - ``learn(info)``: update from the finished trial's ``info`` (``error``, ``action``, the errors);
    - ``reset()``: forget what was learned; the next ``act`` is the first trial's again.
    """

    def act(self, observation: Any) -> Array: ...

    def learn(self, info: Mapping[str, Any]) -> None: ...

    def reset(self) -> None: ...


@dataclass(frozen=True, eq=False)
class LearnerContext:
    """Everything a learner may be built from: the same for every learner in a comparison."""

    model: NominalModel
    """The nominal model (for a cyclic task, the first segment's; see ``models``)."""
    action_space: spaces.Box
    """The env's action box [physical units]."""
    observation_space: spaces.Box
    """The env's observation space."""
    seed: int = 0
    """Seed of the learner's own randomness."""
    nu_a: float = 1.0
    """The config's gain of eq. 33, for learners that use it."""
    nu_b: float = 1.0
    """The config's gain of eq. 34."""
    models: tuple[NominalModel, ...] = ()
    """A cyclic task's nominal models, one per segment (empty for a one-trial task)."""


LearnerFactory = Callable[[LearnerContext], Learner]
"""Builds a learner: ``make(context) -> Learner``; ``compare --methods pkg.module:make`` takes one."""
