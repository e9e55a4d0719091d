"""A session a script can drive: :func:`new`, :func:`next`, :func:`record`, :func:`status` and
:func:`withdraw` on a session folder, each returning a dataclass (``ilc-steering session`` prints them).

A session is section 5 of the paper with a person, or a lab's own script, at the robot: ``new``
starts it from a process-plant config, ``next`` writes the pending trial's commands
(``trials/NNNN/commands.csv`` and ``request.json``), the robot runs them, ``record`` stores where it
stopped and learns from it, ``status`` tells where the learning is (its :class:`State`, and the exit
code ``session status`` gives for it, as ``run``'s), ``withdraw`` takes back the last recorded trial.
Each call holds the session's lock as the command does and leaves the folder whole; bad input raises
:class:`~ilc_steering.errors.BadInput` (commands beyond the robot's limits: its subclass
:class:`~ilc_steering.errors.LimitError`), a learner that fails on the recorded trials
:class:`~ilc_steering.errors.LearnerError`. The folder itself is :mod:`ilc_steering.session_folder`.

Example: section 5's simulated MARIO (:class:`~ilc_steering.lab_robot.LabRobot`) stands in for the
robot and for the person measuring where it stopped (the packaged config adds the library's
simulated measurement noise to each recorded pose, from the session's seed):

>>> import tempfile
>>> from pathlib import Path
>>> from ilc_steering import session
>>> from ilc_steering.config import load_config
>>> from ilc_steering.lab_robot import LabRobot
>>> folder = Path(tempfile.mkdtemp()) / "mario"
>>> started = session.new(folder, "experiment_forward_process", trials=10)
>>> robot = LabRobot(load_config("experiment_forward"))
>>> state = session.status(folder)
>>> while state.state is session.State.PENDING:
...     trial = session.next(folder)  # writes trial k's commands.csv and request.json
...     final = robot.trial(trial.request)["final"]  # the robot runs them; where it stopped [m, rad]
...     state = session.record(folder, final)
>>> state.state.value, state.converged_at, state.exit_code, len(state.trials)
('converged', 4, 0, 6)
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass
from enum import Enum
from pathlib import Path
from typing import Any

import numpy as np

from ilc_steering.core.robots.chart import rotate
from ilc_steering.core.score import trial_cost
from ilc_steering.errors import BadInput, LimitError
from ilc_steering.pose_files import final_pose
from ilc_steering.runner import RunResult, TrialRecord
from ilc_steering.session_folder import Replay, Session
from ilc_steering.trial_board import TrialBoard, check_tensorboard, run_folder
from ilc_steering.verdict import Verdict

__all__ = [
    "EXIT_CODES",
    "NextTrial",
    "Session",
    "Started",
    "State",
    "Status",
    "Withdrawn",
    "new",
    "next",
    "record",
    "status",
    "withdraw",
]

Folder = str | os.PathLike[str]


class State(str, Enum):
    """Where a session's learning is, from its recorded trials (:attr:`Status.state`)."""

    CONVERGED = "converged"
    """The last ``hold`` (3) recorded trials are within the tolerance: exit 0, as ``run``'s."""
    FLOOR = "floor"
    """Converged to the robot's floor: the tolerance is below the robot's repeatability (estimated from
    the trials) and the last trials are within that: exit 5, as ``run``'s."""
    PENDING = "pending"
    """Not converged yet, and a trial is left to run (:attr:`Status.pending`): exit 1."""
    SPENT = "spent"
    """Not converged within the session's budget of trials, and none left: exit 1, as ``run``'s."""
    REFUSED = "refused"
    """Not converged, and the pending trial's commands are beyond the robot's ``plant.limits``
    (:attr:`Status.refusal` says which, and from which recorded pose): exit 2, as ``run``'s."""


EXIT_CODES = {
    State.CONVERGED: 0,
    State.FLOOR: 5,
    State.PENDING: 1,
    State.SPENT: 1,
    State.REFUSED: 2,
}
"""The exit code ``ilc-steering session status`` gives for each :class:`State` (the codes of ``run``)."""


@dataclass(frozen=True)
class Started:
    """What :func:`new` made."""

    folder: Path
    learner: str
    seed: int
    trials: int
    """The session's budget of trials."""


