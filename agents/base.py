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

import json
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import numpy as np
import numpy.typing as npt
from gymnasium import spaces

from ilc_steering.boxes import residual_box
from ilc_steering.core.nominal import NominalModel
from ilc_steering.entries import load_entry
from ilc_steering.errors import BadInput

__all__ = [
    "PRIORS",
    "START_SPREAD",
    "BaseLearner",
    "Closable",
    "Learner",
    "LearnerContext",
    "LearnerFactory",
    "TimedUpdates",
    "Transferable",
    "close_learner",
    "load_factory",
    "transferred",
    "update_times",
]

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


@runtime_checkable
class Closable(Protocol):
    """A learner's optional part: ``close()``, called once when the trial loop ends, however it
    ends (the adapters of pull-style optimizers stop their optimizer's thread there)."""

    def close(self) -> None: ...


@runtime_checkable
class TimedUpdates(Protocol):
    """A learner's optional part: ``update_seconds``, the wall time [s] of each of its updates
    (the model-based learners keep it; ``compare`` reports the median)."""

    update_seconds: list[float]


@runtime_checkable
class Transferable(Protocol):
    """A learner's optional part: ``transfer()``, what it learned of the robot (not of the goal: a
    car's identified geometry, its servo's offset) for the next goal's learner of the same id, which
    gets it as :attr:`LearnerContext.carried`. Called once, after the last trial and before
    ``close()``; plain data (it is written into a run's JSON), or ``None`` when there is nothing to
    carry yet."""

    def transfer(self) -> Mapping[str, Any] | None: ...


class BaseLearner:
    """A base class that declares a learner's optional parts with their defaults (SB3's
    ``BaseAlgorithm`` in small): subclass it and override :meth:`close`, or append to
    :attr:`update_seconds`. A learner need not subclass it: the protocols :class:`Learner`,
    :class:`Closable` and :class:`TimedUpdates` are what the loop and the engine ask for."""

    update_seconds: list[float]

    def __init__(self) -> None:
        self.update_seconds = []

    def act(self, observation: Any) -> npt.NDArray[np.float64]:
        raise NotImplementedError

    def learn(self, info: Mapping[str, Any]) -> None:
        raise NotImplementedError

    def reset(self) -> None:
        raise NotImplementedError

    def close(self) -> None:
        """Release what the learner holds (nothing by default)."""


def close_learner(learner: Learner) -> None:
    """Call the learner's ``close()`` if it declares one (:class:`Closable`)."""
    if isinstance(learner, Closable):
        learner.close()


def transferred(learner: Learner) -> dict[str, Any] | None:
    """What ``learner`` hands to the next goal (:class:`Transferable`), a copy as plain JSON data;
    ``None`` if it carries nothing. ``TypeError`` if it hands something else."""
    if not isinstance(learner, Transferable):
        return None
    carried = learner.transfer()
    if carried is None:
        return None
    if not isinstance(carried, Mapping):
        raise TypeError(f"transfer() must return a mapping or None, got {type(carried).__name__}")
    try:
        data: dict[str, Any] = json.loads(json.dumps(dict(carried), allow_nan=False))
    except (TypeError, ValueError) as error:
        raise TypeError(f"transfer() must return plain JSON data (finite numbers, strings, lists): {error}") from None
    return data


def update_times(learner: Learner) -> list[float]:
    """The learner's update times [s] (:class:`TimedUpdates`), empty if it keeps none."""
    if isinstance(learner, TimedUpdates) and isinstance(learner.update_seconds, list):
        return learner.update_seconds
    return []


PRIORS = ("nominal", "none")
"""The conditions of a comparison: what every learner may start from (see :class:`LearnerContext`)."""

START_SPREAD = 0.02
"""A seeded start point lies within this fraction of the search box's half-widths of its centre."""


