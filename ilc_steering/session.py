"""``ilc-steering session``: learning with a robot that is driven by a person or a script, through a folder.

The paper's section 5 in a folder: ``new`` starts a session (a process-plant config: the robot's
nominal model, its limits and control rate; a learner; a seed), ``next`` writes the next trial's
commands, the robot runs them, ``record`` stores where it stopped, ``status`` shows the trials so
far. Nothing but the measurements is kept: every command replays the session from them, the
learner made afresh from its id and seed and fed every recorded trial in order, so the session
resumed a week later on another machine gives the same next commands (a replay whose commands
differ from the recorded ones is refused, naming the trial). No pickles, and every file is written
atomically.

A session folder holds ``session.json`` (the learner, the seed, the budget), ``config.yaml`` (a copy
of the config it was started with) and ``trials/NNNN/``: ``request.json`` (the process plant's
request: the chained inputs ``v1, v2`` and the robot's nominal inputs sampled at the control rate,
the nominal path, the limits), ``commands.csv`` (the same samples as columns) and, once recorded,
``result.json`` (the process plant's answer: the final pose, world frame). A withdrawn result
(a botched trial) is moved to ``withdrawn/`` and the trial is asked again, uncounted.
"""

from __future__ import annotations

import fcntl
import math
import os
import shutil
import time
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from ilc_steering import __version__
from ilc_steering.config import SteeringConfig, load_config
from ilc_steering.config.loading import resolve_config
from ilc_steering.core.robots.process import ProcessPlant, ProcessPlantConfig
from ilc_steering.errors import BadInput, ConfigError, LimitError, PlantError
from ilc_steering.output import check_output_dir, open_lock, write_atomic, write_json
from ilc_steering.readers import read_json
from ilc_steering.runner import RunResult, learner_spec, run_ilc

__all__ = ["Replay", "Session", "SessionPending"]

SESSION = "session.json"
CONFIG = "config.yaml"
MAX_RECORD_BYTES = 64 << 20
"""The largest file of a session read back [bytes] (a request at 1 kHz for minutes fits)."""


class SessionPending(PlantError):
    """The replay reached a trial the robot has not run: its request is written, ``trial`` its number."""

    def __init__(self, trial: int, folder: Path, request: dict[str, Any]) -> None:
        super().__init__(f"trial {trial} is pending: its commands are in {folder}")
        self.trial = trial
        self.folder = folder
        self.request = request


class _SessionFileError(PlantError):
    """A session's file that the replay cannot take: unreadable, of another shape, or a request
    other than the replay's (raised through the env, refused as bad input by :meth:`Session.replay`)."""


class _FolderCable:
    """The process plant's cable, answered from a session's folder: a request whose result is
    recorded gets it; the first one without is written there, and the replay stops."""

    def __init__(self, trials: Path, write: bool) -> None:
        self.name = f"the session's robot ({trials.parent})"
        self.trials = trials
        self.write = write
        self._pending: dict[str, Any] | None = None

    def fail(self, problem: str) -> PlantError:
        return _SessionFileError(f"{self.name}: {problem}")

    def _read(self, path: Path) -> dict[str, Any]:
        try:
            data = read_json(path, MAX_RECORD_BYTES)
        except ValueError as error:
            raise _SessionFileError(str(error)) from None
        if not isinstance(data, dict):
            raise _SessionFileError(f"{path}: holds a {type(data).__name__}, not a JSON object")
        return data

    def send(self, message: dict[str, Any], what: str) -> None:
        self._pending = message

    def receive(self, timeout: float, what: str) -> dict[str, Any]:
        request, self._pending = self._pending, None
        assert request is not None, "receive() before send()"
        k = int(request["trial"])
        folder = self.trials / f"{k:04d}"
        recorded = folder / "request.json"
        if recorded.exists():
            before = self._read(recorded)
            if before.get("c") != request["c"]:
                raise _SessionFileError(
                    f"{recorded}: the replay asks trial {k} with other coefficients than the recorded ones "
                    f"({request['c']} != {before.get('c')}): the session was started by another version of the "
                    "library or of the learner, and cannot be continued by this one"
                )
        result = folder / "result.json"
        if result.exists():
            return self._read(result)
        if self.write and not recorded.exists():
            folder.mkdir(parents=True, exist_ok=True)
            write_atomic(folder / "commands.csv", _commands_csv(request))
            write_json(recorded, request)
        raise SessionPending(k, folder, request)

    def close(self, kill: bool = False) -> None:
        pass