@dataclass(frozen=True)
class NextTrial:
    """The pending trial whose commands :func:`next` wrote (or, on a dry run, would write)."""

    trial: int
    """Its number, from 1."""
    folder: Path
    """``trials/NNNN/``: its ``commands.csv`` (the samples as columns) and ``request.json``."""
    request: dict[str, Any]
    """The process plant's request (docs/your_robot.md's protocol): ``control`` (the chained inputs
    ``v1, v2`` sampled every ``dt`` [s]), ``nominal`` (the robot's inputs ``u1, u2`` and its nominal
    path, world frame), ``start``, ``limits``."""
    restored: tuple[str, ...] = ()
    """Its files written again because they were not its request's (cut short, deleted, edited)."""
    written: bool = True
    """False on a dry run: nothing was written."""

    @property
    def commands(self) -> Path:
        return self.folder / "commands.csv"


@dataclass(frozen=True)
class Status:
    """A session's recorded trials and what they say (:func:`status`, :func:`record`)."""

    folder: Path
    learner: str
    seed: int
    budget: int
    """The session's trials in all."""
    result: RunResult
    """The recorded trials as ``run`` judges them: ``status --json`` writes it, ``plot`` reads it."""
    pending: int | None
    """The next trial to run, or None when the budget is spent."""
    refusal: str | None = None
    """Why the pending trial cannot be sent (its commands beyond the robot's limits), in one line."""

    @property
    def trials(self) -> list[TrialRecord]:
        """The recorded trials, in order (their true errors are the measured ones)."""
        return self.result.trials

    @property
    def verdict(self) -> Verdict:
        return self.result.verdict

    @property
    def converged_at(self) -> int | None:
        """The first trial of the stretch within the tolerance the session ends with, if it holds."""
        return self.result.verdict.converged_at

    @property
    def state(self) -> State:
        """Converged (or at the floor) first: a verdict on the trials recorded, whatever is pending."""
        if self.converged_at is not None:
            return State.CONVERGED
        if self.result.verdict.floor:
            return State.FLOOR
        if self.refusal is not None:
            return State.REFUSED
        return State.SPENT if self.pending is None else State.PENDING

    @property
    def exit_code(self) -> int:
        """The exit code of ``ilc-steering session status`` (:data:`EXIT_CODES`)."""
        return EXIT_CODES[self.state]


@dataclass(frozen=True)
class Withdrawn:
    """What :func:`withdraw` took back."""

    folder: Path
    trial: int
    """The trial whose result moved to ``withdrawn/``: it is asked again, uncounted."""


def new(
    folder: Folder, config: str | Path, learner: str = "ilc_paper", seed: int = 1, trials: int | None = None
) -> Started:
    """Start a session in ``folder`` (new, or an empty folder) from a process-plant ``config`` (a path
    or a packaged config's name; its text becomes the session's ``config.yaml``), with ``learner`` (an
    id of the registry or ``module:attr``) and ``seed``; ``trials``: the budget (default: the config's
    ``learning.trials``). Everything is checked first, and the folder made whole or not at all."""
    session = Session.new(Path(folder), config, learner, seed, trials)
    return Started(session.folder, session.learner, session.seed, session.trials)


def next(folder: Folder, dry_run: bool = False) -> NextTrial | None:
    """Write the pending trial's ``commands.csv`` and ``request.json`` (again, where they are not its
    request's) and return it; None when the session has run its trials. ``dry_run``: write nothing.
    A trial whose commands are beyond the robot's limits raises
    :class:`~ilc_steering.errors.LimitError` (naming the recorded pose it was learned from)."""
    session = Session(Path(folder))
    with session.locked(write=not dry_run):
        replay = session.replay(write=not dry_run)
    refused = _refusal(session, replay)
    if refused is not None:
        raise refused
    if replay.pending is None or replay.pending_folder is None or replay.request is None:
        return None
    return NextTrial(replay.pending, replay.pending_folder, replay.request, tuple(replay.restored), not dry_run)


