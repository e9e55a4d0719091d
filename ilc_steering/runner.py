"""Runs of the paper's learners on a config, as records for the CLI, JSON and figures.

Both runs go through the one trial loop, :func:`ilc_steering.loop.run_trials`. Before the first
trial, :func:`~ilc_steering.preflight.check_task` refuses a task that is ill-posed for its nominal
model and :func:`~ilc_steering.preflight.step_warning` says when the integrator's step is too coarse
for it (:mod:`ilc_steering.preflight`, re-exported here). When a run has
converged, and whether the plant's scatter allowed it to, is its verdict
(:mod:`ilc_steering.verdict`).
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import gymnasium as gym

from ilc_steering.agents.base import Learner, LearnerContext
from ilc_steering.agents.cyclic_ilc import CyclicILCAgent
from ilc_steering.agents.registry import LearnerSpec, lookup
from ilc_steering.config import SteeringConfig, config_data, load_config
from ilc_steering.core import scatter as scatter_
from ilc_steering.core.cable import owned
from ilc_steering.core.score import within_tolerance
from ilc_steering.core.trajectory import Trajectory
from ilc_steering.errors import ENDS_A_RUN, BadInput, keep_partial
from ilc_steering.loop import run_trials
from ilc_steering.preflight import MAX_STEP_MISS, check_task, step_warning
from ilc_steering.segmented import segmented_learner
from ilc_steering.trial_board import run_folder
from ilc_steering.verdict import Verdict, verdict, with_scatter

__all__ = [
    "DEFAULT_LEARNER",
    "MAX_STEP_MISS",
    "CycleRecord",
    "CyclicRunResult",
    "RunResult",
    "TrialRecord",
    "check_task",
    "learner_spec",
    "run_cyclic_ilc",
    "run_goals",
    "run_ilc",
    "step_warning",
]

ENV_ID = "ilc_steering/ChainedSteering-v0"
CYCLIC_ENV_ID = "ilc_steering/CyclicSteering-v0"
SEGMENTED_ENV_ID = "ilc_steering/SegmentedSteering-v0"
DEFAULT_LEARNER = "ilc_paper"
"""``run``'s learner: the paper's eqs. 33-34, its fictitious zero iteration first. Every id of
:data:`ilc_steering.agents.registry.REGISTRY` means the same in ``run``, ``compare`` and ``sweep``
(``ilc`` starts from the nominal solution in all three)."""


def learner_spec(name: str) -> LearnerSpec:
    """The registry's spec of ``run --learner name``: any id of
    :data:`~ilc_steering.agents.registry.REGISTRY`, or ``module:attr`` (a module in the working
    directory included); ``ValueError`` for anything else."""
    return lookup(name, "--learner")


@dataclass(frozen=True)
class TrialRecord:
    """One trial: its true errors (those of the true final configuration, the measured ones
    differing by the env's measurement noise), final configuration as measured (world frame),
    chained error as measured (what the learner used), action and, when recorded, its trajectory."""

    trial: int  # for a cyclic run: the index l of the waypoint reached (r is home)
    error_norm: float
    cartesian_error: float | None
    orientation_error: float | None
    final_state: list[float]
    error: list[float]
    action: list[float]
    left_chart: bool = False  # the trial stopped where eqs. 4-5 break down (see the env's Episode End)
    clipped: bool = False  # the env clipped the learner's action to its box (task.action_bound)
    trajectory: Trajectory | None = None
    plant: dict[str, Any] | None = None  # an external plant's log of the trial (highway-env: its actions, a crash)

    def to_json(self) -> dict[str, Any]:
        record = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}
        if self.trajectory is not None:
            record["trajectory"] = self.trajectory.to_json()
        return {k: v for k, v in record.items() if v is not None}


def _run_json(config: SteeringConfig, kind: str, records: list[Any], result: Verdict) -> dict[str, Any]:
    """A run as plain data: ``kind`` (``"trials"`` or ``"cycles"``) names the list of records,
    the verdict's fields come at the top level, and the config comes along whole (``load_config``
    builds it back; tested)."""
    return {
        "name": config.name,
        "kind": kind,
        kind: [r.to_json() for r in records],
        **result.to_json(),
        "config": config_data(config),
    }


class _Judged:
    """What a run and a cyclic run share: their config's name, and where their verdict says they converged."""

    config: SteeringConfig
    verdict: Verdict

    @property
    def name(self) -> str:
        return self.config.name

    @property
    def converged_at(self) -> int | None:
        """The first trial (or cycle) of the stretch within the tolerance the run ends with, if it held."""
        return self.verdict.converged_at


@dataclass(frozen=True)
class RunResult(_Judged):
    """A run of one-trial ILC: the JSON that ``ilc-steering run --json`` writes and ``plot`` reads."""

    config: SteeringConfig
    trials: list[TrialRecord]
    verdict: Verdict
    carried: dict[str, Any] | None = None  # what its learner handed on to the next goal (run_goals)
    started_from: dict[str, Any] | None = None  # what it was handed by the last goal's (context.carried)

    def to_json(self) -> dict[str, Any]:
        data = _run_json(self.config, "trials", self.trials, self.verdict)
        extra = {"started_from": self.started_from, "carried": self.carried}
        return {**data, **{k: v for k, v in extra.items() if v is not None}}


