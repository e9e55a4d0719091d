"""The docs' own learner ("Your own learner", ``docs/learners.md``): Broyden's secant steps.

Anything with ``act(observation) -> c``, ``learn(info)`` and ``reset()`` is a ``Learner``; ``make``
builds one from a ``LearnerContext``. From the folder that holds this file::

    ilc-steering compare --methods ilc least_squares my_learners:make --scenarios parallel_parking forward_parking

The step is the least-squares solution of the secant model ``J dc = error``, kept inside the env's
action box (the env would clip it, and a clipped action repeated measures no slope), and a trial
that did not move the action (``dc = 0``) leaves ``J`` as it was: Broyden's update divides by
``|dc|^2``, and a zero there turned ``J`` into NaN, which ``lstsq`` met as ``LinAlgError``.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ilc_steering.agents.newton import nominal_jacobian


class Broyden:
    """Secant steps: the nominal Jacobian at the start, corrected after each trial by what the
    trial measured (Broyden's rank-one update), so the model error is learned along the way."""

    def __init__(self, context: Any) -> None:
        self.context = context
        self.low = np.asarray(context.action_space.low, dtype=np.float64)
        self.high = np.asarray(context.action_space.high, dtype=np.float64)
        self.reset()

    def reset(self) -> None:
        self.c = self.context.first_action()  # the nominal solution, under prior=nominal
        self.J = nominal_jacobian(self.context.model, self.c)
        self.last: tuple[np.ndarray, np.ndarray] | None = None

    def act(self, observation: Any) -> np.ndarray:
        return self.c.copy()

    def learn(self, info: dict[str, Any]) -> None:
        c, error = np.asarray(info["action"], dtype=np.float64), np.asarray(info["error"], dtype=np.float64)
        if self.last is not None:
            dc, dz = c - self.last[0], self.last[1] - error  # how far the final state moved
            if dc @ dc > 1e-24 * (1.0 + c @ c):  # an action not moved measures no slope
                update = np.outer(dz - self.J @ dc, dc) / (dc @ dc)
                if np.all(np.isfinite(update)):
                    self.J += update
        self.last = (c, error)
        step = np.linalg.lstsq(self.J, error, rcond=None)[0]
        self.c = np.clip(c + step, self.low, self.high)


def make(context: Any) -> Broyden:
    return Broyden(context)
