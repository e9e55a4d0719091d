"""The library's errors, on the lowest floor: every layer raises and catches these, none imports
another layer for them.

- :class:`ParameterError`: a parameter out of its range (the core's range rules).
- :class:`ConfigError`: a config or a record on disk that cannot be used, naming the file and key.
- :class:`LearnerError`: a learner failed (it raised, exited, or acted with an action the env refused).

The CLI maps the first two to exit 2 and the last to exit 4 (``docs/usage.md``).
"""

from __future__ import annotations

from typing import Any

__all__ = ["ConfigError", "LearnerError", "ParameterError"]


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
