r"""A plant that is another program (``plant.model: process``): your robot on the other end of a cable.

The library starts the program once per run (``plant.command``, in the config's folder) and
speaks JSON lines with it over its stdin and stdout (``docs/your_robot.md``, protocol 1): a
``hello`` each way, then one ``trial`` request per counted trial, answered by a ``result`` (the
measured final configuration, world frame) or an ``error`` (the trial failed). A request carries
the trial's input profile and coefficients (eqs. 15-17), the chained inputs ``v1``, ``v2`` sampled
at ``plant.control_rate`` (for a robot that steers closed-loop with eqs. 3-5 from its own state
estimate), and the robot's own inputs and configurations along the nominal model's path (for a
robot that can only replay inputs open-loop).

The controller's model is the nested ``plant.robot`` (a ``car``, a ``unicycle``, ...: its
*nominal* keys; its simulated-plant keys must equal them, for the program is the plant). Before a
trial leaves the library its nominal path is checked against ``plant.limits`` (top speed, steering
angle and rate, workspace): a trial beyond them is refused with a
:class:`~ilc_steering.errors.LimitError`, never clipped. What the program does wrong is a
:class:`~ilc_steering.errors.PlantError` naming it (:mod:`ilc_steering.core.cable`), and the trial
is not counted.
"""

from __future__ import annotations

import os
import shutil
import sys
import weakref
from collections.abc import Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from dataclasses import dataclass, field, replace
from math import isfinite
from pathlib import Path
from typing import Any, ClassVar, Literal

import numpy as np
import numpy.typing as npt

from ilc_steering.core.cable import Cable, describe
from ilc_steering.core.checks import require
from ilc_steering.core.external import ExternalPlantBase, ExternalTrials
from ilc_steering.core.grid import MAX_STEPS_PER_TRIAL
from ilc_steering.core.integrate import LEFT_CHART, OK
from ilc_steering.core.plants import PlantConfig, PlantKind
from ilc_steering.core.profiles import InputProfile
from ilc_steering.core.robots.car import rotate
from ilc_steering.core.robots.process_limits import (
    WRAPPED,
    ProcessLimits,
    brief,
    check_path,
    kept_log,
    number_list,
    reported_pose,
    reported_trajectory,
    steering_index,
)
from ilc_steering.core.robots.process_request import nominal_path, profile_message, sample
from ilc_steering.entries import CONFIG_FOLDERS

__all__ = ["PROTOCOL", "ProcessPlant", "ProcessPlantConfig", "without_program"]

Array = npt.NDArray[np.float64]

PROTOCOL = 1
"""The protocol's version, sent and expected in both ``hello`` messages."""
SUBSTEPS = 10
"""Integrator steps of the nominal path per control period, at each of which the limits are checked."""
RESULT_KEYS = frozenset({"type", "trial", "final", "trajectory", "log", "left_chart"})
"""The keys a ``result`` may hold."""


_PROGRAM_CHECKED: ContextVar[bool] = ContextVar("_PROGRAM_CHECKED", default=True)


@contextmanager
def without_program() -> Iterator[None]:
    """Configs loaded inside the block are not checked for their ``plant.command`` (a program on the
    ``PATH``, an executable file): for what runs none, a session or a run's record read back."""
    token = _PROGRAM_CHECKED.set(False)
    try:
        yield
    finally:
        _PROGRAM_CHECKED.reset(token)


class _Link:
    """The running program of a run, shared by the plant's copies (``with_frame``): started on the
    first trial, stopped when the last copy is gone (or at exit)."""

    def __init__(self) -> None:
        self.cables: list[Cable] = []
        self.sent = 0  # trial requests sent, each answered by a result (a failure ends the run)
        weakref.finalize(self, _stop, self.cables)


def _stop(cables: list[Cable]) -> None:
    for cable in cables:
        cable.close()