def _commands_csv(request: dict[str, Any]) -> str:
    """The request's samples as columns: time, the chained inputs, the robot's nominal inputs, the nominal pose."""
    control, nominal = request["control"], request["nominal"]
    q = np.asarray(nominal["q"], dtype=np.float64)
    coordinates = ["x", "y", "theta", "phi"][: q.shape[1]]
    lines = [",".join(["t", "v1", "v2", "u1", "u2", *(f"nominal_{c}" for c in coordinates)])]
    for i, t in enumerate(control["t"]):
        row = [t, control["v1"][i], control["v2"][i], nominal["u1"][i], nominal["u2"][i], *q[i]]
        lines.append(",".join(repr(float(v)) for v in row))
    return "\n".join(lines) + "\n"


@dataclass(frozen=True, eq=False)
class _SessionPlant(ProcessPlant):
    """A process plant whose program is the session's folder."""

    write: bool = False

    def _cable(self) -> Any:
        if not self._link.cables:
            self._link.cables.append(_FolderCable(Path(self.folder) / "trials", self.write))  # type: ignore[arg-type]
        return self._link.cables[0]


@dataclass(frozen=True)
class _SessionPlantConfig(ProcessPlantConfig):
    write: bool = False  # write the pending trial's commands

    plant_class: ClassVar[type[ProcessPlant]] = _SessionPlant

    def _check_command(self) -> None:  # no program is started: the folder answers
        pass

    def plant(self) -> ProcessPlant:
        return _SessionPlant(
            self.command, str(self.folder), self.timeout, self.control_rate, self.limits, self.nominal_map(),
            self.nominal(), self.kind, self.robot.dimension, write=self.write,
        )  # fmt: skip


@dataclass
class Replay:
    """What the recorded measurements give: the trials so far and the pending one, if any
    (``refused``: its commands are beyond the robot's limits)."""

    result: RunResult
    pending: int | None
    pending_folder: Path | None
    refused: LimitError | None = None
    request: dict[str, Any] | None = None
    """The pending trial's request (its commands), if any and within the limits."""


