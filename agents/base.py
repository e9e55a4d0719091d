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

import os
import sys
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from importlib import import_module, invalidate_caches
from pathlib import Path
from types import ModuleType
from typing import Any, Protocol, runtime_checkable

import numpy as np
import numpy.typing as npt
from gymnasium import spaces

from ilc_steering.core.nominal import NominalModel

__all__ = [
    "PRIORS",
    "RESIDUAL_SCALE",
    "START_SPREAD",
    "BaseLearner",
    "Closable",
    "Learner",
    "LearnerContext",
    "LearnerFactory",
    "TimedUpdates",
    "close_learner",
    "load_factory",
    "residual_box",
    "update_times",
    "working_directory_importable",
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


def update_times(learner: Learner) -> list[float]:
    """The learner's update times [s] (:class:`TimedUpdates`), empty if it keeps none."""
    if isinstance(learner, TimedUpdates) and isinstance(learner.update_seconds, list):
        return learner.update_seconds
    return []


PRIORS = ("nominal", "none")
"""The conditions of a comparison: what every learner may start from (see :class:`LearnerContext`)."""

RESIDUAL_SCALE = 0.3
"""Half-width of the residual search box under ``prior="nominal"``, in units of
``NominalModel.action_scale()``: the true solution of every packaged task lies within 0.21 of it
(forward parking 0.10, the saturated task 0.21, parallel parking 0.09, the chained plant 0.09)."""

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

    @classmethod
    def from_env(
        cls,
        env: Any,
        *,
        seed: int = 0,
        prior: str = "nominal",
        nu_b: float | None = None,
        progress_bar: bool = False,
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
        )

    def __post_init__(self) -> None:
        if self.prior not in PRIORS:
            raise ValueError(f"prior must be one of {list(PRIORS)}, got {self.prior!r}")

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


def residual_box(model: NominalModel, action_space: spaces.Box) -> tuple[Array, Array]:
    """Centre and half-widths [physical units] of the residual box under ``prior="nominal"``: the
    nominal solution (clipped to ``action_space``) and :data:`RESIDUAL_SCALE` times its action scale."""
    low = np.asarray(action_space.low, dtype=np.float64)
    high = np.asarray(action_space.high, dtype=np.float64)
    return np.clip(model.solve(), low, high), RESIDUAL_SCALE * model.action_scale()


def working_directory_importable() -> None:
    """Put the working directory on ``sys.path`` (last, so it shadows nothing installed): a user's
    learner module sits there (``my_learners.py``), where ``python -m ilc_steering`` finds it and
    the ``ilc-steering`` script would not. Spawned workers inherit the path."""
    cwd = os.getcwd()
    if cwd not in sys.path and "" not in sys.path:
        sys.path.append(cwd)


def load_factory(spec: str, option: str = "--methods") -> LearnerFactory:
    """The learner factory named ``module:attr`` (``option`` names where it was given, for the
    message): ``module`` an import name (``my_learners``, ``mypkg.mod``), ``attr`` a name in it,
    dotted for a nested one (``module:Class.make``, as in an entry point). ``ValueError``, naming
    what to give instead, if it is not of that form, cannot be imported (the module importing
    raised included: the user's code, not ilc-steering, failed), has no such attribute (a module
    of the same name found before the working directory's is named) or is not callable."""
    module_name, colon, attr = spec.partition(":")
    if module_name.endswith(".py") or "/" in module_name or "\\" in module_name:
        stem = module_name.replace("\\", "/").rsplit("/", 1)[-1].removesuffix(".py")
        raise ValueError(
            f"{option} {spec}: give the module's import name, not its file: {stem}:{attr or 'make'} "
            f"for {stem}.py in the working directory (or a package's dotted name)"
        )
    dotted = (module_name, attr)
    if not colon or not all(part.isidentifier() for name in dotted for part in name.split(".")):
        raise ValueError(
            f"{option} {spec}: give module:attr, a module's import name and a factory in it, e.g. my_learners:make"
        )
    invalidate_caches()  # a module written since this process started is found
    try:
        target: Any = import_module(module_name)
    except ModuleNotFoundError as error:
        if error.name is not None and (module_name + ".").startswith(error.name + "."):
            raise ValueError(
                f"{option} {spec}: cannot import it: no module {error.name!r} in the working directory "
                f"({os.getcwd()}) or on the path"
            ) from None
        raise ValueError(
            f"{option} {spec}: cannot import it: importing it raised ModuleNotFoundError: {error}"
        ) from None
    except Exception as error:
        raise ValueError(
            f"{option} {spec}: cannot import it: importing it raised {type(error).__name__}: {error}"
        ) from None
    module = target
    for part in attr.split("."):
        if not hasattr(target, part):
            raise ValueError(f"{option} {spec}: cannot import it: {_missing(module, attr)}")
        target = getattr(target, part)
    if not callable(target):
        raise ValueError(f"{option} {spec}: not callable; give a factory make(context) -> Learner")
    return target  # type: ignore[no-any-return]


def _missing(module: ModuleType, attr: str) -> str:
    """That ``module`` (and its file) has no ``attr``, and, when an installed module of the same
    top-level name came before the working directory's file of that name (the working directory is
    searched last, so that it shadows nothing installed), so."""
    text = f"module {module.__name__} ({getattr(module, '__file__', None) or 'built in'}) has no attribute {attr!r}"
    top = module.__name__.split(".")[0]
    found = getattr(sys.modules.get(top), "__file__", None)
    for mine in (Path(top + ".py"), Path(top, "__init__.py")):
        if mine.is_file() and (found is None or Path(found).resolve() != mine.resolve()):
            return f"{text}; it is an installed module, found before your {mine} of the working directory: rename yours"
    return text
