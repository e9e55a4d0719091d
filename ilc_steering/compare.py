"""Trials to tolerance: ILC against RL (SB3), black-box and users' learners, across seeds and priors.

Every method is a :class:`~ilc_steering.agents.base.Learner` built from the same
:class:`~ilc_steering.agents.base.LearnerContext` (the nominal model, the env's spaces, a seed and
the prior), run on ``ilc_steering/ChainedSteering-v0`` by the one trial loop,
:func:`~ilc_steering.loop.run_trials`, which runs and counts every trial it asks for (probes,
random exploration and RL's deterministic trials included) up to the budget; a
:class:`TrialLog` records the *true* errors (the env may measure with noise).

Two conditions, ``--priors``: ``nominal`` (every method's first trial is the nominal open-loop
solution, and black-box and RL methods search a residual box around it) and ``none`` (no prior:
a seeded start near ``c = 0`` in the env's whole action box). ``ilc_paper`` is the paper's
learner exactly, whose fictitious zero iteration is its own first trial under both.

A run folder holds ``run.json`` (the settings, the package version and the content hash of each
scenario's resolved config), ``cells/<prior>__<method>__<scenario>__<seed>.json`` (one per
finished cell, written the moment it finishes; the method's part of the name is injective,
:func:`~ilc_steering.output.injective_name`), ``failed/`` (one file per cell that raised or
outlived ``--cell-timeout``, with its error) and, at the end, ``compare.{csv,json,md}`` and
``compare_<scenario>.png``. Running again on the same folder skips the finished cells and
retries the failed ones: an interrupted run resumes and never recomputes or loses a finished
cell. A resume with other settings, another version, or another config under a scenario's name
is refused, saying which; every resumed cell is checked value by value (:func:`read_cell`).
Cells run in ``--workers`` processes (one per core by default, at most
:data:`~ilc_steering.backends.MAX_WORKERS`), with the same results as one process.

``--against DIR`` puts new methods beside a committed run without rerunning it: the run takes
the committed run's settings (budgets, seeds, ``quick``; another version or other settings are
refused, :mod:`~ilc_steering.against`), its scenarios and priors, copies its cells, each checked,
into ``--out`` (``DIR`` is only read), computes only the cells it lacks, and reports them all.

A tolerance level is met when the error is at most the level; a count that a relative change
of 1e-6 in the error would move (:data:`FRAGILE`) is listed in the cell's ``fragile`` and
marked in the report.

    ilc-steering compare [--quick] [--out DIR] [--methods ilc least_squares mypkg.mod:make ...]
    ilc-steering compare --methods mypkg.mod:make --against docs/compare --out DIR
    python benchmarks/compare.py [--quick] [--out DIR]
"""

from __future__ import annotations

import argparse
import fcntl
import os
import sys
import time
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from dataclasses import asdict, dataclass, fields, replace
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from ilc_steering import __version__
from ilc_steering.against import CommittedRun, check_out, describe, read_committed, resolve_settings
from ilc_steering.agents import registry
from ilc_steering.agents.base import PRIORS, Learner, LearnerContext, update_times
from ilc_steering.agents.registry import Budgets, is_custom
from ilc_steering.backends import BACKENDS, MAX_WORKERS, check_workers, run_calls
from ilc_steering.compare_report import LADDER, write_report
from ilc_steering.core.score import true_cost
from ilc_steering.inputs import read_json
from ilc_steering.loop import run_trials
from ilc_steering.output import (
    MAX_RESULT_BYTES,
    check_output_dir,
    check_run_settings,
    content_hash,
    differences,
    injective_name,
    write_json,
)
from ilc_steering.runner import check_task, step_warning

__all__ = [
    "LADDER",
    "Args",
    "TrialLog",
    "main",
    "main_with_failures",
    "make_learner",
    "measure",
    "method_families",
    "parse",
    "run_all",
    "run_cell",
    "run_cells",
]

