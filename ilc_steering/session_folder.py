"""A session's folder (:class:`Session`), under the verbs of :mod:`ilc_steering.session`.

Nothing but the measurements is kept: every verb replays the session from them, the learner made
afresh from its id and seed (no pickles; no program is run). The folder holds ``session.json``
(learner, seed, budget, version, the config's hash), ``config.yaml`` (the config as read at ``new``),
``trials/NNNN/``: ``request.json`` (the process plant's request), ``commands.csv`` (its samples as
columns) and, once recorded, ``result.json`` (the final pose, world frame, and under ``recorded`` the
hashes of that pose and of the request it answered); ``withdrawn/``, the results taken back. Every
file ends with a newline; every change is all or none; a folder edited by hand is named for what
changed (docs/trust.md) before a replay is put to the learner or the library.
"""

from __future__ import annotations

import fcntl
import json
import os
import time
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Annotated, Any, ClassVar

from pydantic import Field

from ilc_steering import __version__
from ilc_steering.config import SteeringConfig, load_config
from ilc_steering.config.loading import MAX_FILE_BYTES, ConfigSource, resolve_config
from ilc_steering.core.robots.process import ProcessPlant, ProcessPlantConfig, without_program
from ilc_steering.errors import BadInput, ConfigError, LimitError, PlantError
from ilc_steering.output import content_hash, json_text, make_folder, move_all, open_lock, write_atomic
from ilc_steering.pose_files import commands_csv, typed_pose
from ilc_steering.readers import check_new_folder, describe, holds, is_file, read_json, read_text
from ilc_steering.runner import RunResult, learner_spec, run_ilc
from ilc_steering.schema import MethodName, check_record

__all__ = ["Replay", "Session", "SessionPending"]

SESSION = "session.json"
CONFIG = "config.yaml"
RECORDED = "recorded"
"""The key of a ``result.json`` under which ``record`` keeps the hashes of the pose and of the request."""
MAX_RECORD_BYTES = 64 << 20
"""The largest file of a session read back [bytes] (a request at 1 kHz for minutes fits)."""


@dataclass(frozen=True)
class _Record:
    """``session.json``, checked by the schema library (a key missing or added, a type, a range)."""

    learner: MethodName
    seed: Annotated[int, Field(ge=0)]
    trials: Annotated[int, Field(ge=1)]
    version: str
    created: str
    config: str | None = None  # the hash of config.yaml; None: a session made before issue 64


class SessionPending(PlantError):
    """The replay reached a trial the robot has not run (its files ``restored`` or ``intact``: see :class:`Replay`)."""

    def __init__(self, trial: int, folder: Path, request: dict[str, Any], restored: list[str], intact: bool) -> None:
        super().__init__(f"trial {trial} is pending: its commands are in {folder}")
        self.trial, self.folder, self.request, self.restored, self.intact = trial, folder, request, restored, intact


class _SessionFileError(PlantError):
    """A session's file that the replay cannot take (raised through the env, bad input to the user)."""


class _Replayed(PlantError):
    """The replay asks trial ``trial`` other coefficients than its ``request.json`` at ``path``, a file
    as ``next`` wrote it; ``version`` the one that recorded its result, if any."""

    def __init__(self, trial: int, path: Path, version: str | None) -> None:
        super().__init__(f"{path}: other coefficients")
        self.trial, self.path, self.version = trial, path, version


