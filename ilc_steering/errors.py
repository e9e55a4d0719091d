"""The library's errors, on the lowest floor: every layer raises and catches these, none imports
another layer for them.

- :class:`BadInput`: what the user handed the library cannot be used (an option, a file, a value
  given to the API), named where it enters; the base of the three below.
- :class:`ParameterError`: a parameter out of its range (the core's range rules).
- :class:`ConfigError`: a config or a record on disk that cannot be used, naming the file and key.
- :class:`LearnerError`: a learner failed (it raised, exited, or acted with an action the env refused).
- :class:`PlantError`: the user's plant failed (it raised, exited or returned junk; a program on the
  other end of a pipe hung, died or answered junk: ``plant.model: process``).
- :class:`LimitError`: a trial's commands beyond the robot's limits, refused before they were sent.

The CLI maps :class:`BadInput` (``ParameterError``, ``ConfigError`` and ``LimitError`` among them)
to exit 2, ``LearnerError`` and ``PlantError`` to exit 4 (the user's code failed;
``docs/usage.md``) and an interrupt to 130; anything else that escapes, a ``ValueError`` of numpy
or scipy included, is an internal error (exit 3, a bug of the library's). Each ``BadInput`` is a
``ValueError``, so code that catches those keeps working. Each of :data:`ENDS_A_RUN` may carry
``partial``, the trials run before it.

What a user's code (a learner, a plant, a robot's config class) raises is its failure, whatever it
raises (``sys.exit()`` included), except :data:`INTERRUPTS`: the boundaries into it catch
``INTERRUPTS`` first and let them pass, then ``BaseException``, and name the code with
:func:`described`.
"""

from __future__ import annotations

from typing import Any

__all__ = [
    "ENDS_A_RUN",
    "INTERRUPTS",
    "BadInput",
    "ConfigError",
    "LearnerError",
    "LimitError",
    "ParameterError",
    "PlantError",
    "described",
    "keep_partial",
]

INTERRUPTS = (KeyboardInterrupt, GeneratorExit)
"""What a user's code may raise that is not its failure: the user's interrupt (Ctrl-C) and a
generator's close. Everything else it raises, ``SystemExit`` and other ``BaseException`` included,
is its failure (exit 4, or exit 2 for a robot's config class), never the library's success or bug."""


def described(error: BaseException, limit: int = 300) -> str:
    """``"Type: message"`` of an error a user's code raised, on one line, the message cut at
    ``limit`` characters (a ``sys.exit(obj)`` carries the whole ``repr`` of ``obj``)."""
    text = " ".join(str(error).split())
    return f"{type(error).__name__}: {text if len(text) <= limit else text[:limit] + ' ...'}"


class BadInput(ValueError):
    """What the user handed the library cannot be used: an option, a file, a value given to the
    API. The message names it, where it entered (the option, the file and key, the argument), and
    says what to give instead."""


class ParameterError(BadInput):
    """A parameter out of its range: ``name`` is the parameter, ``problem`` what is wrong with it."""

    def __init__(self, name: str, problem: str) -> None:
        super().__init__(f"{name}: {problem}")
        self.name = name
        self.problem = problem


class ConfigError(BadInput):
    """A config that cannot be used, with the file and key at fault in its message."""


class LearnerError(Exception):
    """A learner failed: it raised, or acted with an action the env refused. The message names
    the learner and the trial; ``partial``, where the caller sets it, holds what was run before.

    One string argument, so it crosses process boundaries (pickling) intact."""

    partial: Any = None

    def __init__(self, message: str) -> None:
        super().__init__(message)


class PlantError(Exception):
    """The user's plant failed: a plant that runs its own trials in this process raised (or
    exited), or returned something that is not a result of the trials asked for
    (:func:`~ilc_steering.core.external.run_external`); or the program behind ``plant.model:
    process`` hung past its timeout, died, or answered junk. The message names the plant (a
    program by its command) and the trial; the trial is not counted. ``partial``, where the caller
    sets it, holds the trials run before.

    One string argument, so it crosses process boundaries (pickling) intact."""

    partial: Any = None

    def __init__(self, message: str) -> None:
        super().__init__(message)


class LimitError(BadInput):
    """A trial's commands beyond the robot's limits (``plant.limits``: its top speed, steering angle,
    steering rate or workspace), refused before anything was sent: bad input, never clipped.
    ``partial`` as :class:`PlantError`'s."""

    partial: Any = None


ENDS_A_RUN = (LearnerError, PlantError, LimitError, KeyboardInterrupt)
"""What ends a run before its budget with the trials run before it kept (:func:`keep_partial`):
the user's learner or plant failed, commands beyond the robot's limits, the user's interrupt."""


def keep_partial(error: BaseException, partial: Any) -> None:
    """Attach ``partial``, what was run before ``error`` (one of :data:`ENDS_A_RUN`), to it as
    ``error.partial``, for whoever catches it to keep; re-raise it after."""
    error.partial = partial  # type: ignore[attr-defined]  # a KeyboardInterrupt declares none