ENV_ID = "ilc_steering/ChainedSteering-v0"
MAX_SEED = 2**32 - 1
MODEL_METHODS = registry.ids("model-based")
BLACKBOX = registry.ids("black-box")
RL = registry.ids("RL")
METHODS = registry.METHODS
DEFAULT_METHODS = registry.DEFAULT_METHODS
"""Views of the one table of method ids, :data:`ilc_steering.agents.registry.REGISTRY`."""
SCENARIOS = (
    "forward_parking",
    "forward_parking_saturated",
    "parallel_parking",
    "forward_parking_noisy",
    "unicycle_parking",
    "trailer_bay",
)


@dataclass(frozen=True)
class Args:
    quick: bool = False
    """Tiny budgets and two seeds: checks that everything runs and writes well-formed output (CI)."""
    out: Path = Path("runs/compare")
    """Run folder; an existing one is resumed."""
    against: Path | None = None
    """A committed run folder, only read: run the cells of ``methods`` it lacks, with its settings,
    and report both (:mod:`~ilc_steering.against`)."""
    priors: tuple[str, ...] = PRIORS
    """Conditions: ``nominal`` (start from the nominal solution) and ``none`` (no prior)."""
    methods: tuple[str, ...] = DEFAULT_METHODS
    """Methods: the library's ids, or ``module:attr`` for a user's learner factory."""
    scenarios: tuple[str, ...] = SCENARIOS
    """Packaged config names or YAML paths of one-trial tasks."""
    seeds: tuple[int, ...] = tuple(range(10))
    """Seeds; each (prior, method, scenario, seed) is one cell."""
    model_trials: int = 30
    """Budget of the model-based learners (``ilc``, ``ilc_paper``, ``newton``) [trials]."""
    blackbox_trials: int = 3000
    """Budget of each black-box optimizer [trials]."""
    rl_trials: int | None = None
    """Budget of each RL algorithm [trials]; None: ``n_timesteps`` of its hyperparameter file."""
    custom_trials: int = 300
    """Budget of a user's learner (``module:attr``) [trials]."""
    workers: int = 0
    """Worker processes; 0: one per core."""
    progress_bar: bool = False
    """SB3's progress bar on RL cells (with one worker only)."""
    backend: str = "local"
    """Where cells run: ``local`` processes or ``ray`` tasks (:mod:`ilc_steering.backends`)."""
    cell_timeout: float | None = None
    """[s] a cell still running after this is stopped and recorded as failed; None: no limit."""


FRAGILE = 1e-6
"""A count is fragile when scaling every error by ``1 - FRAGILE`` or ``1 + FRAGILE`` would move it."""
MAX_BUDGET = 1_000_000
"""The largest budget of any method [trials]: the trial log is kept in memory."""

QUICK = {"model_trials": 6, "blackbox_trials": 40, "rl_trials": 48, "custom_trials": 20}
QUICK_SEEDS = (0, 1)


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


def method_families(methods: Iterable[str] = ()) -> dict[str, tuple[str, ...]]:
    """The families the comparison's figures colour by (:mod:`~ilc_steering.figure_styles`):
    :func:`ilc_steering.agents.registry.families`."""
    return registry.families(methods)


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
    env: gym.Env[Any, Any], learner: Learner, trials: int, seed: int, name: str | None = None
) -> dict[str, Any]:
    """Run ``learner`` (``name`` for errors) on ``env`` for ``trials`` trials and return what it
    reached: the trials to each tolerance of :data:`LADDER` and which of them are fragile
    (:func:`fragile_levels`), the best true cost, the off-chart fraction, the wall time [s] and
    the best-so-far curve."""
    log = TrialLog()
    start = time.perf_counter()
    run_trials(env, learner, trials, seed=seed, callbacks=[log], name=name)
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


def run_cell(args: Args, prior: str, method: str, scenario: str, seed: int) -> dict[str, Any]:
    """One (prior, method, scenario, seed) cell: the method's run within its budget, and what it reached."""
    if method in RL:
        import torch

        torch.set_num_threads(1)  # as in the worker processes: serial and parallel runs agree
    env = gym.make(ENV_ID, config=scenario)
    context = LearnerContext.from_env(env, seed=seed, prior=prior, progress_bar=args.progress_bar)
    spec = registry.lookup(method)
    trials = spec.budget(budgets(args), context.task, prior)
    learner = spec.make(context, trials)
    result = measure(env, learner, trials, seed, method)
    result["implementation"] = spec.implementation()
    env.close()
    return {"prior": prior, "method": method, "scenario": context.task, "seed": seed, "budget": trials, **result}


