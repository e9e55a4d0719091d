"""A plant that is someone else's code: a simulator or a robot that runs one trial as a Python call.

The library's own plants hand the simulator a compiled vector field (:class:`~ilc_steering.core.plants.Plant`).
A plant written elsewhere (another simulator, a real car behind a driver) cannot: it takes a trial's
input profile and coefficients and returns where the robot ended, and optionally the states it
passed through. :class:`ExternalPlant` is that contract; the controller's view stays the library's
nominal model (:class:`~ilc_steering.core.nominal.NominalModel`), built from the config's
``nominal_map()`` as for any robot.

The envs, ``run`` and ``compare`` take an external plant like any other
(:meth:`~ilc_steering.envs.scenario.Scenario.run` hands it the trial). What needs the plant's
equations is refused with one line, never faked: the compiled kernel (``kernel``), true factors
(``with_true_factors``: ``parameter_jitter``, a vector env's ``true_factors``, a robustness map,
``sweep --axis``), a model family (``with_family``) and the ``solve_ivp`` reference
(``reference_field``). :class:`ExternalPlantBase` holds those refusals.

A plant that scatters its trials (a simulated rough floor, a scatter drawn per trial) draws from a
generator of its own; the env's seed reaches it through :meth:`ExternalPlant.reseed`, which the
envs call on ``reset(seed=...)`` (so ``ilc-steering run``'s seed and each of ``compare``'s seeds): the same
seed gives the same trials, another seed another draw. :func:`plant_generator` makes that
generator, a stream apart from the env's own. :class:`ExternalPlantBase`'s ``reseed`` does
nothing (a real robot, a plant that repeats itself), so a subclass written before it keeps working.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass, field
from reprlib import repr as show
from typing import Any, ClassVar, NoReturn, Protocol, runtime_checkable

import numpy as np
import numpy.typing as npt

from ilc_steering.core.checks import require
from ilc_steering.core.plants import CHART_MARGIN, Kernel, PlantKind
from ilc_steering.core.profiles import InputProfile
from ilc_steering.core.simulate import Trials
from ilc_steering.core.stepper import LEFT_CHART, OK
from ilc_steering.errors import INTERRUPTS, BadInput, ConfigError, LimitError, PlantError, described

__all__ = [
    "PLANT_STREAM",
    "ExternalPlant",
    "ExternalPlantBase",
    "ExternalTrials",
    "chart_status",
    "is_external",
    "plain_log",
    "plant_generator",
    "run_external",
    "users_plant",
]

Array = npt.NDArray[np.float64]


@dataclass(frozen=True)
class ExternalTrials(Trials):
    """:class:`~ilc_steering.core.simulate.Trials` of an external plant, with what the plant itself
    logged for each trial (``logs[b]``, a mapping of plain JSON data: the actions it was sent, a
    crash, its own success test; or none at all, ``[]``); the env puts ``logs[b]`` in the trial's
    ``info["plant"]`` and ``run --json`` keeps it. A log that is not JSON data (an object, a NaN) is
    the plant's failure (:func:`run_external`)."""

    logs: list[dict[str, Any]] = field(default_factory=list)


@runtime_checkable
class ExternalPlant(Protocol):
    """What a plant that is someone else's code provides.

    The configuration it reports is the library's (for a car: rear-axle ``x``, ``y`` [m], ``theta``,
    ``phi`` [rad]), in the *task frame* the scenario gives it with :meth:`with_frame`; its states are
    configurations (``state_dim`` entries, :meth:`configuration` the identity or a projection).
    """

    kind: ClassVar[PlantKind]
    factor_names: ClassVar[tuple[str, str]]

    @property
    def state_dim(self) -> int: ...

    @property
    def steering_limit(self) -> float | None: ...

    def configuration(self, x: Array) -> Array: ...

    def estimate(self, x: Array) -> Array: ...

    def check_configuration(self, q: Array) -> None: ...

    def initial_state(self, q: Array) -> Array: ...

    def with_frame(self, angle: float) -> ExternalPlant:
        """The plant reporting configurations in the task frame, the world rotated by ``angle`` [rad]."""
        ...

    def run_trials(self, profile: InputProfile, x0: Array, c: Array, record: bool = False) -> ExternalTrials:
        """Run ``B`` trials with coefficients ``c`` ``(B, 1 + q)`` of ``profile`` from states ``x0``
        ``(B, state_dim)`` (task frame): their final states, status (``OK`` or ``LEFT_CHART``), the
        states at ``times`` with ``record``, and each trial's log."""
        ...

    def reseed(self, seed: int) -> None:
        """Start the plant's own random draws (a simulated scatter) afresh from the env's ``seed``
        (``reset(seed=...)``: ``run``'s seed, each of ``compare``'s seeds): the same seed gives the
        same trials, another seed another draw (:func:`plant_generator`). A plant that draws
        nothing of its own (a real robot) does nothing."""
        ...