def record(
    folder: Folder,
    final: Sequence[float] | None = None,
    *,
    pose_file: str | Path | None = None,
    topic: str | None = None,
) -> Status:
    """Store where the robot stopped after the pending trial and learn from it: ``final`` (``x, y,
    theta[, phi]`` [m, rad], world frame; without ``phi``, the commanded steering angle at the end)
    or the last pose of ``pose_file`` (a CSV, or a ROS bag's ``topic``). Returns the status after
    it. A pose refused, or a learner that fails on it, leaves the folder as it was."""
    if (final is None) == (pose_file is None):
        raise BadInput("record: give the final pose or a pose file, one of them")
    if topic is not None and pose_file is None:
        raise BadInput("--topic: names a topic of --pose-file's bag; give --pose-file")
    session = Session(Path(folder))
    if pose_file is not None:
        final = final_pose(Path(pose_file), topic, session.config.plant.kind)
    assert final is not None
    with session.locked():
        return _status(session, session.record(final))


def status(folder: Folder, trajectories: bool = False, tensorboard: Folder | None = None) -> Status:
    """The session's recorded trials, their verdict and what is pending; writes nothing to the
    session. ``trajectories``: keep each trial's path (its start and end) for a run record's
    figures. ``tensorboard``: write the recorded trials there as TensorBoard events (:func:`board`)."""
    session = Session(Path(folder))
    if tensorboard is not None:
        if Path(tensorboard).resolve().is_relative_to(session.folder.resolve()):
            raise BadInput(
                f"--tensorboard {tensorboard}: inside the session {session.folder}; give a folder outside it"
            )
        check_tensorboard(Path(tensorboard))
    with session.locked(write=False):
        state = _status(session, session.replay(write=False, paths=trajectories))
    if tensorboard is not None:
        board(state, session, tensorboard)
    return state


def board(state: Status, session: Session, root: Folder) -> Path:
    """Write a session's recorded trials as TensorBoard events under ``root``, in the folder ``run
    --tensorboard`` gives a run (``<config>/<learner>_seed<seed>``, its earlier events replaced): a
    point per trial and tag, the tags of every learner's run, the measured errors standing for the
    true ones (a session knows no other). Returns the folder."""
    config = session.config
    writer = TrialBoard(run_folder(root, config.name, state.learner, state.seed), config.learning.tolerance)
    try:
        for record in state.trials:
            errors = {"error_norm": record.error_norm}
            errors.update(
                {
                    k: v
                    for k, v in (
                        ("cartesian_error", record.cartesian_error),
                        ("orientation_error", record.orientation_error),
                    )
                    if v is not None
                }
            )
            info = {**errors, **{f"true_{k}": v for k, v in errors.items()}, "left_chart": record.left_chart}
            writer.write(record.trial, info, -float(trial_cost(info)))
    finally:
        writer.close()
    return writer.folder


def withdraw(folder: Folder) -> Withdrawn:
    """Move the last recorded result to ``withdrawn/`` (the robot slipped, a pose typed wrong): that
    trial is asked again, uncounted, and the next trial's commands, learned from it, go with it."""
    session = Session(Path(folder))
    with session.locked():
        return Withdrawn(session.folder, session.withdraw())


def _status(session: Session, replay: Replay) -> Status:
    refused = _refusal(session, replay)
    refusal = None if refused is None else " ".join(str(refused).split())
    return Status(session.folder, session.learner, session.seed, session.trials, replay.result, replay.pending, refusal)


def _refusal(session: Session, replay: Replay) -> LimitError | None:
    """The pending trial's refusal for the robot's limits, naming the recorded pose it was learned
    from and the way back (``withdraw``): a pose typed wrong is the likeliest cause of a step too large."""
    if replay.refused is None or not replay.result.trials:
        return replay.refused  # none, or trial 1's: the config's task and limits, no pose yet
    last, kind = replay.result.trials[-1], session.config.plant.kind
    frame = session.config.frame() if kind.has_pose else 0.0
    pose = np.asarray(last.final_state, dtype=np.float64)
    world = (rotate(pose, -frame) if frame else pose)[: 3 if kind.has_pose else None]  # x, y, θ: a pose
    names = ", ".join(label.split()[0] for label in kind.coordinates[: len(world)])
    off = "" if last.cartesian_error is None else f", {last.cartesian_error:.3g} m"
    off += "" if last.orientation_error is None else f" and {last.orientation_error:.3g} rad"
    return LimitError(
        f"{replay.refused}; the learner asks this of trial {last.trial}'s recorded pose ({names}) = "
        f"({', '.join(f'{v:.4g}' for v in world)}) (world frame){off} from the goal: if the robot did not "
        "stop there (a pose typed or measured wrong, the robot disturbed), take it back with "
        f"`ilc-steering session withdraw {session.folder}` and record the trial again"
    )