def cell_path(out: Path, prior: str, method: str, scenario: str, seed: int, folder: str = "cells") -> Path:
    """The file of a cell, under ``out/folder``: one file per (prior, method, scenario, seed), never shared."""
    return out / folder / f"{prior}__{injective_name(method, METHODS)}__{scenario}__{seed}.json"


def validate(args: Args) -> dict[str, str]:
    """Check every argument and scenario before the first cell; returns scenario -> config name.

    ``ValueError`` names the argument: unknown or repeated priors, methods, scenarios or seeds, a
    user's learner that cannot be imported, a seed outside ``[0, 2**32)``, a cyclic config
    (``compare`` runs one-trial tasks), two scenarios of one name, a budget outside ``[1,
    MAX_BUDGET]``, a worker count outside ``[0, MAX_WORKERS]``, a ``cell_timeout`` that is not a
    time > 0 s.
    """
    from ilc_steering.config import load_config

    if args.backend not in BACKENDS:
        raise ValueError(f"--backend must be one of {list(BACKENDS)}, got {args.backend!r}")
    options = (("--priors", args.priors), ("--methods", args.methods), ("--scenarios", args.scenarios))
    for option, values in (*options, ("--seeds", args.seeds)):
        if not values:
            raise ValueError(f"{option}: give at least one")
        repeated = sorted({str(v) for v in values if list(values).count(v) > 1})
        if repeated:
            raise ValueError(f"{option}: {repeated[0]} is given twice; each cell is counted once")
    unknown_priors = [p for p in args.priors if p not in PRIORS]
    if unknown_priors:
        raise ValueError(f"--priors: unknown prior {unknown_priors[0]!r}; choose from {list(PRIORS)}")
    for method in args.methods:
        registry.lookup(method)
    bad = [s for s in args.seeds if isinstance(s, bool) or not isinstance(s, int) or not 0 <= s <= MAX_SEED]
    if bad:
        raise ValueError(f"--seeds: {bad[0]!r} is not a whole number in [0, {MAX_SEED}]")
    for option in ("model_trials", "blackbox_trials", "rl_trials", "custom_trials"):
        value = getattr(args, option)
        if value is not None and (
            isinstance(value, bool) or not isinstance(value, int) or not 1 <= value <= MAX_BUDGET
        ):
            raise ValueError(
                f"--{option.replace('_', '-')}: the budget must be a whole number in [1, {MAX_BUDGET}], got {value!r}"
            )
    check_workers(args.workers)
    timeout = args.cell_timeout
    if timeout is not None and not (isinstance(timeout, (int, float)) and np.isfinite(timeout) and timeout > 0):
        raise ValueError(f"--cell-timeout: a time limit > 0 s, got {timeout!r}")
    names: dict[str, str] = {}
    for scenario in args.scenarios:
        config = load_config(scenario)
        if config.is_cyclic:
            raise ValueError(
                f"--scenarios {scenario}: a cyclic config; compare runs one-trial tasks "
                "(use ilc-steering run for cycles)"
            )
        if config.name in names.values():
            raise ValueError(f"--scenarios {scenario}: another scenario is also named {config.name!r}")
        env = gym.make(ENV_ID, config=config)
        check_task(env, f"--scenarios {scenario}")
        env.close()
        names[scenario] = config.name
    for prior in args.priors:
        for method in args.methods:
            for name in names.values():
                budget(args, prior, method, name)  # RL: its hyperparameters exist
    return names


CELL_KEYS = {
    "prior": str,
    "method": str,
    "scenario": str,
    "seed": int,
    "budget": int,
    "trials": int,
    "off_chart_fraction": float,
    "trials_to": dict,
    "fragile": list,
    "best_error": float,
    "wall_s": float,
    "curve": list,
    "config_sha": str,
    "version": str,
}


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
    if problems:
        raise ValueError(f"{path}: {problems[0]}; {hint}")


