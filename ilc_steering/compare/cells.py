"""A comparison's cells: one learner's run on one scenario, what it reached, and its file.

A cell is one (prior, method, scenario, seed): :func:`run_cell` builds the method's learner
through the registry (:mod:`~ilc_steering.agents.registry`) from
:meth:`~ilc_steering.agents.base.LearnerContext.from_env`, runs it for its budget by the one trial
loop (:func:`~ilc_steering.loop.run_trials`) and :func:`measure` records what it reached from the
*true* errors (:class:`TrialLog`). :func:`read_cell` is the resume checker: a cell read back is
checked against its key and value by value before it is trusted.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import gymnasium as gym
import numpy as np
from pydantic import Field

from ilc_steering.agents import registry
from ilc_steering.agents.base import Learner, LearnerContext, update_times
from ilc_steering.agents.registry import Budgets
from ilc_steering.compare.stats import LADDER
from ilc_steering.core.score import true_cost
from ilc_steering.errors import BadInput
from ilc_steering.loop import run_trials
from ilc_steering.output import MAX_RESULT_BYTES, injective_name
from ilc_steering.readers import read_json
from ilc_steering.schema import MethodName, Name, check_record
from ilc_steering.trial_board import run_folder

if TYPE_CHECKING:
    from ilc_steering.compare.args import Args

__all__ = [
    "ENV_ID",
    "FRAGILE",
    "MAX_REPORT_BYTES",
    "CellRecord",
    "CompareReport",
    "TrialLog",
    "best_so_far",
    "budget",
    "budgets",
    "cell_name",
    "cell_path",
    "cell_roots",
    "check_cell",
    "first_within",
    "fragile_levels",
    "implementation",
    "make_learner",
    "measure",
    "read_cell",
    "read_report",
    "run_cell",
]

ENV_ID = "ilc_steering/ChainedSteering-v0"
CONFIGS = "ilc_steering.configs"
"""The package of the packaged configs, which the config loader reads by name (a root of every cell)."""

FRAGILE = 1e-6
"""A count is fragile when scaling every error by ``1 - FRAGILE`` or ``1 + FRAGILE`` would move it."""


class TrialLog:
    """A trial-loop callback that keeps every trial's *true* errors: Cartesian [m] and orientation
    [rad] for a robot with a pose, the chained error norm for a chained plant (``cartesian`` holds
    it then, ``orientation`` zeros), the true cost (:func:`~ilc_steering.core.score.true_cost`,
    the off-chart penalty included), whether it left the chart and whether the env clipped its action."""

    def __init__(self) -> None:
        self.cartesian: list[float] = []
        self.orientation: list[float] = []
        self.cost: list[float] = []
        self.left_chart: list[bool] = []
        self.clipped: list[bool] = []

    def __call__(self, k: int, info: dict[str, Any]) -> None:
        self.cartesian.append(float(info.get("true_cartesian_error", info["true_error_norm"])))
        self.orientation.append(float(info.get("true_orientation_error", 0.0)))
        self.cost.append(float(true_cost(info)))
        self.left_chart.append(bool(info["left_chart"]))
        self.clipped.append(bool(info.get("clipped", False)))


def first_within(log: TrialLog, tolerance: float, scale: float = 1.0) -> int | None:
    """The 1-based index of the first trial that stayed in the chart with both errors (each times
    ``scale``) at most ``tolerance`` (a chained plant: its error norm), or None."""
    ok = (scale * np.asarray(log.cartesian) <= tolerance) & (scale * np.asarray(log.orientation) <= tolerance)
    hits = np.flatnonzero(ok & ~np.asarray(log.left_chart, dtype=bool))
    return int(hits[0]) + 1 if hits.size else None


def fragile_levels(log: TrialLog) -> list[str]:
    """The levels of :data:`LADDER` whose count a relative change of :data:`FRAGILE` in every
    error would move: the paper's law cuts the error exactly tenfold a trial, so an error can
    land *on* 1 cm, where the integrator's last digits, not the learner, decide the count."""
    return [
        level
        for level, tolerance in LADDER.items()
        if len({first_within(log, tolerance, 1.0 + sign * FRAGILE) for sign in (-1.0, 0.0, 1.0)}) > 1
    ]