class Session:
    """A session folder (see the module docstring)."""

    def __init__(self, folder: Path) -> None:
        self.folder = Path(folder)
        path = self.folder / SESSION
        if not path.is_file():
            raise BadInput(f"{self.folder}: not a session folder (no {SESSION}; start one with `session new`)")
        data = read_json(path, MAX_RECORD_BYTES)
        kinds = {"learner": str, "seed": int, "trials": int, "version": str, "created": str}
        if not isinstance(data, dict) or set(data) != set(kinds):
            raise BadInput(f"{path}: not a session record (it holds exactly the keys {sorted(kinds)})")
        for key, kind in kinds.items():
            value = data[key]
            least = {"seed": 0, "trials": 1}.get(key)
            small = least is not None and isinstance(value, int) and value < least
            if not isinstance(value, kind) or isinstance(value, bool) or small:
                needs = f"a whole number >= {least}" if least is not None else "a string"
                raise BadInput(f"{path}: {key} = {value!r}: needs {needs}")
        self.learner: str = data["learner"]
        self.seed: int = data["seed"]
        self.trials: int = data["trials"]
        self.config = _session_config(load_config(self.folder / CONFIG), self.folder)

    @contextmanager
    def locked(self) -> Iterator[None]:
        """Hold the session's lock: a second command on the same session at once is refused."""
        handle = open_lock(self.folder / ".lock")
        try:
            try:
                fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                raise BadInput(f"{self.folder}: another session command is running on it; wait for it") from None
            yield
        finally:
            os.close(handle)

    @classmethod
    def new(cls, folder: Path, config: str | Path, learner: str, seed: int, trials: int | None) -> Session:
        """Start a session in ``folder`` (new or empty) from a process-plant ``config`` (a path or a
        packaged config's name, read once: its text is the session's ``config.yaml``)."""
        source = resolve_config(config)
        steering = load_config(source)
        _session_config(steering, folder)  # refused before anything is written
        learner_spec(learner)
        budget = steering.learning.trials if trials is None else trials
        if isinstance(budget, bool) or not isinstance(budget, int) or budget < 1:
            raise BadInput(f"--trials must be a whole number >= 1, got {budget!r}")
        folder = Path(folder)
        if folder.exists() and any(folder.iterdir()):
            raise BadInput(f"{folder}: exists and is not empty; a session starts in a new or empty folder")
        check_output_dir(folder, "session folder")
        write_atomic(folder / CONFIG, source.text)
        record = {"learner": learner, "seed": seed, "trials": budget, "version": __version__, "created": _now()}
        write_json(folder / SESSION, record)
        return cls(folder)

    def replay(self, write: bool = True) -> Replay:
        """Every recorded trial fed to a fresh learner, until the first trial without a result,
        whose commands are written (``write``) unless they are beyond the robot's limits."""
        plant = self.config.plant
        assert isinstance(plant, _SessionPlantConfig)
        config = replace(self.config, plant=replace(plant, write=write))
        try:
            result = run_ilc(config, trials=self.trials, learner=self.learner, seed=self.seed)
        except SessionPending as pending:  # run_ilc keeps the trials before it, judged as run judges
            return Replay(pending.partial, pending.trial, pending.folder, request=pending.request)
        except _SessionFileError as error:
            raise BadInput(str(error)) from None
        except LimitError as refused:
            k = len(refused.partial.trials) + 1
            return Replay(refused.partial, k, self.folder / "trials" / f"{k:04d}", refused)
        return Replay(result, None, None)

    def record(self, final: Sequence[float]) -> Replay:
        """Store the pending trial's measured final pose (world frame) and learn from it; the
        session is unchanged if the pose is refused."""
        before = self.replay(write=False)
        if before.pending is None or before.pending_folder is None:
            raise BadInput(f"{self.folder}: no pending trial (the session has run its {self.trials} trials)")
        if not (before.pending_folder / "request.json").exists():
            raise BadInput(f"{self.folder}: trial {before.pending} has no commands yet: run `session next` first")
        dimension = self.config.plant.dimension
        values = [float(v) for v in final]
        if len(values) == dimension - 1 and dimension == 4:  # no steering angle measured: the commanded one
            request = read_json(before.pending_folder / "request.json", MAX_RECORD_BYTES)
            values.append(float(request["nominal"]["q"][-1][3]))
        if len(values) != dimension or not all(math.isfinite(v) for v in values):
            raise BadInput(f"--final needs {dimension} finite numbers (x, y, theta[, phi]; world frame), got {final}")
        result = before.pending_folder / "result.json"
        write_json(result, {"type": "result", "trial": before.pending, "final": values})
        try:
            return self.replay(write=False)
        except (PlantError, ValueError) as error:  # the pose refused (outside the workspace, ...): unchanged
            result.unlink()
            raise BadInput(str(error)) from None

    def withdraw(self) -> int:
        """Move the last recorded result to ``withdrawn/``: that trial is asked again, uncounted.
        The next trial's commands, learned from that result, go with it (``NNNN-<time>/``)."""
        recorded = sorted((self.folder / "trials").glob("*/result.json"))
        if not recorded:
            raise BadInput(f"{self.folder}: no recorded trial to withdraw")
        last = recorded[-1]
        k = int(last.parent.name)
        stamp = _now().replace(":", "")
        withdrawn = self.folder / "withdrawn"
        withdrawn.mkdir(exist_ok=True)
        shutil.move(last, _unused(withdrawn / f"{k:04d}-{stamp}", ".json"))
        for later in sorted((self.folder / "trials").iterdir()):
            if later.is_dir() and later.name.isdigit() and int(later.name) > k:
                shutil.move(later, _unused(withdrawn / f"{later.name}-{stamp}", ""))
        return k


def _unused(stem: Path, suffix: str) -> Path:
    """``stem + suffix``, or with ``-2``, ``-3``, ... before the suffix if taken (two withdrawals in
    one second keep both)."""
    path, n = Path(f"{stem}{suffix}"), 1
    while path.exists():
        n += 1
        path = Path(f"{stem}-{n}{suffix}")
    return path


def _session_config(config: SteeringConfig, folder: Path) -> SteeringConfig:
    """``config`` with its process plant answered from ``folder``; refused unless it is a process
    plant. (``simulation.measurement_noise`` adds the library's simulated noise to what is recorded,
    as for any plant: for a simulated robot; a real robot's config leaves it out.)"""
    plant = config.plant
    if not isinstance(plant, ProcessPlantConfig):
        raise ConfigError(
            f"{config.name}: a session needs plant.model: process (the robot's nominal model, its limits and "
            f"control rate; docs/your_robot.md), got plant.model: {getattr(plant, 'model', plant)}"
        )
    fields = {name: getattr(plant, name) for name in ("model", "command", "robot", "limits", "timeout", "control_rate")}
    return replace(config, plant=_SessionPlantConfig(**fields, folder=str(Path(folder).resolve())))


def _now() -> str:
    return time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())