def read_cell(path: Path, key: dict[str, Any]) -> dict[str, Any]:
    """A finished cell, checked against its ``key`` (prior, method, scenario, seed, budget, the
    config's content hash and the package version) and value by value (finite, in range, within
    the budget); ``ValueError`` names the file."""
    hint = "delete it to have the cell computed again"
    try:
        cell = read_json(path, MAX_RESULT_BYTES)
    except ValueError as error:
        raise ValueError(f"not a readable cell: {error}; {hint}") from None
    return check_cell(cell, key, path, hint)


def check_cell(cell: Any, key: dict[str, Any], path: Path | str, hint: str) -> dict[str, Any]:
    """``cell`` checked as :func:`read_cell` checks it; ``ValueError`` names ``path`` and ends with ``hint``."""
    if not isinstance(cell, dict):
        raise ValueError(f"{path}: not a cell (a JSON object); {hint}")
    for name, kind in CELL_KEYS.items():
        value = cell.get(name)
        ok = isinstance(value, (int, float)) if kind is float else isinstance(value, kind)
        if not ok or isinstance(value, bool):
            raise ValueError(f"{path}: {name!r} is missing or not a {kind.__name__}; {hint}")
    for name, value in key.items():
        if cell[name] != value:
            what = {"config_sha": "the content hash of its config", "version": "the ilc-steering version"}
            raise ValueError(f"{path}: holds {what.get(name, name)} {cell[name]!r}, not {value!r}; {hint}")
    if not 1 <= cell["trials"] <= cell["budget"]:
        raise ValueError(f"{path}: {cell['trials']} trials for a budget of {cell['budget']}; {hint}")
    reached = cell["trials_to"]
    if sorted(reached) != sorted(LADDER) or not all(
        v is None or (isinstance(v, int) and 1 <= v <= cell["trials"]) for v in reached.values()
    ):
        raise ValueError(f"{path}: 'trials_to' needs {sorted(LADDER)}, each a trial or null; {hint}")
    _check_values(cell, path, hint)
    return cell


def run_settings(args: Args) -> dict[str, Any]:
    """What ``run.json`` records and a resume (or ``--against``) must match: the budgets, the seeds,
    ``quick`` and the package version; not the grid's axes (a resume may add cells), nor how or
    where cells run."""
    skip = ("out", "against", "progress_bar", "priors", "methods", "scenarios", "workers", "backend", "cell_timeout")
    settings = {k: v for k, v in asdict(args).items() if k not in skip}
    settings["seeds"] = list(settings["seeds"])
    settings["version"] = __version__
    return settings


def _check_run_folder(args: Args, configs: dict[str, str]) -> None:
    """Record the settings, the version and the configs' content hashes; refuse to resume a folder
    written with other budgets, seeds or version, or another config of one of these names."""
    settings = run_settings(args)
    cells = args.out / "cells"
    check_output_dir(args.out, "--out")
    if cells.exists() and not cells.is_dir():
        raise ValueError(f"{cells}: exists and is not a folder; this is not a compare run folder")
    resumed = check_run_settings(args.out, settings, cells, configs)
    cells.mkdir(exist_ok=True)
    if resumed:
        _restore_cells(args.out)


MAX_REPORT_BYTES = 256 << 20
"""The largest ``compare.json`` read back to restore a clone's cells [bytes]."""


def _restore_cells(folder: Path) -> None:
    """Write back the cells that the folder's ``compare.json`` holds and ``cells/`` lacks (a clone of a
    run whose cells were not kept): the settings matched, so they are the cells this run would compute.
    Each is checked like any resumed cell when it is read (its config's hash and version included)."""
    report = folder / "compare.json"
    if not report.is_file():
        return
    try:
        data = read_json(report, MAX_REPORT_BYTES)
        cells = data.get("cells", []) if isinstance(data, dict) else []
    except ValueError as error:
        raise ValueError(f"{error}; use another --out folder") from None
    restored = 0
    for cell in cells if isinstance(cells, list) else []:
        try:
            path = cell_path(folder, cell["prior"], cell["method"], cell["scenario"], cell["seed"])
        except (KeyError, TypeError, ValueError):
            raise ValueError(f"{report}: holds a cell without its key; use another --out folder") from None
        if not path.exists():
            write_json(path, cell)
            restored += 1
    if restored:
        print(f"restored {restored} cells from {report}", flush=True)