class _FolderCable:
    """The process plant's cable, answered from a session's folder: a request whose result is
    recorded (or is the ``candidate`` a record checks) gets it; the first one without is pending,
    its files written again where they are not the request's (``write``), and the replay stops."""

    closed = False

    def __init__(self, trials: Path, write: bool, candidate: dict[str, Any] | None) -> None:
        self.name = f"the session's robot ({trials.parent})"
        self.trials, self.write, self.candidate = trials, write, candidate
        self._pending: dict[str, Any] | None = None

    def fail(self, problem: str) -> PlantError:
        return _SessionFileError(f"{self.name}: {problem}")

    def _read(self, path: Path) -> Any:
        try:
            return read_json(path, MAX_RECORD_BYTES)
        except ValueError as error:
            raise _SessionFileError(str(error)) from None

    def send(self, message: dict[str, Any], what: str, timeout: float | None = None) -> None:
        self._pending = message

    def receive(self, timeout: float, what: str) -> dict[str, Any]:
        request, self._pending = self._pending, None
        assert request is not None, "receive() before send()"
        k = int(request["trial"])
        folder = self.trials / f"{k:04d}"
        asked, result = folder / "request.json", folder / "result.json"
        if self.candidate is not None and self.candidate["trial"] == k:
            return {key: value for key, value in self.candidate.items() if key != RECORDED}
        if not is_file(result):
            raise self._pending_trial(k, folder, request)
        answer = self._read(result)
        if not isinstance(answer, dict):
            raise _SessionFileError(f"{result}: holds a {type(answer).__name__}, not a JSON object")
        hashes = answer.pop(RECORDED, None)
        hashes = hashes if isinstance(hashes, dict) else {}  # none: recorded before issue 64
        if hashes and hashes.get("final") != content_hash([k, answer.get("final")]):
            raise _SessionFileError(
                f"{result}: edited by hand after `session record` wrote it (its final pose is not the one "
                "recorded); put the recorded one back, or withdraw the trial and record it again"
            )
        on_file = self._read(asked) if is_file(asked) else None
        c = on_file.get("c") if isinstance(on_file, dict) else None
        if c != request["c"]:
            if on_file is None or not isinstance(c, list) or hashes.get("request") == content_hash(request["c"]):
                raise _SessionFileError(
                    f"{asked}: deleted or edited by hand (trial {k}'s result was recorded against other coefficients "
                    "than these: the replay's); put it back as `session next` wrote it"
                )
            raise _Replayed(k, asked, hashes.get("version"))
        return answer

    def _pending_trial(self, k: int, folder: Path, request: dict[str, Any]) -> SessionPending:
        """The pending trial ``k``: its files checked against ``request``, written (again) if ``write``."""
        files = {"request.json": json_text(request), "commands.csv": commands_csv(request)}
        asked = folder / "request.json"
        on_file = self._read(asked) if is_file(asked) else None
        c = on_file.get("c") if isinstance(on_file, dict) else None
        if isinstance(c, list) and isinstance(on_file, dict) and on_file.get("trial") == k and c != request["c"]:
            raise _Replayed(k, asked, None)  # a request as written, of other coefficients: never overwritten
        wrong = sorted(name for name, text in files.items() if not holds(folder / name, text, MAX_RECORD_BYTES))
        if "request.json" in wrong and holds(asked, json.dumps(request), MAX_RECORD_BYTES):
            wrong.remove("request.json")  # as `next` wrote it before issue 68: without the newline
        asked_before = any(is_file(folder / name) for name in files)
        if wrong and self.write:
            folder.mkdir(parents=True, exist_ok=True)
            for name in wrong:  # commands.csv first: request.json marks a trial asked
                write_atomic(folder / name, files[name])
        restored = wrong if self.write and asked_before else []
        return SessionPending(k, folder, request, restored, self.write or not wrong)

    def close(self, kill: bool = False) -> None:
        pass


@dataclass(frozen=True, eq=False)
class _SessionPlant(ProcessPlant):
    """A process plant whose program is the session's folder."""

    write: bool = False
    candidate: dict[str, Any] | None = None

    @property
    def who(self) -> str:  # a session runs no process: a trial refused is one not written to its folder
        return f"the robot of the session {self.folder}"

    def _cable(self) -> Any:
        if not self._link.cables:
            self._link.cables.append(_FolderCable(Path(self.folder) / "trials", self.write, self.candidate))  # type: ignore[arg-type]
        return self._link.cables[0]


@dataclass(frozen=True)
class _SessionPlantConfig(ProcessPlantConfig):
    write: bool = False  # write the pending trial's files (again)
    candidate: dict[str, Any] | None = field(default=None, compare=False)  # a result a record checks

    plant_class: ClassVar[type[ProcessPlant]] = _SessionPlant

    def _check_command(self) -> None:  # no program is started: the folder answers
        pass

    def plant(self) -> ProcessPlant:
        return _SessionPlant(
            self.command, str(self.folder), self.timeout, self.control_rate, self.limits, self.nominal_map(),
            self.nominal(), self.kind, self.robot.dimension, write=self.write, candidate=self.candidate,
        )  # fmt: skip


@dataclass
class Replay:
    """The recorded trials and the pending one, if any (``refused``: beyond the robot's limits)."""

    result: RunResult
    pending: int | None
    pending_folder: Path | None
    refused: LimitError | None = None
    request: dict[str, Any] | None = None
    """The pending trial's request (its commands), if any and within the limits."""
    restored: list[str] = field(default_factory=list)
    """The pending trial's files that ``next`` wrote again (cut short, deleted, edited)."""
    intact: bool = True
    """Whether the pending trial's files on disk are its request's."""


