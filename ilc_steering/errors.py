"""The library's errors, on the lowest floor: every layer raises and catches these, none imports
another layer for them.

- :class:`ParameterError`: a parameter out of its range (the core's range rules).
- :class:`ConfigError`: a config or a record on disk that cannot be used, naming the file and key.
- :class:`LearnerError`: a learner failed (it raised, exited, or acted with an action the env refused).
- :class:`PlantError`: the user's plant failed (a program on the other end of a pipe hung, died or
  answered junk: ``plant.model: process``).
- :class:`LimitError`: a trial's commands beyond the robot's limits, refused before they were sent.

The CLI maps ``ParameterError``, ``ConfigError`` and ``LimitError`` to exit 2 (bad input) and
``LearnerError`` and ``PlantError`` to exit 4 (the user's code failed; ``docs/usage.md``).
"""

from __future__ import annotations

from typing import Any

__all__ = ["ConfigError", "LearnerError", "LimitError", "ParameterError", "PlantError"]


class ParameterError(ValueError):
    """A parameter out of its range: ``name`` is the parameter, ``problem`` what is wrong with it."""

    def __init__(self, name: str, problem: str) -> None:
        super().__init__(f"{name}: {problem}")
        self.name = name
        self.problem = problem


class ConfigError(ValueError):
    """A config that cannot be used, with the file and key at fault in its message."""


class LearnerError(Exception):
    """A learner failed: it raised, or acted with an action the env refused. The message names
    the learner and the trial; ``partial``, where the caller sets it, holds what was run before.

    One string argument, so it crosses process boundaries (pickling) intact."""

    partial: Any = None

    def __init__(self, message: str) -> None:
        super().__init__(message)


class PlantError(Exception):
    """The user's plant failed: the program behind ``plant.model: process`` hung past its timeout,
    died, or answered something that is not a result of the trial asked for. The message names the
    program (its command) and the trial; the trial is not counted. ``partial``, where the caller
    sets it, holds the trials run before.

    One string argument, so it crosses process boundaries (pickling) intact."""

    partial: Any = None

    def __init__(self, message: str) -> None:
        super().__init__(message)


class LimitError(ValueError):
    """A trial's commands beyond the robot's limits (``plant.limits``: its top speed, steering angle,
    steering rate or workspace), refused before anything was sent: bad input, never clipped.
    ``partial`` as :class:`PlantError`'s."""

    partial: Any = None