@contextmanager
def _locked(folder: Path) -> Iterator[None]:
    """Hold an exclusive lock on the run folder: two ``compare`` processes never share one."""
    with open(folder / ".lock", "a") as handle:
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            raise ValueError(f"{folder}: another compare is running on this folder") from None
        try:
            yield
        finally:
            fcntl.flock(handle, fcntl.LOCK_UN)


def _progress(cell: dict[str, Any]) -> None:
    reached = cell["trials_to"]
    print(
        f"{cell['prior']:7s} {cell['scenario']:26s} {cell['method']:13s} seed {cell['seed']}: "
        f"best {cell['best_error']:.2e}; 1 cm at trial {reached['1cm'] or '-'}, "
        f"0.5 mm / 0.5 mrad at {reached['0.5mm'] or '-'} ('-': not within {cell['budget']}); "
        f"{100 * cell['off_chart_fraction']:.0f}% off the chart; {cell['wall_s']:.1f} s",
        flush=True,
    )


def workers(args: Args) -> int:
    return args.workers or os.cpu_count() or 1


Runner = Callable[[Args, str, str, str, int], dict[str, Any]]


def run_cells(args: Args, runner: Runner = run_cell) -> list[dict[str, Any]]:
    """Every finished cell of the run (:func:`run_all`), in order; the failed ones are in ``failed/``."""
    return run_all(args, runner)[0]


def _failure(key: dict[str, Any], message: str) -> dict[str, Any]:
    cell = {name: key[name] for name in ("prior", "method", "scenario", "seed", "budget")}
    return {**cell, "error": message}


Cell = tuple[str, str, str, int]
"""A cell's (prior, method, scenario name, seed)."""


def against_args(args: Args) -> tuple[Args, CommittedRun]:
    """``args`` for ``--against`` and the committed run as read: its settings (budgets, seeds,
    ``quick``) where ``args`` holds the defaults, its scenarios and priors unless a subset of them
    is given. ``ValueError`` (one line, naming the option) for a run of another version or other
    settings, an ``--out`` inside it, a method list left at the default, a scenario or prior it
    has no cells of, or a scenario of its that is not packaged and not given as a YAML file."""
    from ilc_steering.config import load_config, packaged_configs

    folder = args.against
    if folder is None:
        raise ValueError("--against: give a committed run folder")
    committed = read_committed(folder)
    check_out(args.out, folder)
    if args.methods == Args.methods:
        raise ValueError(f"--against {folder}: name the methods to add with --methods, e.g. --methods my_learners:make")
    defaults = {f.name: f.default for f in fields(Args)}
    args = replace(args, **resolve_settings(committed, asdict(args), defaults, __version__))
    cells = [cell for _, cell in committed.cells]
    scenarios = [name for name in committed.configs if any(c["scenario"] == name for c in cells)]
    if args.scenarios == Args.scenarios:
        unknown = [name for name in scenarios if name not in packaged_configs()]
        if unknown:
            raise ValueError(
                f"--against {folder}: its scenario {unknown[0]!r} is not a packaged config; give its YAML file with "
                f"--scenarios, beside those of its other scenarios to run ({' '.join(scenarios)})"
            )
        args = replace(args, scenarios=tuple(scenarios))
    for scenario in args.scenarios:
        if load_config(scenario).name not in scenarios:
            raise ValueError(
                f"--scenarios {scenario}: the committed run --against {folder} has no cells of it; its scenarios: "
                f"{' '.join(scenarios)}"
            )
    priors = [prior for prior in PRIORS if any(c["prior"] == prior for c in cells)]
    if args.priors == Args.priors:
        args = replace(args, priors=tuple(priors))
    elif not set(args.priors) <= set(priors):
        raise ValueError(f"--priors: the committed run --against {folder} has cells of {' '.join(priors)} only")
    settings = run_settings(args)
    if settings != committed.settings:
        raise ValueError(
            f"--against {folder}: it was run with other settings: {differences(committed.settings, settings)}"
        )
    return args, committed