@dataclass(frozen=True)
class ProcessPlant(ExternalPlantBase):
    """The program of ``command`` as the true plant, the nested robot's nominal model as the
    controller's (see the module). Configurations are the robot's, in the task frame (the world
    rotated by ``frame`` [rad]); the program sees the world frame."""

    factor_names: ClassVar[tuple[str, str]] = ("none", "none")
    name: ClassVar[str] = "a process plant (another program)"
    command: tuple[str, ...]
    folder: str
    timeout: float
    control_rate: float
    limits: ProcessLimits
    chained_map: Any
    nominal: Any
    """The nominal robot's plant: its chart and steering limit check configurations."""
    kind: PlantKind  # the nested robot's kind, named process
    dimension: int
    frame: float = 0.0
    encoder_pulses: int = 0  # the controller's odometry (plant.robot's pulses a turn; 0: none), known to learners
    _link: _Link = field(default_factory=_Link, compare=False, repr=False)

    @property
    def state_dim(self) -> int:
        return self.dimension

    @property
    def steering_limit(self) -> float | None:
        limit: float | None = self.nominal.steering_limit
        return limit

    @property
    def trials_sent(self) -> int:
        """Trial requests sent to the program so far (each one a counted trial)."""
        return self._link.sent

    def with_frame(self, angle: float) -> ProcessPlant:
        return replace(self, frame=float(angle))  # the same program (its link), a subclass kept

    def check_configuration(self, q: Array) -> None:
        self.nominal.check_configuration(q)

    def to_world(self, q: Array) -> Array:
        return rotate(q, -self.frame) if self.frame else np.array(q, dtype=np.float64)

    def to_task(self, q: Array) -> Array:
        return rotate(q, self.frame) if self.frame else np.array(q, dtype=np.float64)

    @property
    def who(self) -> str:
        return describe(self.command)

    def run_trials(self, profile: InputProfile, x0: Array, c: Array, record: bool = False) -> ExternalTrials:
        """One request per trial, each checked against the limits before any is sent; one answer each."""
        first = self._link.sent + 1
        requests = [self.request(first + b, profile, x0[b], c[b], record) for b in range(c.shape[0])]
        cable = self._cable()
        outcomes = []
        for b, request in enumerate(requests):
            k = request["trial"]
            cable.send(request, f"trial {k}", self.timeout)
            self._link.sent = k
            outcomes.append(self._result(cable, k, cable.receive(self.timeout, f"trial {k}"), x0[b]))
        final = np.array([o[0] for o in outcomes])
        status = np.array([o[1] for o in outcomes], dtype=np.int64)
        logs = [o[3] for o in outcomes]
        if not record:
            return ExternalTrials(final, status, logs=logs)
        total = float(sum(profile.durations))
        paths = [o[2] for o in outcomes]
        if any(p is None for p in paths) or len({p[0].tobytes() for p in paths if p is not None}) > 1:
            # no trajectory (or trajectories of different samples): the start and the end
            times = np.array([0.0, total])
            states = np.stack([np.stack([x0[b], outcomes[b][0]]) for b in range(len(outcomes))])
        else:
            times = paths[0][0]  # type: ignore[index]
            states = np.stack([p[1] for p in paths])  # type: ignore[index]
        return ExternalTrials(final, status, times, states, logs=logs)

    def _cable(self) -> Cable:
        """The running program, started and greeted on the first trial."""
        if self._link.cables and not self._link.cables[0].closed:
            return self._link.cables[0]
        self._link.cables.clear()  # stopped at the end of a run (cable.owned): this is another run
        command = [sys.executable if self.command[0] == "python" else self.command[0], *self.command[1:]]
        cable = Cable(command, self.folder)
        cable.name = self.who
        self._link.cables.append(cable)
        hello = {"type": "hello", "protocol": PROTOCOL, "robot": self.chained_map.robot, "dimension": self.dimension}
        cable.send(hello, "the hello", self.timeout)
        answer = cable.receive(self.timeout, "the hello")
        greeted = answer.get("type") == "hello" and answer.get("protocol") == PROTOCOL
        if not greeted or not isinstance(answer.get("name"), str):
            wanted = f'{{"type": "hello", "protocol": {PROTOCOL}, "name": "..."}}'
            raise cable.fail(f"answered the hello with {brief(answer)}, not {wanted}")
        return cable

    def request(self, k: int, profile: InputProfile, x0: Array, c: Array, record: bool = False) -> dict[str, Any]:
        """Trial ``k``'s request from the start ``x0`` (task frame) with coefficients ``c``, checked
        against :attr:`limits` (a :class:`~ilc_steering.errors.LimitError` names the first limit
        passed, before anything is sent)."""
        total = float(sum(profile.durations))
        steps = max(1, round(total * self.control_rate))
        t = np.linspace(0.0, total, steps + 1)
        step = max(total / steps / SUBSTEPS, 2 * total / MAX_STEPS_PER_TRIAL)  # a long trial: the integrator's cap
        times, q, acted_on = nominal_path(self.nominal, profile, x0, c, step)
        check_path(self.limits, self.kind, times, self.to_world(q), f"trial {k}", self.who)
        v1, v2 = profile.evaluate(c, t)
        v1 = np.broadcast_to(np.asarray(v1, dtype=np.float64), t.shape)
        v2 = np.broadcast_to(np.asarray(v2, dtype=np.float64), t.shape)
        u1, u2 = (np.asarray(u, dtype=np.float64) for u in self.chained_map.inputs(sample(times, acted_on, t), v1, v2))
        return {
            "type": "trial",
            "trial": k,
            "start": self.to_world(x0).tolist(),
            "profile": profile_message(profile),
            "c": [float(v) for v in c],
            "control": {"dt": total / steps, "t": t.tolist(), "v1": v1.tolist(), "v2": v2.tolist()},
            "nominal": {"u1": u1.tolist(), "u2": u2.tolist(), "q": self.to_world(sample(times, q, t)).tolist()},
            "limits": self.limits.to_json(),
            "record": bool(record),
        }

    def _result(
        self, cable: Cable, k: int, answer: dict[str, Any], x0: Array
    ) -> tuple[Array, int, tuple[Array, Array] | None, dict[str, Any]]:
        """Trial ``k``'s answer checked: the final configuration (task frame), its status, the
        trajectory ``(t, q)`` (task frame) if sent, and the program's log."""
        kind = answer.get("type")
        if kind == "error":
            message = answer.get("message")
            cable.close()
            raise cable.fail(f"says trial {k} failed: {message if isinstance(message, str) else brief(answer)}")
        if kind != "result":
            raise cable.fail(f'answered trial {k} with {brief(answer)}, not a "result" or an "error"')
        if answer.get("trial") != k:
            raise cable.fail(
                f"answered trial {brief(answer.get('trial'))} to trial {k}'s request (a stale or wrong answer)"
            )
        unknown = sorted(set(answer) - RESULT_KEYS)
        if unknown:
            raise cable.fail(f"answered trial {k} with unknown keys {unknown}; a result has {sorted(RESULT_KEYS)}")
        n = self.dimension
        final = number_list(answer.get("final"), n)
        if final is None:
            raise cable.fail(
                f"answered trial {k} with final = {brief(answer.get('final'))}: it needs {n} finite numbers "
                f"({', '.join(self.kind.coordinates)}; world frame)"
            )
        log = answer.get("log", {})
        if not isinstance(log, dict):
            raise cable.fail(f"answered trial {k} with log = {brief(log)}: it needs a JSON object")
        left = answer.get("left_chart", False)
        if not isinstance(left, bool):
            raise cable.fail(f"answered trial {k} with left_chart = {brief(left)}: it needs true or false")
        q, out, wrapped = reported_pose(self.limits, self.kind, final, self.frame, f"trial {k}", cable.fail)
        log = {**kept_log(log), **({WRAPPED: wrapped} if wrapped else {})}  # the wrap stated with the trial
        status = LEFT_CHART if left or out else OK
        path = reported_trajectory(answer.get("trajectory"), self.dimension, f"trial {k}", cable.fail)
        return q, status, None if path is None else (path[0], self.to_task(path[1])), log