def best_so_far(log: TrialLog) -> list[list[float]]:
    """``[trial, best true cost]`` at every trial that improved it."""
    best = np.minimum.accumulate(np.asarray(log.cost))
    changed = np.flatnonzero(np.concatenate([[True], best[1:] < best[:-1]]))
    return [[int(i) + 1, float(best[i])] for i in changed]


def budgets(args: Args) -> Budgets:
    """The budgets of ``args``, one per family."""
    return Budgets(args.model_trials, args.blackbox_trials, args.rl_trials, args.custom_trials)


def budget(args: Args, prior: str, method: str, scenario: str) -> int:
    """The budget of ``method`` on the config named ``scenario`` [trials] (the registry's rule)."""
    return registry.lookup(method).budget(budgets(args), scenario, prior)


def implementation(method: str) -> str:
    """What made a cell of ``method`` (:meth:`~ilc_steering.agents.registry.LearnerSpec.implementation`)."""
    return registry.lookup(method).implementation()


def make_learner(args: Args, method: str, scenario: str, context: LearnerContext) -> Learner:
    """The learner of ``method`` for ``context`` with its budget under ``args``, through the registry."""
    spec = registry.lookup(method)
    return spec.make(context, spec.budget(budgets(args), context.task or scenario, context.prior))


def measure(
    env: gym.Env[Any, Any],
    learner: Learner,
    trials: int,
    seed: int,
    name: str | None = None,
    tensorboard: Path | None = None,
) -> dict[str, Any]:
    """Run ``learner`` (``name`` for errors) on ``env`` for ``trials`` trials and return what it
    reached: the trials to each tolerance of :data:`LADDER` and which of them are fragile
    (:func:`fragile_levels`), the best true cost, the off-chart fraction, the wall time [s] and
    the best-so-far curve. ``tensorboard``, a folder, gets the run's TensorBoard event files
    (:class:`~ilc_steering.trial_board.TrialBoard`); what it reached is the same without."""
    log = TrialLog()
    start = time.perf_counter()
    run_trials(env, learner, trials, seed=seed, callbacks=[log], name=name, tensorboard=tensorboard)
    wall = time.perf_counter() - start
    curve = best_so_far(log)
    # A learner that times its own updates (TimedUpdates: the model-based ones) reports the median.
    updates = update_times(learner)
    update_s = float(np.median(updates)) if updates else None
    return {
        "update_s": update_s,
        "trials": len(log.cost),
        "off_chart_fraction": float(np.mean(log.left_chart)),
        "clipped_fraction": float(np.mean(log.clipped)),
        "trials_to": {level: first_within(log, tolerance) for level, tolerance in LADDER.items()},
        "fragile": fragile_levels(log),
        "best_error": curve[-1][1],
        "wall_s": wall,
        "curve": curve,
    }


def run_cell(
    args: Args, prior: str, method: str, scenario: str, seed: int, trials: int | None = None
) -> dict[str, Any]:
    """One (prior, method, scenario, seed) cell: the method's run within its budget (``trials``, or
    the registry's rule under ``args``), and what it reached; with ``args.tensorboard``, its
    TensorBoard event files in its own folder there (:func:`~ilc_steering.trial_board.run_folder`),
    which its result does not record."""
    spec = registry.lookup(method)
    if spec.family == "RL":
        import torch

        torch.set_num_threads(1)  # as in the worker processes: serial and parallel runs agree
    env = gym.make(ENV_ID, config=scenario)
    name = env.unwrapped.config.name  # type: ignore[attr-defined]
    board = None if args.tensorboard is None else run_folder(args.tensorboard, name, method, seed, prior)
    logs = None if board is None else str(board)
    context = LearnerContext.from_env(env, seed=seed, prior=prior, progress_bar=args.progress_bar, tensorboard_log=logs)
    if trials is None:
        trials = spec.budget(budgets(args), context.task, prior)
    learner = spec.make(context, trials)
    result = measure(env, learner, trials, seed, method, board)
    result["implementation"] = spec.implementation()
    env.close()
    return {"prior": prior, "method": method, "scenario": context.task, "seed": seed, "budget": trials, **result}