def _committed_cells(
    args: Args, committed: CommittedRun, configs: dict[str, str]
) -> tuple[dict[Cell, dict[str, Any]], dict[str, str]]:
    """The committed run's cells, each checked against its key and value by value, and the
    content hash of every scenario's config; ``ValueError`` if a scenario to run has another
    config than the committed run's cells of that name, or a committed cell is not one of its run."""
    folder = committed.folder
    for name, digest in configs.items():
        theirs = committed.configs.get(name)
        if theirs != digest:
            raise ValueError(
                f"--against {folder}: its {name!r} cells were computed with another config (content hash {theirs}, "
                f"this one's {digest}): the same name, another content"
            )
    hint = f"the committed run --against {folder} is not consistent; recompute it"
    held: dict[Cell, dict[str, Any]] = {}
    for where, cell in committed.cells:
        prior, method, scenario, seed = (cell[name] for name in ("prior", "method", "scenario", "seed"))
        known = isinstance(method, str) and (method in METHODS or is_custom(method))
        ours = isinstance(scenario, str) and scenario in committed.configs
        if prior not in PRIORS or not known or not ours or seed not in args.seeds:
            raise ValueError(
                f"{where}: not a cell of its run (prior {prior!r}, method {method!r}, scenario {scenario!r}, "
                f"seed {seed!r}); {hint}"
            )
        key = {
            "prior": prior,
            "method": method,
            "scenario": scenario,
            "seed": seed,
            "budget": budget(args, prior, method, scenario),
            "config_sha": committed.configs[scenario],
            "version": __version__,
        }
        held[(prior, method, scenario, seed)] = check_cell(cell, key, where, hint)
    scenarios = dict.fromkeys(cell[2] for cell in held)
    return held, {**{name: committed.configs[name] for name in scenarios}, **configs}


def _grid(args: Args, names: list[str], held: dict[Cell, dict[str, Any]]) -> list[Cell]:
    """The cells of an ``--against`` run, in the report's order: every committed one, and those of
    ``args.methods`` on ``names`` under ``args.priors`` that it lacks."""
    priors = [prior for prior in PRIORS if prior in args.priors or any(cell[0] == prior for cell in held)]
    scenarios = list(dict.fromkeys([*(cell[2] for cell in held), *names]))
    methods = list(dict.fromkeys([*(cell[1] for cell in held), *args.methods]))
    return [
        (prior, method, name, seed)
        for prior in priors
        for name in scenarios
        for method in methods
        for seed in args.seeds
        if (prior, method, name, seed) in held or (method in args.methods and prior in args.priors and name in names)
    ]


def _copy_committed(held: dict[Cell, dict[str, Any]], keys: list[dict[str, Any]], path: Callable[[int], Path]) -> None:
    """Write each committed cell into the run folder as it is, where it lacks it; ``ValueError``
    if the folder holds another result for one of them (it is never overwritten)."""
    for index, key in enumerate(keys):
        cell = held.get((key["prior"], key["method"], key["scenario"], key["seed"]))
        if cell is None:
            continue
        if not path(index).exists():
            write_json(path(index), cell)
        elif read_cell(path(index), key) != cell:
            raise ValueError(f"{path(index)}: holds another result than the committed run's; use another --out folder")