def _record(index: int, info: dict[str, Any]) -> TrialRecord:
    return TrialRecord(
        trajectory=info.get("trajectory"),
        trial=index,
        error_norm=info["true_error_norm"],
        cartesian_error=info.get("true_cartesian_error"),
        orientation_error=info.get("true_orientation_error"),
        final_state=info["q_final"].tolist(),
        error=info["error"].tolist(),
        action=info["action"].tolist(),
        left_chart=bool(info["left_chart"]),
        clipped=bool(info.get("clipped", False)),
        plant=info.get("plant"),
    )


def run_ilc(
    config: str | Path | SteeringConfig,
    trials: int | None = None,
    on_trial: Callable[[TrialRecord], None] | None = None,
    trajectories: bool = False,
    learner: str = DEFAULT_LEARNER,
    seed: int = 1,
    hold: int = scatter_.HOLD,
    carried: Mapping[str, Any] | None = None,
    transfer: bool = False,
    tensorboard: str | os.PathLike[str] | None = None,
) -> RunResult:
    """Run a learner (default: the paper's eqs. 33-34; any id of the registry or ``module:attr``,
    :func:`learner_spec`) for ``trials`` trials (default: the config's), with ``seed`` for the
    env's noise and the learner. It has converged when its last ``hold`` trials are within the
    tolerance (:class:`~ilc_steering.verdict.Verdict`).

    ``on_trial`` is called with each record as soon as the trial ends. ``trajectories`` keeps
    every trial's :class:`~ilc_steering.envs.trajectory.Trajectory` in its record (for plots).
    ``carried`` is what a learner of the same id learned of the same robot on an earlier goal
    (:attr:`~ilc_steering.agents.base.LearnerContext.carried`); with ``transfer`` the result keeps
    what this one hands on (:func:`run_goals` chains them). ``tensorboard``, a folder, gets the run's
    TensorBoard event files in ``<config name>/<learner>_seed<seed>`` under it
    (:func:`~ilc_steering.trial_board.run_folder`; an RL learner's own logs beside them).

    A learner that fails raises :class:`~ilc_steering.errors.LearnerError` naming it (``learner``),
    its ``partial`` the :class:`RunResult` of the trials run before (the trial it failed on
    included, if it ran); so do a plant that fails (:class:`~ilc_steering.errors.PlantError`),
    commands refused for the robot's limits (:class:`~ilc_steering.errors.LimitError`) and an
    interrupt (``KeyboardInterrupt``).
    """
    config = load_config(config)
    spec = learner_spec(learner)
    count = config.learning.trials if trials is None else trials
    board = None if tensorboard is None else run_folder(tensorboard, config.name, learner, seed)
    logs = None if board is None else str(board)
    agent: Learner
    if config.is_segmented:  # one learner per segment, each on its segment's one-trial view
        env = gym.make(SEGMENTED_ENV_ID, config=config, record_trajectory=trajectories)
        views = env.unwrapped.segment_views()  # type: ignore[attr-defined]
        for k, view in enumerate(views):
            check_task(view, f"{config.name} task.segments[{k}]")

        def make(context: LearnerContext) -> Learner:
            return spec.make(replace(context, carried=carried, tensorboard_log=logs), count)

        agent = segmented_learner(make, views, seed)
    else:
        env = gym.make(ENV_ID, config=config, record_trajectory=trajectories)
        check_task(env, config.name)
        agent = spec.make(LearnerContext.from_env(env, seed=seed, carried=carried, tensorboard_log=logs), count)
    started_from = None if carried is None else dict(carried)
    model = env.unwrapped.nominal_model  # type: ignore[attr-defined]

    def judged(met: list[bool]) -> Verdict:  # the scatter's bound is one segment's model's: not for a manoeuvre
        if config.is_segmented:
            return verdict(met, hold)
        return with_scatter(config, model, records, verdict(met, hold))

    records: list[TrialRecord] = []
    met: list[bool] = []

    def keep(k: int, info: dict[str, Any]) -> None:
        records.append(_record(k, info))
        met.append(within_tolerance(config.learning.tolerance, info))
        if on_trial is not None:
            on_trial(records[-1])

    try:
        with owned():  # a robot program this run starts is stopped when it ends, however it ends
            rollout = run_trials(
                env,
                agent,
                count,
                seed=seed,
                callbacks=[keep],
                name=learner,
                transfer=transfer,
                tensorboard=board,
                hold=hold,
            )
    except ENDS_A_RUN as error:  # the trials before it are kept
        keep_partial(error, RunResult(config, records, judged(met), started_from=started_from))
        raise
    finally:
        env.close()
    return RunResult(config, records, judged(met), rollout.carried, started_from)