class Session:
    """A session folder (see the module docstring)."""

    def __init__(self, folder: Path) -> None:
        self.folder = Path(folder)
        path = self.folder / SESSION
        if not is_file(path):
            raise BadInput(f"{self.folder}: not a session folder (no {SESSION}; start one with `session new`)")
        data = check_record(_Record, read_json(path, MAX_RECORD_BYTES), path)  # a FIFO, a loop of links: named
        try:
            learner_spec(data.learner)
        except BadInput as error:
            raise BadInput(f"{path}: {str(error).replace('--learner: ', 'learner: ', 1)}") from None
        self.learner, self.seed, self.trials, self.version = data.learner, data.seed, data.trials, data.version
        text = read_text(self.folder / CONFIG, MAX_FILE_BYTES)
        if data.config not in (None, content_hash(text)):
            raise BadInput(
                f"{self.folder / CONFIG}: not the config this session was started with ({SESSION} holds the hash "
                "of that one): a session runs on the config it started with; put it back, or start a new session"
            )
        with without_program():  # a session runs no program: one missing here is no matter
            self.recorded = load_config(ConfigSource(text, str(self.folder / CONFIG), None, str(self.folder)))
        self.config = _session_config(self.recorded, self.folder)

    @contextmanager
    def locked(self, write: bool = True) -> Iterator[None]:
        """Hold the session's lock, exclusive to ``write``, shared to read: a command that would write
        while another command runs, or read while one writes, is refused."""
        handle = open_lock(self.folder / ".lock", shared=not write)
        try:
            if handle >= 0:  # -1: a folder nobody can write (read-only, archived): nothing to hold
                try:
                    fcntl.flock(handle, (fcntl.LOCK_EX if write else fcntl.LOCK_SH) | fcntl.LOCK_NB)
                except BlockingIOError:
                    raise BadInput(f"{self.folder}: another session command is running on it; wait for it") from None
            yield
        finally:
            if handle >= 0:
                os.close(handle)

    @classmethod
    def new(cls, folder: Path, config: str | Path, learner: str, seed: int, trials: int | None) -> Session:
        """Start a session in ``folder`` (new or empty) from a process-plant ``config`` (a path or a
        packaged config's name, read once: its text is the session's ``config.yaml``). Everything is
        checked before the folder is made, and it is made whole or not at all."""
        folder = check_new_folder(Path(folder), "a session")
        source = resolve_config(config)
        with without_program():  # a session runs none
            steering = load_config(source)
        _session_config(steering, folder)
        learner_spec(learner)
        budget = steering.learning.trials if trials is None else trials
        for option, value, least in (("--trials", budget, 1), ("--seed", seed, 0)):
            if isinstance(value, bool) or not isinstance(value, int) or value < least:
                raise BadInput(f"{option} must be a whole number >= {least}, got {value!r}")
        record = {"learner": learner, "seed": seed, "trials": budget, "version": __version__, "created": _now()}
        text = source.text if source.text.endswith("\n") else source.text + "\n"
        record["config"] = content_hash(text)
        make_folder(folder, {CONFIG: text, SESSION: json_text(record)}, "the session folder")
        return cls(folder)

    def replay(self, write: bool = True, candidate: dict[str, Any] | None = None, paths: bool = False) -> Replay:
        """Every recorded trial fed to a fresh learner, until the first trial without a result (or
        without ``candidate``, a result being recorded), whose files are written (``write``) unless
        its commands are beyond the robot's limits; with ``paths``, each trial's path (its start and
        end: a session records no more) for a run record's figures."""
        self._trials()
        plant = self.config.plant
        assert isinstance(plant, _SessionPlantConfig)
        config = replace(self.config, plant=replace(plant, write=write, candidate=candidate))
        try:
            result = run_ilc(config, trials=self.trials, trajectories=paths, learner=self.learner, seed=self.seed)
        except SessionPending as p:  # run_ilc keeps the trials before it, judged as run judges
            return Replay(self._as_recorded(p.partial), p.trial, p.folder, None, p.request, p.restored, p.intact)
        except _Replayed as replayed:
            raise BadInput(self._diagnosis(replayed)) from None
        except _SessionFileError as error:
            raise BadInput(str(error)) from None
        except LimitError as refused:
            k = len(refused.partial.trials) + 1
            return Replay(self._as_recorded(refused.partial), k, self.folder / "trials" / f"{k:04d}", refused)
        return Replay(self._as_recorded(result), None, None)

    def _as_recorded(self, result: RunResult) -> RunResult:
        """``result`` with the session's config as it is on disk: a run record that ``plot`` reads."""
        return replace(result, config=self.recorded)

    def _diagnosis(self, replayed: _Replayed) -> str:
        """What made the replay ask other coefficients than a request as written: by now the results
        before it, its own result's record of it and the config are known to be as recorded."""
        asks = f"{replayed.path}: the replay asks trial {replayed.trial} other coefficients than these"
        version = replayed.version or self.version
        if version != __version__:
            return f"{asks}: they were recorded by ilc-steering {version}, this is {__version__}; continue with that"
        return (
            f"{asks}, from results and a config as recorded: the learner {self.learner}'s code or the library's "
            f"changed since (version {version} both), {SESSION}'s seed or learner was edited, or this file was"
        )

    def record(self, final: Sequence[float]) -> Replay:
        """Store the pending trial's measured final pose (world frame) and learn from it: the replay
        takes it first, so a pose refused (or a learner that fails on it) leaves the folder as it was."""
        before = self.replay(write=False)
        k, folder = before.pending, before.pending_folder
        if k is None or folder is None:
            raise BadInput(f"{self.folder}: no pending trial (the session has run its {self.trials} trials)")
        if before.request is None or not is_file(folder / "request.json"):
            raise BadInput(f"{self.folder}: trial {k} has no commands yet: run `session next` first")
        if not before.intact:
            raise BadInput(
                f"{folder}: trial {k}'s request.json or commands.csv is not what `session next` wrote (cut short, "
                "deleted, edited): the robot may have run part of it; run `session next` to write them again, "
                "run the trial, then record it"
            )
        values = typed_pose(final, self.config.plant.kind, before.request["nominal"]["q"][-1], "--final")
        hashes = {
            "final": content_hash([k, values]),
            "request": content_hash(before.request["c"]),
            "version": __version__,
        }
        result = {"type": "result", "trial": k, "final": values, RECORDED: hashes}
        after = self.replay(write=False, candidate=result)
        write_atomic(folder / "result.json", json_text(result))
        return after

    def _trials(self) -> tuple[int, list[int]]:
        """The trial folders' count and the recorded trials, in order; refused when a trial's folder or
        result is missing under a later trial's (deleted by hand: the later one would hide behind it)."""
        root = self.folder / "trials"
        try:
            names = sorted(entry.name for entry in os.scandir(root) if entry.name.isdigit())
        except FileNotFoundError:
            return 0, []
        except OSError as error:
            raise BadInput(f"{root}: cannot read it ({describe(error)})") from None
        recorded = [int(name) for name in names if is_file(root / name / "result.json")]
        for i, name in enumerate(names):
            if name != f"{i + 1:04d}":
                raise BadInput(f"{root / f'{i + 1:04d}'}: missing, though {root / name} is there: put it back")
            if i + 1 not in recorded and i + 1 < len(names):
                raise BadInput(
                    f"{root / name / 'result.json'}: missing, though trial {names[-1]} is there (a result deleted by "
                    f"hand); put it back, or move {root / names[i + 1]} and later away as `session withdraw` does"
                )
        return len(names), recorded

    def withdraw(self) -> int:
        """Move the last recorded result to ``withdrawn/``: that trial is asked again, uncounted. The
        next trial's commands, learned from that result, go with it (``NNNN-<time>/``). All of it or
        none: a move that fails (``withdrawn`` a file, a folder that cannot be written) undoes the others."""
        count, recorded = self._trials()
        if not recorded:
            raise BadInput(f"{self.folder}: no recorded trial to withdraw")
        k, stamp, withdrawn = recorded[-1], _now().replace(":", ""), self.folder / "withdrawn"
        trials = self.folder / "trials"  # the farthest trial first: stopped halfway, the session still replays
        moves = [(trials / f"{j:04d}", _unused(withdrawn / f"{j:04d}-{stamp}", "")) for j in range(count, k, -1)]
        moves.append((trials / f"{k:04d}" / "result.json", _unused(withdrawn / f"{k:04d}-{stamp}", ".json")))
        move_all(moves, withdrawn, f"{self.folder}: withdrawing trial {k}")
        return k


def _unused(stem: Path, suffix: str) -> Path:
    """``stem + suffix``, or with ``-2``, ``-3``, ... before the suffix if taken (two withdrawals in
    one second keep both)."""
    path, n = Path(f"{stem}{suffix}"), 1
    while os.path.lexists(path):
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
    return replace(config, plant=_SessionPlantConfig(**fields, folder=os.path.realpath(folder)))


def _now() -> str:
    return time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())