def run_all(args: Args, runner: Runner = run_cell) -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
    """Every cell of the run, computing only those not yet in the run folder, in :func:`workers`
    processes (one with a custom ``runner``, called as it is: a test's hook); returns the
    finished cells and the failed ones, each in the run's order.

    Everything is validated before the first cell; each finished cell is written the moment it
    finishes, whatever happens to the others. A cell that raises or outlives ``cell_timeout`` is
    written to ``failed/`` with its error (prior, method, scenario and seed named) and the run
    goes on; a resume computes it again.
    """
    from ilc_steering.config import load_config

    committed = None
    if args.against is not None:
        args, committed = against_args(args)
    names = validate(args)
    configs = {name: content_hash(asdict(load_config(scenario))) for scenario, name in names.items()}
    for scenario in names:
        warning = step_warning(load_config(scenario))
        if warning is not None:
            print(f"ilc-steering: {warning}", file=sys.stderr, flush=True)
    held: dict[Cell, dict[str, Any]] = {}
    if committed is not None:
        held, configs = _committed_cells(args, committed, configs)
    _check_run_folder(args, configs)

    def key_of(prior: str, method: str, name: str, seed: int) -> dict[str, Any]:
        return {
            "prior": prior,
            "method": method,
            "scenario": name,
            "seed": seed,
            "budget": budget(args, prior, method, name),
            "config_sha": configs[name],
            "version": __version__,
        }

    if committed is None:
        grid = [
            (prior, method, name, seed)
            for prior in args.priors
            for name in names.values()
            for method in args.methods
            for seed in args.seeds
        ]
    else:
        grid = _grid(args, list(names.values()), held)
    keys = [key_of(*cell) for cell in grid]
    scenario_of = {name: scenario for scenario, name in names.items()}
    done: dict[int, dict[str, Any]] = {}
    failed: dict[int, dict[str, Any]] = {}

    def path(index: int, folder: str = "cells") -> Path:
        key = keys[index]
        return cell_path(args.out, key["prior"], key["method"], key["scenario"], key["seed"], folder)

    with _locked(args.out):
        if held:
            _copy_committed(held, keys, path)
        todo = []
        for index, key in enumerate(keys):
            if path(index).exists():
                done[index] = read_cell(path(index), key)
            else:
                todo.append(index)
        if committed is not None:
            print(
                f"--against {committed.folder}: {len(held)} committed cells taken as they are (copied into "
                f"{args.out}/cells), {len(todo)} cells to compute, with its settings: {describe(committed.settings)}",
                flush=True,
            )

        def finish(index: int, cell: dict[str, Any]) -> None:
            cell = {**cell, "config_sha": keys[index]["config_sha"], "version": __version__}
            write_json(path(index), cell)
            path(index, "failed").unlink(missing_ok=True)
            done[index] = cell
            _progress(cell)

        def fail(index: int, message: str) -> None:
            key = keys[index]
            failed[index] = _failure(key, message)
            path(index, "failed").parent.mkdir(exist_ok=True)
            write_json(path(index, "failed"), failed[index])
            print(
                f"{key['prior']:7s} {key['scenario']:26s} {key['method']:13s} seed {key['seed']}: FAILED, "
                f"recorded in {path(index, 'failed')}: {message}",
                flush=True,
            )

        def call(index: int) -> tuple[Args, str, str, str, int]:
            key = keys[index]
            return args, key["prior"], key["method"], scenario_of[key["scenario"]], key["seed"]

        if runner is not run_cell:
            for index in todo:
                finish(index, runner(*call(index)))
        else:
            parallel = args.backend == "ray" or min(workers(args), len(todo)) > 1
            quiet = replace(args, progress_bar=False) if parallel else args
            calls = {index: (quiet, *call(index)[1:]) for index in todo}
            run_calls(run_cell, calls, finish, args.backend, args.workers, fail, args.cell_timeout)
    order = range(len(keys))
    return [done[i] for i in order if i in done], [failed[i] for i in order if i in failed]


def main(args: Args) -> list[dict[str, Any]]:
    """Run (or resume) the comparison and write its report; returns the finished cells."""
    return main_with_failures(args)[0]