def run_goals(
    configs: Sequence[str | Path | SteeringConfig],
    trials: int | None = None,
    learner: str = DEFAULT_LEARNER,
    seed: int = 1,
    hold: int = scatter_.HOLD,
    carry: bool = True,
    on_goal: Callable[[int, RunResult], None] | None = None,
    on_trial: Callable[[TrialRecord], None] | None = None,
    tensorboard: str | os.PathLike[str] | None = None,
) -> list[RunResult]:
    """One run of ``learner`` per goal (one-trial configs of one robot, in order), each its own budget
    and trial counter; with ``carry`` each learner starts from what the last one learned of the robot
    (:class:`~ilc_steering.agents.base.Transferable`). ``on_goal(k, result)`` follows goal ``k`` (from
    0). A failure raises as :func:`run_ilc`'s, its ``partial`` the list so far. ``tensorboard``: as
    :func:`run_ilc`'s, each goal under its config's name."""
    goals = [load_config(config) for config in configs]
    other = next((k for k, goal in enumerate(goals) if carry and goal.plant != goals[0].plant), None)
    if not goals or other is not None:
        where = f"goal {other + 1} ({goals[other].name}) has another plant than goal 1" if other else "no goal"
        raise BadInput(f"run_goals: {where}: learning is carried between goals of one robot")
    results: list[RunResult] = []
    carried: dict[str, Any] | None = None
    for k, config in enumerate(goals):
        try:
            result = run_ilc(
                config,
                trials,
                on_trial,
                False,
                learner,
                seed,
                hold,
                carried if carry else None,
                transfer=carry,
                tensorboard=tensorboard,
            )
        except ENDS_A_RUN as error:
            last = getattr(error, "partial", None)
            keep_partial(error, [*results, last] if last is not None else results)
            raise
        results.append(result)
        carried = result.carried
        if on_goal is not None:
            on_goal(k, result)
    return results


@dataclass(frozen=True)
class CycleRecord:
    """One cycle: a record per waypoint reached, in order (``trial`` holds the waypoint index)."""

    cycle: int
    waypoints: list[TrialRecord]

    def to_json(self) -> dict[str, Any]:
        rows = [{"index": w.trial, **{k: v for k, v in w.to_json().items() if k != "trial"}} for w in self.waypoints]
        return {"cycle": self.cycle, "waypoints": rows}


@dataclass(frozen=True)
class CyclicRunResult(_Judged):
    """A run of cyclic ILC, with the same JSON conventions as :class:`RunResult`."""

    config: SteeringConfig
    cycles: list[CycleRecord]
    verdict: Verdict

    def to_json(self) -> dict[str, Any]:
        return _run_json(self.config, "cycles", self.cycles, self.verdict)


def run_cyclic_ilc(
    config: str | Path | SteeringConfig,
    cycles: int | None = None,
    on_cycle: Callable[[CycleRecord], None] | None = None,
    start: list[float] | None = None,
    trajectories: bool = False,
    hold: int = scatter_.HOLD,
    tensorboard: str | os.PathLike[str] | None = None,
) -> CyclicRunResult:
    """Run the cyclic ILC agent (eqs. 39-40) for ``cycles`` cycles (default: ``learning.trials``),
    never resetting the robot; ``start`` puts it off home at the beginning. ``trajectories``
    keeps every segment's trajectory in its record.

    A cycle met the tolerance when every waypoint met it in that cycle; the run has converged
    when its last ``hold`` cycles met it (:class:`~ilc_steering.verdict.Verdict`). A run that
    fails or is interrupted raises as :func:`run_ilc`'s, its ``partial`` the cycles completed.
    ``tensorboard``: as :func:`run_ilc`'s, one point per segment (the loop's trial).
    """
    config = load_config(config)
    env = gym.make(CYCLIC_ENV_ID, config=config, cycles=cycles, record_trajectory=trajectories)
    models = env.unwrapped.nominal_models  # type: ignore[attr-defined]
    agent = CyclicILCAgent(models, config.learning.nu_a, config.learning.nu_b)
    records: list[CycleRecord] = []
    cycles_met: list[bool] = []
    waypoints: list[TrialRecord] = []
    met: list[bool] = []

    def keep(k: int, info: dict[str, Any]) -> None:
        waypoints.append(_record(info["waypoint"], info))
        met.append(within_tolerance(config.learning.tolerance, info))
        if info["waypoint"] < len(models):
            return
        record = CycleRecord(info["cycle"], list(waypoints))
        records.append(record)
        if on_cycle is not None:
            on_cycle(record)
        cycles_met.append(all(met))
        waypoints.clear()
        met.clear()

    steps = (config.learning.trials if cycles is None else cycles) * len(models)
    try:
        board = None if tensorboard is None else run_folder(tensorboard, config.name, DEFAULT_LEARNER, 0)
        options = None if start is None else {"start": start}
        run_trials(env, agent, steps, seed=0, options=options, callbacks=[keep], tensorboard=board, hold=hold)
    except ENDS_A_RUN as error:  # the cycles before it are kept
        keep_partial(error, CyclicRunResult(config, records, verdict(cycles_met, hold)))
        raise
    finally:
        env.close()
    return CyclicRunResult(config, records, verdict(cycles_met, hold))