def cell_roots(method: str, robot: str) -> tuple[str, ...]:
    """Where the computation of a cell of ``method`` on a scenario of the robot whose config class
    lives in module ``robot`` starts (:mod:`~ilc_steering.engine.closure`): this module and the
    settings it is handed, the env that :data:`ENV_ID` names, the learner's sources, the robot's
    module and the packaged configs' package. Their import closure is the cell's code."""
    entry = gym.spec(ENV_ID).entry_point
    env = entry if isinstance(entry, str) else ENV_ID
    return (__name__, "ilc_steering.compare.args", env, *registry.lookup(method).sources(), robot, CONFIGS)


def cell_name(prior: str, method: str, scenario: str, seed: int) -> str:
    """The file name (without ``.json``) of a cell: injective in (prior, method, scenario, seed)."""
    return f"{prior}__{injective_name(method, registry.METHODS)}__{scenario}__{seed}"


def cell_path(out: Path, prior: str, method: str, scenario: str, seed: int, folder: str = "cells") -> Path:
    """The file of a cell, under ``out/folder``: one file per (prior, method, scenario, seed), never shared."""
    return out / folder / f"{cell_name(prior, method, scenario, seed)}.json"


Number = Annotated[float, Field(allow_inf_nan=True)]
"""A number whose range :func:`check_cell` checks, naming the value (a NaN included)."""


@dataclass(frozen=True)
class CellRecord:
    """A cell's file (``cells/*.json``, and each of ``compare.json``'s ``cells``), as its schema:
    read back, a cell of another shape is refused naming the key (:func:`check_cell`)."""

    prior: Name
    method: MethodName
    scenario: Name  # names a figure's file: read back, a name leading elsewhere is refused
    seed: int
    budget: int  # [trials]
    trials: int  # run [trials]
    off_chart_fraction: Number
    trials_to: dict[str, int | None]  # level of LADDER -> the first trial within it, or null
    fragile: tuple[str, ...]  # levels of LADDER
    best_error: Number  # the best true cost
    wall_s: Number  # [s]
    curve: tuple[tuple[int, Number], ...]  # [trial, best true cost] at every trial that improved it
    config_sha: str  # the content hash of its config
    version: str  # the ilc-steering version that computed it
    update_s: float | None = None  # [s] the median update of a learner that times its updates
    clipped_fraction: Number = 0.0
    implementation: str | None = None  # what made it (RL: the backend and its version)
    code: str | None = None  # the hash of its code (engine.provenance); None: a cell made before cells kept it


@dataclass(frozen=True)
class CompareReport:
    """``compare.json``, as its schema: the cells it was made from, and the tables made of them."""

    cells: tuple[CellRecord, ...]
    rows: tuple[dict[str, Any], ...] = ()
    summary: tuple[dict[str, Any], ...] = ()
    ratios: tuple[dict[str, Any], ...] = ()
    failed: tuple[dict[str, Any], ...] = ()


MAX_REPORT_BYTES = 256 << 20
"""The largest ``compare.json`` read [bytes]."""


def read_report(path: Path) -> dict[str, Any]:
    """``compare.json`` at ``path``, checked against :class:`CompareReport`: ``ValueError`` names the
    file and the key of the first thing wrong."""
    data: dict[str, Any] = read_json(path, MAX_REPORT_BYTES)
    check_record(CompareReport, data, path)
    return data


def _finite(value: float) -> bool:
    return bool(np.isfinite(value))


