"""The trial loop: a learner on an env for a budget of trials. The only copy in the library,
in two forms: :func:`run_trials` (one env) and :func:`run_vector_trials` (a learner per env of a
vector env, all stepped together: a sweep's row).

The runner, the comparison, the benchmarks and the tests all call :func:`run_trials`. Each step
of the env is one trial (for the cyclic env, one segment); every trial the learner asks for is
run, counted and recorded, and nothing past the budget is.

What a learner raises, in ``act``, ``learn`` or ``close`` (``sys.exit()`` and any other
``BaseException`` but an interrupt, :data:`~ilc_steering.errors.INTERRUPTS`), and an action the env
refuses (a NaN, the wrong shape) is a :class:`LearnerError` naming the learner and the trial: the
learner's fault, not bad input to the library (exit 2) nor a bug of it (exit 3).

A trial is recorded (the rollout, the callbacks and, where asked, TensorBoard's event files:
:mod:`~ilc_steering.trial_board`) as soon as the env has run it, before the learner learns from it:
a learner that fails in ``learn`` loses no trial that ran.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import gymnasium as gym
import numpy as np

from ilc_steering.agents.base import Closable, Learner, transferred
from ilc_steering.core.scatter import HOLD
from ilc_steering.core.score import TRUE_KEYS
from ilc_steering.errors import INTERRUPTS, BadInput, ConfigError, LearnerError, LimitError, described
from ilc_steering.trial_board import TrialBoard

__all__ = ["Rollout", "TrialCallback", "VectorCallback", "run_trials", "run_vector_trials"]


def _fault(name: str, what: str, trial: int, error: BaseException) -> LearnerError:
    return LearnerError(f"learner {name}: {what} in trial {trial}: {described(error, 2000)}")


TrialCallback = Callable[[int, dict[str, Any]], bool | None]
"""Called after trial ``k`` (from 1) with its ``info``, before the learner learns from it;
returning ``True`` stops the loop (after the learner has learned from that trial)."""


@dataclass
class Rollout:
    """The per-trial record of a loop: each trial's ``info`` and reward, in order."""

    infos: list[dict[str, Any]] = field(default_factory=list)
    rewards: list[float] = field(default_factory=list)
    stopped: bool = False
    """A callback stopped the loop before the budget was spent."""
    carried: dict[str, Any] | None = None
    """What the learner handed to the next goal (``run_trials(..., transfer=True)``)."""

    def __len__(self) -> int:
        return len(self.infos)