def main_with_failures(args: Args) -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
    """:func:`main`, returning the failed cells too; the last line printed says how many failed."""
    committed = None
    if args.against is not None:  # the committed run's settings, quick budgets included
        args, committed = against_args(args)
    elif args.quick:  # the quick budgets, where no budget was given
        quick: dict[str, Any] = {k: v for k, v in QUICK.items() if getattr(args, k) == getattr(Args, k)}
        args = replace(args, **quick)
    cells, failed = run_all(args)
    names = list(validate(args).values())
    if committed is not None:
        names = list(dict.fromkeys([*(c["scenario"] for c in cells), *names]))
    if cells:
        groups = method_families(c["method"] for c in cells)
        text = write_report(cells, names, args.out, {"black-box": BLACKBOX, "RL": RL}, failed, groups)
        print(text)
        where = f"{args.out}/compare.{{csv,json,md}}, compare_<scenario>.png"
        print(f"wrote {where} and one file per cell in {args.out}/cells")
    if committed is not None:
        print(
            f"the report holds the {len(committed.cells)} cells of the committed run --against {committed.folder} "
            f"and {len(cells) - len(committed.cells)} of {' '.join(args.methods)}"
            + (f"; its {committed.failed} failed cells are not taken" if committed.failed else ""),
            flush=True,
        )
    total = len(cells) + len(failed)
    if failed:
        print(
            f"{len(failed)} of {total} cells failed, each recorded with its error in {args.out}/failed "
            "(a resume computes them again)",
            flush=True,
        )
    else:
        print(f"all {total} cells finished", flush=True)
    return cells, failed


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.formatter_class = argparse.ArgumentDefaultsHelpFormatter
    parser.add_argument(
        "--quick",
        action="store_true",
        help=f"tiny budgets ({QUICK['model_trials']} model-based, {QUICK['blackbox_trials']} black-box, "
        f"{QUICK['rl_trials']} RL, {QUICK['custom_trials']} custom trials) and, unless --seeds is given, seeds "
        f"{' '.join(map(str, QUICK_SEEDS))}: checks that everything runs",
    )
    parser.add_argument("--out", type=Path, default=Args.out, help="run folder; an existing one is resumed")
    parser.add_argument(
        "--against",
        type=Path,
        default=None,
        metavar="DIR",
        help="a committed run folder (e.g. docs/compare), only read: run the cells of --methods it lacks, with its "
        "scenarios, seeds, priors and budgets (its run.json; another version or other settings are refused), and "
        "write the joint report to --out",
    )
    parser.add_argument(
        "--priors", nargs="+", default=list(PRIORS), help="nominal: start from the nominal solution; none: no prior"
    )
    parser.add_argument(
        "--methods",
        nargs="+",
        default=list(DEFAULT_METHODS),
        help=f"any of {' '.join(METHODS)}, or module:attr, a factory make(LearnerContext) -> Learner",
    )
    parser.add_argument(
        "--scenarios", nargs="+", default=list(SCENARIOS), help="packaged config names or YAML paths (one-trial tasks)"
    )
    parser.add_argument(
        "--seeds",
        type=int,
        nargs="+",
        default=argparse.SUPPRESS,
        help=f"whole numbers in [0, {MAX_SEED}] (default: 0 to 9; with --quick: 0 1)",
    )
    for option, what in (
        ("model_trials", "ilc, ilc_paper and newton"),
        ("blackbox_trials", "each black-box optimizer"),
        ("rl_trials", "each RL algorithm (default: n_timesteps of configs/rl/*.yaml)"),
        ("custom_trials", "a user's learner (module:attr)"),
    ):
        parser.add_argument(
            f"--{option.replace('_', '-')}",
            type=int,
            default=argparse.SUPPRESS,
            help=f"budget of {what} [trials] (default: {getattr(Args, option)}; with --quick: {QUICK[option]})",
        )
    parser.add_argument(
        "--workers", type=int, default=0, help=f"worker processes (0: one per core; at most {MAX_WORKERS})"
    )
    parser.add_argument(
        "--cell-timeout",
        type=float,
        default=None,
        metavar="SECONDS",
        help="stop a cell still running after this and record it as failed (default: no limit)",
    )
    parser.add_argument(
        "--backend",
        default="local",
        help="local worker processes, or Ray tasks on ray.init() (a local Ray; a cluster through RAY_ADDRESS)",
    )
    bar = parser.add_mutually_exclusive_group()
    bar.add_argument("--progress-bar", action="store_true", help="SB3's progress bar on RL cells (one worker)")
    bar.add_argument("--no-progress-bar", action="store_true", help="no progress bar (the default)")


def from_namespace(ns: argparse.Namespace) -> Args:
    given = getattr(ns, "seeds", None)
    seeds = given if given is not None else (QUICK_SEEDS if ns.quick else Args.seeds)
    budgets = {k: getattr(ns, k) for k in QUICK if hasattr(ns, k)}
    args = Args(
        quick=ns.quick,
        out=ns.out,
        against=ns.against,
        priors=tuple(ns.priors),
        methods=tuple(ns.methods),
        scenarios=tuple(ns.scenarios),
        seeds=tuple(seeds),
        workers=ns.workers,
        progress_bar=ns.progress_bar,
        backend=ns.backend,
        cell_timeout=ns.cell_timeout,
    )
    return replace(args, **budgets)


def parse(argv: list[str] | None = None) -> Args:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    add_arguments(parser)
    return from_namespace(parser.parse_args(argv))