def _check_values(cell: dict[str, Any], path: Path | str, hint: str) -> None:
    """Every value a summary uses, in its range: ``ValueError`` naming the file and the value."""
    problems = []
    if not (_finite(cell["best_error"]) and cell["best_error"] >= 0):
        problems.append(f"best_error {cell['best_error']!r} is not a finite error >= 0")
    if not (_finite(cell["wall_s"]) and cell["wall_s"] >= 0):
        problems.append(f"wall_s {cell['wall_s']!r} is not a time >= 0 s")
    if not (_finite(cell["off_chart_fraction"]) and 0 <= cell["off_chart_fraction"] <= 1):
        problems.append(f"off_chart_fraction {cell['off_chart_fraction']!r} is not a fraction in [0, 1]")
    curve = cell["curve"]
    points = [p for p in curve if isinstance(p, list) and len(p) == 2]
    if not curve or len(points) != len(curve):
        problems.append("curve is not a non-empty list of [trial, best error] pairs")
    else:
        trials = [p[0] for p in points]
        errors = [p[1] for p in points]
        if not all(isinstance(t, int) and not isinstance(t, bool) and 1 <= t <= cell["trials"] for t in trials):
            problems.append(f"curve holds a trial outside [1, {cell['trials']}]")
        elif trials != sorted(set(trials)) or not all(
            isinstance(e, (int, float)) and _finite(e) and e >= 0 for e in errors
        ):
            problems.append("curve is not increasing in trials with finite errors >= 0")
    clipped = cell.get("clipped_fraction", 0.0)
    if not (isinstance(clipped, (int, float)) and _finite(clipped) and 0 <= clipped <= 1):
        problems.append(f"clipped_fraction {clipped!r} is not a fraction in [0, 1]")
    if not set(cell["fragile"]) <= set(LADDER):
        problems.append(f"fragile holds a level outside {sorted(LADDER)}")
    if not problems:
        problems += _contradictions(cell)
    if problems:
        raise BadInput(f"{path}: {problems[0]}; {hint}")


def _contradictions(cell: dict[str, Any]) -> list[str]:
    """What a cell's ``trials_to`` says against itself or its curve: a tighter level met before a
    looser one, or a level met at a trial whose best cost so far exceeds what meeting it allows
    (both errors within the level: a cost of at most twice it)."""
    reached = [cell["trials_to"][level] for level in LADDER]
    met = [k for k in reached if k is not None]
    if met != reached[: len(met)] or met != sorted(met):
        return [f"trials_to {cell['trials_to']} meets a tighter level before a looser one"]
    for level, k in zip(LADDER, reached):
        if k is None:
            continue
        best = min((cost for trial, cost in cell["curve"] if trial <= k), default=None)
        if best is None or best > 2 * LADDER[level] * (1 + 1e-9):
            return [f"trials_to meets {level} at trial {k}, where its curve's best cost is {best!r}"]
    return []


def read_cell(path: Path, key: dict[str, Any]) -> dict[str, Any]:
    """A finished cell, checked against its ``key`` (prior, method, scenario, seed, budget, the
    config's content hash and the package version) and value by value (finite, in range, within
    the budget); ``ValueError`` names the file."""
    hint = "delete it to have the cell computed again"
    try:
        cell = read_json(path, MAX_RESULT_BYTES)
    except ValueError as error:
        raise BadInput(f"not a readable cell: {error}; {hint}") from None
    return check_cell(cell, key, path, hint)


def check_cell(cell: Any, key: dict[str, Any], path: Path | str, hint: str) -> dict[str, Any]:
    """``cell`` checked as :func:`read_cell` checks it; ``ValueError`` names ``path`` and ends with ``hint``."""
    if not isinstance(cell, dict):
        raise BadInput(f"{path}: not a cell (a JSON object); {hint}")
    check_record(CellRecord, cell, path, hint)
    for name, value in key.items():
        if cell[name] != value:
            what = {"config_sha": "the content hash of its config", "version": "the ilc-steering version"}
            raise BadInput(f"{path}: holds {what.get(name, name)} {cell[name]!r}, not {value!r}; {hint}")
    if not 1 <= cell["trials"] <= cell["budget"]:
        raise BadInput(f"{path}: {cell['trials']} trials for a budget of {cell['budget']}; {hint}")
    reached = cell["trials_to"]
    if sorted(reached) != sorted(LADDER) or not all(
        v is None or (isinstance(v, int) and 1 <= v <= cell["trials"]) for v in reached.values()
    ):
        raise BadInput(f"{path}: 'trials_to' needs {sorted(LADDER)}, each a trial or null; {hint}")
    _check_values(cell, path, hint)
    return cell
