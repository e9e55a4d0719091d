"""Pull-style optimizers as :class:`~ilc_steering.agents.base.Learner` s.

A black-box optimizer (scipy, ``cma``) or an RL algorithm (Stable-Baselines3) *pulls*: it calls
``env.step`` when it wants a trial. The trial loop *pushes*: it asks ``act`` for an action and
hands the result to ``learn``. :class:`PullLearner` joins the two: the optimizer runs in a worker
thread against :class:`TrialPort`, a one-trial Gymnasium env whose ``step`` hands the action to
``act`` and waits for ``learn``'s ``info``. ``learn`` then waits for the optimizer's next action
(or its end), so exactly one thread runs at a time, among all the learners of a sweep's row too: a
run is as deterministic as the optimizer, and an optimizer that uses a process-wide state (``cma``
draws from numpy's global RNG) never runs beside another. When the loop ends, ``close()`` stops the
optimizer inside its pending ``step``.

The port serves one-trial tasks: its observation is the last one ``act`` was given (constant
for ``ChainedSteering-v0``), its reward minus :func:`~ilc_steering.core.score.trial_cost`.
"""

from __future__ import annotations

import queue
import threading
from collections.abc import Callable, Mapping
from typing import Any

import gymnasium as gym
import numpy as np
import numpy.typing as npt

from ilc_steering.core.score import trial_cost

__all__ = ["PullLearner", "TrialPort"]

Array = npt.NDArray[np.float64]


class _Stop(BaseException):
    """Raised inside the optimizer's pending ``step`` by ``close()``; a ``BaseException`` so that
    no ``except Exception`` of the optimizer swallows it."""


class _Finished:
    """The optimizer returned (or raised ``error``) on its own."""

    def __init__(self, error: BaseException | None = None) -> None:
        self.error = error


class TrialPort(gym.Env[Any, Any]):
    """The env a pull-style optimizer sees: each ``step`` is one trial run by the trial loop."""

    def __init__(self, action_space: gym.spaces.Box, observation_space: gym.spaces.Space[Any]) -> None:
        self.action_space = action_space
        self.observation_space = observation_space
        self.observation: Any = None
        self.actions: queue.Queue[Array | _Finished] = queue.Queue(maxsize=1)
        self.infos: queue.Queue[Mapping[str, Any] | None] = queue.Queue(maxsize=1)

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[Any, dict[str, Any]]:
        super().reset(seed=seed)
        return self.observation, {}

    def step(self, action: Any) -> tuple[Any, float, bool, bool, dict[str, Any]]:
        self.actions.put(np.array(action, dtype=np.float64))
        info = self.infos.get()
        if info is None:
            raise _Stop
        return self.observation, -float(trial_cost(info)), True, False, dict(info)


class PullLearner:
    """A :class:`~ilc_steering.agents.base.Learner` around ``run(env)``, an optimizer that drives a
    Gymnasium env itself; ``run`` gets a :class:`TrialPort` with the given spaces."""

    def __init__(
        self,
        run: Callable[[gym.Env[Any, Any]], Any],
        action_space: gym.spaces.Box,
        observation_space: gym.spaces.Space[Any],
    ) -> None:
        self._run = run
        self._spaces = (action_space, observation_space)
        self._port = TrialPort(*self._spaces)
        self._thread: threading.Thread | None = None
        self._next: Array | _Finished | None = None

    def _main(self) -> None:
        try:
            self._run(self._port)
        except _Stop:
            return
        except BaseException as error:  # handed to the loop's thread by act()
            self._port.actions.put(_Finished(error))
        else:
            self._port.actions.put(_Finished())

    def act(self, observation: Any) -> Array:
        self._port.observation = observation
        if self._thread is None:
            self._thread = threading.Thread(target=self._main, name="pull-learner", daemon=True)
            self._thread.start()
        action = self._port.actions.get() if self._next is None else self._next
        self._next = None
        if isinstance(action, _Finished):
            if action.error is not None:
                raise action.error
            raise RuntimeError("the optimizer stopped on its own before the trial budget was spent")
        return action

    def learn(self, info: Mapping[str, Any]) -> None:
        self._port.infos.put(info)
        self._next = self._port.actions.get()  # the optimizer runs to its next trial now, alone

    def reset(self) -> None:
        """Stop the optimizer; the next ``act`` starts it afresh."""
        self.close()
        self._port = TrialPort(*self._spaces)
        self._next = None

    def close(self) -> None:
        """Stop the optimizer inside its pending trial and wait for its thread."""
        if self._thread is not None and self._thread.is_alive():
            self._port.infos.put(None)
            self._thread.join()
        self._thread = None