PLANT_STREAM = 48
"""The spawn key of an external plant's own generator (:func:`plant_generator`): it sets the
plant's draws apart from the env's ``np_random`` of the same seed."""


def plant_generator(seed: int, plant_seed: int = 0) -> np.random.Generator:
    """The generator of an external plant's own draws for the env's ``seed`` and the plant's own
    ``plant_seed`` (a config key, 0 if it has none): a stream of its own, independent of the
    env's ``np_random`` seeded by the same ``seed`` (which draws the measurement noise, the
    start error), so the plant's scatter and the env's noise are not one sequence of numbers
    twice. ``ValueError`` naming the seeds unless both are integers >= 0."""
    for name, value in (("seed", seed), ("plant seed", plant_seed)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 0:
            raise BadInput(f"an external plant's {name} must be an integer >= 0, got {value!r:.40}")
    return np.random.default_rng(np.random.SeedSequence([int(seed), int(plant_seed)], spawn_key=(PLANT_STREAM,)))


def is_external(plant: object) -> bool:
    """Whether ``plant`` runs its own trials (an :class:`ExternalPlant`) rather than a compiled field."""
    return isinstance(plant, ExternalPlant)


def chart_status(q: Array, states: list[Array], status: int, halted: Array) -> tuple[int, Array]:
    """A trial's status and where it halts after its configuration ``q`` (``states`` so far, ``q``
    last): ``LEFT_CHART`` at the configuration before, once ``|theta|`` comes within
    ``CHART_MARGIN`` of pi/2; as they were otherwise (a plant's trial loop, step by step)."""
    if status == OK and abs(q[2]) >= math.pi / 2 - CHART_MARGIN:
        return LEFT_CHART, states[-2] if len(states) > 1 else q
    return status, halted


class ExternalPlantBase:
    """The refusals every external plant shares: what needs the plant's equations (see the module)."""

    name: ClassVar[str] = "an external plant"
    """What the refusals call the plant."""

    def configuration(self, x: Array) -> Array:
        """The configuration of state ``x``: an external plant's states are its measured configurations."""
        return np.array(x, dtype=np.float64)

    def estimate(self, x: Array) -> Array:
        """What the controller sees of state ``x``: the measured configuration."""
        return np.array(x, dtype=np.float64)

    def initial_state(self, q: Array) -> Array:
        """The state a trial starts from at configuration ``q``: ``q`` itself."""
        return np.array(q, dtype=np.float64)

    def reseed(self, seed: int) -> None:
        """Nothing: a plant that draws random numbers of its own (a simulated scatter) overrides
        this to restart its generator from ``plant_generator(seed, ...)`` (see the protocol)."""

    def control_period(self) -> float:
        """[s] the period at which the plant takes a new input (a trial's length is a whole number
        of them); a plant that uses :meth:`run_trials` below gives it."""
        self._refuse("control period")

    def trial(
        self, profile: InputProfile, x0: Array, c: Array, periods: int
    ) -> tuple[Array, int, Array, dict[str, Any]]:
        """One trial of ``periods`` control periods from state ``x0`` with coefficients ``c``: its
        final state, status, the states at the period boundaries and its log; a plant that uses
        :meth:`run_trials` below gives it."""
        self._refuse("trial of its own")

    def run_trials(self, profile: InputProfile, x0: Array, c: Array, record: bool = False) -> ExternalTrials:
        """The ``B`` trials of ``c`` ``(B, 1 + q)``, one :meth:`trial` each, in order (one drive of
        the plant per trial); ``ValueError`` naming ``task.pieces`` unless the profile lasts a whole
        number of the plant's control periods."""
        total, period = sum(profile.durations), self.control_period()
        periods = round(total / period)
        require(
            abs(periods * period - total) < 1e-9,
            "task.pieces",
            f"must add up to a whole number of {self.name}'s {period} s control periods, got {total} s",
        )
        outcomes = [self.trial(profile, x0[b], c[b], periods) for b in range(c.shape[0])]
        final = np.array([o[0] for o in outcomes])
        status = np.array([o[1] for o in outcomes], dtype=np.int64)
        logs = [o[3] for o in outcomes]
        if not record:
            return ExternalTrials(final, status, logs=logs)
        times = period * np.arange(periods + 1, dtype=np.float64)
        return ExternalTrials(final, status, times, np.array([o[2] for o in outcomes]), logs=logs)

    def _refuse(self, what: str) -> NoReturn:
        raise BadInput(f"{self.name} is someone else's code: it has no {what}")

    def kernel(self) -> tuple[Kernel, Array]:
        self._refuse("compiled kernel (it runs its own trials; no numba field, no PlantBatch)")

    def with_true_factors(self, factors: Array) -> Any:
        self._refuse("true factors to scale (no parameter_jitter, true_factors, robustness map or sweep --axis)")

    def true_factors(self) -> Array:
        self._refuse("true factors to scale (no parameter_jitter, true_factors, robustness map or sweep --axis)")

    def family_names(self) -> tuple[str, ...]:
        self._refuse("model family (its equations are not the library's)")

    def with_family(self, ratios: Array) -> Any:
        self._refuse("model family (its equations are not the library's)")

    def reference_field(self, profile: Any, c: Array) -> tuple[Callable[[float, Array], Array], float, Any]:
        self._refuse("reference field for solve_ivp")


@contextmanager
def users_plant(plant: Any, what: str) -> Iterator[None]:
    """Run a call into the user's ``plant`` (``what``: ``"run_trials"``, ``"reseed"``): whatever it
    raises, ``sys.exit()`` and other ``BaseException`` included, is a
    :class:`~ilc_steering.errors.PlantError` naming the plant, except an interrupt
    (:data:`~ilc_steering.errors.INTERRUPTS`) and the plant's own
    :class:`~ilc_steering.errors.PlantError`, :class:`~ilc_steering.errors.LimitError` and
    :class:`~ilc_steering.errors.ConfigError` (bad input: a config it cannot run), which pass."""
    try:
        yield
    except (PlantError, LimitError, ConfigError, *INTERRUPTS):
        raise
    except BaseException as error:
        raise PlantError(f"{plant_name(plant)}: {what} raised {described(error)}") from error


def plant_name(plant: Any) -> str:
    """What messages call the user's plant: its ``who`` (a program's command), ``name`` or class."""
    return str(getattr(plant, "who", None) or getattr(plant, "name", None) or type(plant).__name__)


def _handed(a: Array) -> Array:
    """A read-only copy of ``a`` for the user's plant: what it does to its arguments stays with it."""
    copy = np.array(a)
    copy.flags.writeable = False
    return copy


MAX_LOG_DEPTH = 32
"""The deepest nesting of a plant's log (:func:`plain_log`)."""


def plain_log(log: Any, where: str = "its log", depth: int = 0) -> Any:
    """A copy of a plant's log of one trial as plain JSON data: ``None``, or a mapping of string keys
    to strings, booleans, ``None``, finite numbers (numpy's included, as Python's), lists and such
    mappings, at most :data:`MAX_LOG_DEPTH` deep; ``ValueError`` naming the first part that is not
    (``where`` it is: ``its log["speeds"][3]``)."""
    if log is None or (depth and isinstance(log, str)):
        return log
    if depth and isinstance(log, (bool, np.bool_)):
        return bool(log)
    if depth and isinstance(log, numbers.Integral):
        return int(log)
    if depth and isinstance(log, numbers.Real):
        if not math.isfinite(log):
            raise BadInput(f"{where} is {log!r}, not a finite number")
        return float(log)
    if depth >= MAX_LOG_DEPTH:
        raise BadInput(f"{where} is nested deeper than {MAX_LOG_DEPTH}")
    if isinstance(log, Mapping):
        wrong = next((key for key in log if not isinstance(key, str)), None)
        if wrong is not None:
            raise BadInput(f"{where} has the key {show(wrong)}, not a string")
        return {key: plain_log(value, f"{where}[{key!r}]", depth + 1) for key, value in log.items()}
    if depth and isinstance(log, (list, tuple)):
        return [plain_log(value, f"{where}[{i}]", depth + 1) for i, value in enumerate(log)]
    kind = "JSON data" if depth else "a mapping or None"
    raise BadInput(f"{where} is {show(log)} (type {type(log).__name__}), not {kind}")


def run_external(plant: ExternalPlant, profile: InputProfile, x0: Array, c: Array, record: bool) -> ExternalTrials:
    """``plant.run_trials`` behind the library's boundary. The plant gets read-only copies of ``x0``
    and ``c`` (what it writes into them never reaches the env's ``info`` nor the learner). What it
    raises is a :class:`~ilc_steering.errors.PlantError` naming the plant (:func:`users_plant`), and
    so is what it returns that is not ``B`` trials of finite, real final states ``(B, state_dim)``
    with a status ``OK`` or ``LEFT_CHART`` each (and with ``record``, ``times`` and ``states`` of
    matching shapes), with no log or one log per trial of plain JSON data (:func:`plain_log`). The
    trials returned are the library's own copies: the logs copied, a trial without one ``{}``."""
    who = plant_name(plant)
    batch = c.shape[0]
    with users_plant(plant, "run_trials"):
        trials = plant.run_trials(profile, _handed(x0), _handed(c), record)

    def refuse(problem: str) -> NoReturn:
        raise PlantError(f"{who}: run_trials returned {problem}; the trials are not counted")

    if not isinstance(trials, Trials):
        refuse(f"a {type(trials).__name__}, not ExternalTrials")
    final = np.asarray(trials.final)
    if not (np.issubdtype(final.dtype, np.integer) or np.issubdtype(final.dtype, np.floating)):
        refuse(f"final states of dtype {final.dtype}, not real numbers")
    if final.shape != (batch, plant.state_dim):
        refuse(f"final states of shape {final.shape}, not ({batch}, {plant.state_dim})")
    if not np.all(np.isfinite(final)):
        refuse("a final state that is not finite (NaN or infinite)")
    status = np.asarray(trials.status)
    if status.shape != (batch,) or not np.all(np.isin(status, (OK, LEFT_CHART))):
        refuse(f"status {status.tolist()!r}, not {batch} of OK ({OK}) or LEFT_CHART ({LEFT_CHART})")
    times, states = trials.times, trials.states
    if record:
        if times is None or states is None:
            refuse("no times or states though the trials were to be recorded")
        times, states = np.asarray(times), np.asarray(states)
        if times.ndim != 1 or states.shape != (batch, times.shape[0], plant.state_dim):
            refuse(f"times {times.shape} and states {states.shape} that do not match ({batch}, len(times), state_dim)")
    logs = trials.logs if isinstance(trials, ExternalTrials) else []
    if not isinstance(logs, (list, tuple)) or len(logs) not in (0, batch):
        count = f"{len(logs)} logs" if isinstance(logs, (list, tuple)) else f"logs of type {type(logs).__name__}"
        refuse(f"{count}, not a list of one log per trial ({batch})")
    checked: list[dict[str, Any]] = []
    for b, log in enumerate(logs):
        try:
            checked.append(plain_log(log, f"logs[{b}]"))
        except ValueError as error:
            refuse(f"a log that is not plain JSON data: {error}")
    return ExternalTrials(
        trials.final, trials.status, trials.times, trials.states, logs=checked or [{} for _ in range(batch)]
    )