@dataclass(frozen=True)
class ProcessPlantConfig:
    model: Literal["process"]
    command: tuple[str, ...]  # the program and its arguments (argv); "python" is the library's own interpreter
    robot: PlantConfig  # the nominal robot: plant.model car, unicycle, ... with its nominal keys
    limits: ProcessLimits  # checked before a trial is sent: workspace [m], speed [m/s], steering [rad], rate [rad/s]
    timeout: float = 60.0  # [s] the longest wait for the program's answer to one trial (and to the hello)
    control_rate: float = 50.0  # [Hz] the samples of the inputs sent with a trial
    folder: str | None = None  # the program's working directory, relative to the config's; None: the config's folder

    plant_class: ClassVar[type[ProcessPlant]] = ProcessPlant

    def __post_init__(self) -> None:
        require(not isinstance(self.robot, ProcessPlantConfig), "robot", "must be a robot's config, not a process")
        require(self.robot.kind.has_pose, "robot", f"must be a robot with a pose (x, y, theta), got {self.robot.model}")
        nominal = self.nominal()  # with the controller's odometry, which is the controller's, not the plant's
        require(
            self.robot.plant() == (nominal.with_odometry(self.encoder_pulses) if self.encoder_pulses else nominal),
            "robot",
            "describes a simulated plant other than its nominal model (true_* keys, servo lags, backlash, ...): "
            "with a process plant the program is the plant; give the nominal values only (and encoder_pulses, "
            "the controller's odometry)",
        )
        require(
            isfinite(self.timeout) and 0 < self.timeout <= 86400,
            "timeout",
            f"must be in (0, 86400] s, got {self.timeout}",
        )
        require(
            isfinite(self.control_rate) and 0 < self.control_rate <= 10000,
            "control_rate",
            f"must be in (0, 10000] Hz, got {self.control_rate}",
        )
        if steering_index(self.robot.kind) is not None:
            require(
                self.limits.steering is not None and self.limits.steering_rate is not None,
                "limits",
                f"a {self.robot.model} steers: give limits.steering [rad] and limits.steering_rate [rad/s]",
            )
        folders = CONFIG_FOLDERS.get()  # a relative folder is the config's folder's, as the command is
        base = Path(folders[0] if folders else os.getcwd())
        object.__setattr__(self, "folder", os.path.realpath(base / (self.folder or ".")))
        if _PROGRAM_CHECKED.get():
            self._check_command()

    def _check_command(self) -> None:
        command = self.command
        require(
            len(command) >= 1 and all(command), "command", f"needs a program and its arguments, got {list(command)}"
        )
        program = command[0]
        if program == "python":
            return
        if os.sep in program or (os.altsep and os.altsep in program):
            path = Path(str(self.folder), program)
            require(
                path.is_file() and os.access(path, os.X_OK),
                "command",
                f"{program!r} is not an executable file (relative to {self.folder})",
            )
        else:
            require(shutil.which(program) is not None, "command", f"no program {program!r} on the PATH")

    @property
    def kind(self) -> PlantKind:
        """The nested robot's kind (its pose, coordinates and inputs), named ``process``."""
        return replace(self.robot.kind, name="process")

    @property
    def dimension(self) -> int:
        return self.robot.dimension

    @property
    def steering_limit(self) -> float | None:
        return self.robot.steering_limit

    def nominal_map(self) -> Any:
        return self.robot.nominal_map()

    @property
    def encoder_pulses(self) -> int:
        """The controller's odometry the nested robot states (0: none; a car's ``encoder_pulses``)."""
        return int(getattr(self.robot, "encoder_pulses", 0))

    def nominal(self) -> Any:
        """The plant the controller assumes: the nested robot with its nominal geometry."""
        robot: Any = self.robot
        return robot.plant_class.nominal_plant(robot.nominal_map(), robot.dimension, robot.steering_limit)

    def plant(self) -> ProcessPlant:
        """The program as the true plant (not started: it starts on the first trial)."""
        return ProcessPlant(
            self.command, str(self.folder), self.timeout, self.control_rate, self.limits, self.nominal_map(),
            self.nominal(), self.kind, self.robot.dimension, encoder_pulses=self.encoder_pulses,
        )  # fmt: skip

    def check_task(self, max_step: float, cyclic: bool) -> None:
        """One-trial tasks only (a cycle's trials would start where the robot stopped, which is for
        a later protocol); the nested robot's own rules."""
        require(not cyclic, "model", "process runs one-trial tasks (task.start, task.goal), not cycles")
        self.robot.check_task(max_step, cyclic)