def run_trials(
    env: gym.Env[Any, Any],
    learner: Learner,
    trials: int,
    *,
    seed: int | None = None,
    options: dict[str, Any] | None = None,
    callbacks: Sequence[TrialCallback] = (),
    name: str | None = None,
    transfer: bool = False,
    tensorboard: str | os.PathLike[str] | None = None,
    hold: int = HOLD,
) -> Rollout:
    """Run ``learner`` on ``env`` for at most ``trials`` trials: act, step, learn, and reset when the
    episode ends (every trial for the one-trial env; at truncation for the cyclic env).

    The learner gets each trial's ``info`` without the true errors (``core.score.TRUE_KEYS``):
    it learns from measurements only. The rollout and the callbacks get the whole ``info``.

    ``seed`` and ``options`` go to the first ``reset``. A learner with a ``close()`` method
    (:class:`~ilc_steering.agents.base.Closable`: the adapters of pull-style optimizers) is
    closed when the loop ends, however it ends.

    ``name`` names the learner in a :class:`LearnerError` (default: its class). With ``transfer``,
    the rollout keeps what the learner hands to the next goal
    (:func:`~ilc_steering.agents.base.transferred`), asked after the last trial, before ``close()``.

    ``tensorboard``, a folder, gets TensorBoard's event files of the run
    (:class:`~ilc_steering.trial_board.TrialBoard`, the ``tensorboard`` extra; checked before the
    first trial): one point per trial of every tag of :data:`~ilc_steering.trial_board.TAGS` the
    env reports, the trial's number as the step; ``trial/converged`` holds when the last ``hold``
    trials (a cyclic env: cycles) were within the config's tolerance.
    """
    if isinstance(trials, bool) or not isinstance(trials, int) or trials < 1:
        raise BadInput(f"trials must be an integer >= 1, got {trials!r}")
    rollout = Rollout()
    who = name or type(learner).__name__
    board = None if tensorboard is None else TrialBoard.of_env(tensorboard, env, hold)
    failed = True
    try:
        observation, _ = env.reset(seed=seed, options=options)
        for k in range(1, trials + 1):
            try:
                action = learner.act(observation)
            except INTERRUPTS:
                raise
            except BaseException as error:  # a learner's sys.exit() is its failure, not success
                raise _fault(who, "act() raised", k, error) from error
            try:
                observation, reward, terminated, truncated, info = env.step(action)
            except (LimitError, ConfigError):  # beyond the robot's limits, or a config the plant cannot run: exit 2
                raise
            except ValueError as error:  # the env checks the action: a NaN, a wrong shape
                raise _fault(who, "the env refused its action", k, error) from error
            rollout.infos.append(info)  # the trial ran: kept, whatever the learner does next
            rollout.rewards.append(float(reward))
            if board is not None:
                board.write(k, info, float(reward))
            stop = any([bool(callback(k, info)) for callback in callbacks])
            try:
                learner.learn({key: value for key, value in info.items() if key not in TRUE_KEYS})
            except INTERRUPTS:
                raise
            except BaseException as error:  # a learner's sys.exit() is its failure, not success
                raise _fault(who, "learn() raised", k, error) from error
            if stop:
                rollout.stopped = k < trials
                break
            if k < trials and (terminated or truncated):
                observation, _ = env.reset()
        if transfer:
            try:
                rollout.carried = transferred(learner)
            except INTERRUPTS:
                raise
            except BaseException as error:
                raise _fault(who, "transfer() raised", len(rollout), error) from error
        failed = False
    finally:
        if board is not None:
            board.close()
        if isinstance(learner, Closable):
            try:
                learner.close()
            except INTERRUPTS:
                raise
            except BaseException as error:
                if not failed:  # else the error that ended the loop is the one to report
                    raise _fault(who, "close() raised", len(rollout), error) from error
    return rollout


VectorCallback = Callable[[int, list[dict[str, Any]]], bool | None]
"""Called after trial ``k`` (from 1) with each env's ``info``; returning ``True`` stops the loop."""


def run_vector_trials(
    envs: Any,
    learners: Sequence[Learner],
    trials: int,
    *,
    seed: int | None = None,
    callbacks: Sequence[VectorCallback] = (),
    name: str | None = None,
) -> int:
    """:func:`run_trials` on a vector env of one-trial envs: ``learners[i]`` drives env ``i``,
    every learner one trial per step, for at most ``trials`` steps; returns the steps run.

    Each learner gets its own env's ``info`` without the true errors, as from :func:`run_trials`;
    the callbacks get every env's whole ``info``. What a learner raises is a :class:`LearnerError`
    naming it (``name``) and the trial; every learner is closed when the loop ends."""
    if isinstance(trials, bool) or not isinstance(trials, int) or trials < 1:
        raise BadInput(f"trials must be an integer >= 1, got {trials!r}")
    if len(learners) != envs.num_envs:
        raise BadInput(f"one learner per env is needed ({envs.num_envs}), got {len(learners)}")
    who = name or (type(learners[0]).__name__ if learners else "learner")
    observations, _ = envs.reset(seed=seed)
    run = 0
    try:
        for k in range(1, trials + 1):
            run = k
            try:
                actions = np.array([learner.act(obs) for learner, obs in zip(learners, observations)])
            except INTERRUPTS:
                raise
            except BaseException as error:  # a learner's sys.exit() is its failure, not success
                raise _fault(who, "act() raised", k, error) from error
            try:
                observations, _, _, _, info = envs.step(actions)
            except ValueError as error:
                raise _fault(who, "the env refused its action", k, error) from error
            final = info["final_info"]
            keys = [key for key in final if not key.startswith("_")]
            rows = [{key: final[key][i] for key in keys} for i in range(len(learners))]
            for learner, row in zip(learners, rows):
                try:
                    learner.learn({key: value for key, value in row.items() if key not in TRUE_KEYS})
                except INTERRUPTS:
                    raise
                except BaseException as error:
                    raise _fault(who, "learn() raised", k, error) from error
            if any([bool(callback(k, rows)) for callback in callbacks]):
                break
    finally:
        for learner in learners:
            if isinstance(learner, Closable):
                learner.close()
    return run