@dataclass(frozen=True, eq=False)
class LearnerContext:
    """Everything a learner may be built from: the same for every learner in a comparison.

    ``prior`` is the condition of the comparison:

    - ``"nominal"`` (the default): every learner's first trial is the nominal open-loop solution
      ``model.solve()``, and black-box and RL methods search the *residual* box
      ``c = c0 + s * a``, ``a`` in ``[-1, 1]``, with ``c0 = model.solve()`` and
      ``s = RESIDUAL_SCALE * model.action_scale()``;
    - ``"none"``: no prior; learners start from a seeded point near ``c = 0`` and search the env's
      whole action box (10 times the nominal scale).
    """

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
    prior: str = "nominal"
    """``"nominal"`` or ``"none"``: what the first trial and the search box are built from."""
    cost: str = "none"
    """The config's ``learning.cost`` (section 7), for learners that use it."""
    task: str = ""
    """The config's name, for learners with per-task settings (RL's hyperparameter files)."""
    progress_bar: bool = False
    """Show a training's progress bar, for learners that have one (RL, in one process)."""
    carried: Mapping[str, Any] | None = None
    """What the last goal's learner of the same id learned of the same robot (its
    :meth:`Transferable.transfer`), for ``run`` on a list of goals with ``--carry``; ``None`` for a
    first goal, and always in ``compare`` and ``sweep``, whose every cell starts afresh. A learner
    that reads it checks it, and may ignore it."""
    tensorboard_log: str | None = None
    """A folder for the learner's own TensorBoard logs, for learners that keep some (RL: SB3's
    ``tensorboard_log``), or ``None``: the run's ``--tensorboard`` folder, beside the trial loop's
    event files. What a learner logs there changes nothing it does."""

    @classmethod
    def from_env(
        cls,
        env: Any,
        *,
        seed: int = 0,
        prior: str = "nominal",
        nu_b: float | None = None,
        progress_bar: bool = False,
        carried: Mapping[str, Any] | None = None,
        tensorboard_log: str | None = None,
    ) -> LearnerContext:
        """The context of a learner on ``env`` (a one-trial env, or a vector env whose every env
        gets the same), with its config's gains, ``learning.cost`` and name: the one place a
        context is built from a config, so no command drops a key of it. ``nu_b`` overrides the
        config's gain of eq. 34 (a sweep's map)."""
        from gymnasium.vector import VectorEnv

        owner: Any = env if isinstance(env, VectorEnv) else env.unwrapped
        if isinstance(env, VectorEnv):
            action_space, observation_space = owner.single_action_space, owner.single_observation_space
        else:
            action_space, observation_space = owner.action_space, owner.observation_space
        learning = owner.config.learning
        return cls(
            owner.nominal_model,
            action_space,
            observation_space,
            seed,
            learning.nu_a,
            learning.nu_b if nu_b is None else nu_b,
            prior=prior,
            cost=learning.cost,
            task=owner.config.name,
            progress_bar=progress_bar,
            carried=carried,
            tensorboard_log=tensorboard_log,
        )

    def __post_init__(self) -> None:
        if self.prior not in PRIORS:
            raise BadInput(f"prior must be one of {list(PRIORS)}, got {self.prior!r}")

    def search_box(self) -> tuple[Array, Array]:
        """Centre and half-widths [physical units] of the box a black-box or RL method searches
        (the env clips what lies outside its own action box)."""
        low = np.asarray(self.action_space.low, dtype=np.float64)
        high = np.asarray(self.action_space.high, dtype=np.float64)
        if self.prior == "none":
            return 0.5 * (high + low), 0.5 * (high - low)
        return residual_box(self.model, self.action_space)

    def start_point(self, restart: int = 0) -> Array:
        """A start in the search box's ``[-1, 1]`` units: the centre for the first start under the
        nominal prior, else a seeded point within :data:`START_SPREAD` of it (``restart`` > 0: a
        learner's later starts, each seeded apart)."""
        size = self.model.profile.num_coefficients
        if restart == 0 and self.prior == "nominal":
            return np.zeros(size)
        rng = np.random.default_rng([self.seed, restart])
        return START_SPREAD * rng.uniform(-1.0, 1.0, size)

    def first_action(self) -> Array:
        """The first trial's coefficients [physical units]: ``model.solve()`` under the nominal
        prior, a seeded point near ``c = 0`` without one."""
        centre, half = self.search_box()
        return centre + half * self.start_point(0)


LearnerFactory = Callable[[LearnerContext], Learner]
"""Builds a learner: ``make(context) -> Learner``; ``compare --methods pkg.module:make`` takes one."""


def load_factory(spec: str, option: str = "--methods") -> LearnerFactory:
    """The learner factory named ``module:attr`` (``option`` names where it was given, for the
    message), loaded by :func:`~ilc_steering.entries.load_entry` (the working directory searched
    last); ``ValueError`` if it cannot be, or is not callable."""
    target = load_entry(spec, option)
    if not callable(target):
        raise BadInput(f"{option} {spec}: not callable; give a factory make(context) -> Learner")
    return target  # type: ignore[no-any-return]
