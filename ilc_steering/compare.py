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

A run folder holds ``run.json`` (the settings), ``cells/<prior>__<method>__<scenario>__<seed>.json``
(one per finished cell, written when it finishes) and, at the end, ``compare.{csv,json,md}`` and
``compare_<scenario>.png``. Running again on the same folder skips the finished cells: an
interrupted run resumes and never recomputes or loses a finished cell. Cells run in
``--workers`` processes (one per core by default), with the same results as one process.

    ilc-steering compare [--quick] [--out DIR] [--methods ilc least_squares mypkg.mod:make ...]
    python benchmarks/compare.py [--quick] [--out DIR]
"""

from __future__ import annotations

import argparse
import fcntl
import json
import os
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from ilc_steering.agents.base import PRIORS, Learner, LearnerContext, load_factory
from ilc_steering.backends import BACKENDS, run_calls
from ilc_steering.compare_report import LADDER, write_report
from ilc_steering.core.score import true_cost
from ilc_steering.loop import run_trials
from ilc_steering.output import check_output_dir, check_run_settings, safe_name, write_json

__all__ = [
    "LADDER",
    "Args",
    "TrialLog",
    "main",
    "make_learner",
    "measure",
    "parse",
    "run_cell",
    "run_cells",
]

ENV_ID = "ilc_steering/ChainedSteering-v0"
MAX_SEED = 2**32 - 1
MODEL_METHODS = ("ilc", "ilc_paper", "newton", "newton_ilc")
BLACKBOX = ("least_squares", "gauss_newton", "nelder_mead", "cma_es")
RL = ("ppo", "sac", "td3")
METHODS = (*MODEL_METHODS, *BLACKBOX, *RL)
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
    priors: tuple[str, ...] = PRIORS
    """Conditions: ``nominal`` (start from the nominal solution) and ``none`` (no prior)."""
    methods: tuple[str, ...] = METHODS
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


LEVEL_SLACK = 1e-9
"""Relative slack of a tolerance level: below the simulator's accuracy, so it never decides a count."""

QUICK = {"model_trials": 6, "blackbox_trials": 40, "rl_trials": 48, "custom_trials": 20}
QUICK_SEEDS = (0, 1)


class TrialLog:
    """A trial-loop callback that keeps every trial's *true* errors: Cartesian [m] and orientation
    [rad] for a robot with a pose, the chained error norm for a chained plant (``cartesian`` holds
    it then, ``orientation`` zeros), the true cost (:func:`~ilc_steering.core.score.true_cost`,
    the off-chart penalty included), and whether it left the chart."""

    def __init__(self) -> None:
        self.cartesian: list[float] = []
        self.orientation: list[float] = []
        self.cost: list[float] = []
        self.left_chart: list[bool] = []

    def __call__(self, k: int, info: dict[str, Any]) -> None:
        self.cartesian.append(float(info.get("true_cartesian_error", info["true_error_norm"])))
        self.orientation.append(float(info.get("true_orientation_error", 0.0)))
        self.cost.append(float(true_cost(info)))
        self.left_chart.append(bool(info["left_chart"]))


def first_within(log: TrialLog, tolerance: float) -> int | None:
    """The 1-based index of the first trial that stayed in the chart with both errors within
    ``tolerance`` (a chained plant: its error norm), or None.

    Within means to :data:`LEVEL_SLACK`: the paper's law on forward parking cuts the error
    exactly tenfold per trial, so its errors land *on* 1 cm and 1 mm, where the last digits of
    the integrator (accurate to 1e-9, not to 1e-16) would otherwise decide the count."""
    bound = tolerance * (1.0 + LEVEL_SLACK)
    ok = (np.asarray(log.cartesian) <= bound) & (np.asarray(log.orientation) <= bound)
    hits = np.flatnonzero(ok & ~np.asarray(log.left_chart, dtype=bool))
    return int(hits[0]) + 1 if hits.size else None


def best_so_far(log: TrialLog) -> list[list[float]]:
    """``[trial, best true cost]`` at every trial that improved it."""
    best = np.minimum.accumulate(np.asarray(log.cost))
    changed = np.flatnonzero(np.concatenate([[True], best[1:] < best[:-1]]))
    return [[int(i) + 1, float(best[i])] for i in changed]


def is_custom(method: str) -> bool:
    """A user's learner factory, ``module:attr``."""
    return ":" in method


def custom_factory(method: str) -> Callable[[LearnerContext], Learner]:
    """The factory named ``module:attr``; ``ValueError`` if it cannot be imported or called."""
    return load_factory(method, "--methods")


def budget(args: Args, prior: str, method: str, scenario: str) -> int:
    if method in MODEL_METHODS:
        return args.model_trials
    if is_custom(method):
        return args.custom_trials
    if method in RL:
        from ilc_steering.agents.rl import hyperparameters

        if args.rl_trials is not None:
            return args.rl_trials
        return int(hyperparameters(method, scenario, prior)["n_timesteps"])
    return args.blackbox_trials


def make_learner(args: Args, method: str, scenario: str, context: LearnerContext) -> Learner:
    """The learner of ``method`` for ``scenario`` (its config's name), built from ``context`` alone."""
    from ilc_steering.agents.ilc import make_ilc, make_ilc_paper
    from ilc_steering.agents.newton import make_newton
    from ilc_steering.agents.newton_ilc import make_newton_ilc

    builders: dict[str, Callable[[LearnerContext], Learner]] = {
        "ilc": make_ilc,
        "ilc_paper": make_ilc_paper,
        "newton": make_newton,
        "newton_ilc": make_newton_ilc,
    }
    if method in builders:
        return builders[method](context)
    if method in RL:
        from ilc_steering.agents import rl

        params = rl.hyperparameters(method, scenario, context.prior)
        trials = budget(args, context.prior, method, scenario)
        return rl.make_learner(method, params, trials, args.progress_bar, context)
    if method in BLACKBOX:
        from ilc_steering.agents import blackbox

        return blackbox.make_learner(method, context)
    if is_custom(method):
        learner = custom_factory(method)(context)
        if not isinstance(learner, Learner):
            raise ValueError(f"--methods {method}: made {type(learner).__name__}, which has no act, learn and reset")
        return learner
    raise ValueError(f"unknown method {method!r}; choose from {list(METHODS)} or give module:attr")


def measure(env: gym.Env[Any, Any], learner: Learner, trials: int, seed: int) -> dict[str, Any]:
    """Run ``learner`` on ``env`` for ``trials`` trials and return what it reached: the trials to
    each tolerance of :data:`LADDER`, the best true cost, the off-chart fraction, the wall time
    [s] and the best-so-far curve."""
    log = TrialLog()
    start = time.perf_counter()
    run_trials(env, learner, trials, seed=seed, callbacks=[log])
    wall = time.perf_counter() - start
    curve = best_so_far(log)
    return {
        "trials": len(log.cost),
        "off_chart_fraction": float(np.mean(log.left_chart)),
        "trials_to": {level: first_within(log, tolerance) for level, tolerance in LADDER.items()},
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
    unwrapped: Any = env.unwrapped
    config = unwrapped.config
    context = LearnerContext(
        unwrapped.nominal_model,
        unwrapped.action_space,
        unwrapped.observation_space,
        seed,
        config.learning.nu_a,
        config.learning.nu_b,
        prior=prior,
        cost=config.learning.cost,
    )
    trials = budget(args, prior, method, config.name)
    learner = make_learner(args, method, config.name, context)
    if context.cost != "none":
        from ilc_steering.agents.costs import with_cost

        learner = with_cost(learner, context)
    result = measure(env, learner, trials, seed)
    env.close()
    return {"prior": prior, "method": method, "scenario": config.name, "seed": seed, "budget": trials, **result}


def cell_path(out: Path, prior: str, method: str, scenario: str, seed: int) -> Path:
    return out / "cells" / f"{prior}__{safe_name(method)}__{scenario}__{seed}.json"


def validate(args: Args) -> dict[str, str]:
    """Check every argument and scenario before the first cell; returns scenario -> config name.

    ``ValueError`` names the argument: unknown or repeated priors, methods, scenarios or seeds, a
    user's learner that cannot be imported, a seed outside ``[0, 2**32)``, a cyclic config
    (``compare`` runs one-trial tasks), two scenarios of one name, a budget below 1, a negative
    worker count.
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
        if is_custom(method):
            custom_factory(method)
        elif method not in METHODS:
            raise ValueError(f"--methods: unknown method {method!r}; choose from {list(METHODS)} or give module:attr")
    bad = [s for s in args.seeds if isinstance(s, bool) or not isinstance(s, int) or not 0 <= s <= MAX_SEED]
    if bad:
        raise ValueError(f"--seeds: {bad[0]!r} is not a whole number in [0, {MAX_SEED}]")
    for option in ("model_trials", "blackbox_trials", "rl_trials", "custom_trials"):
        value = getattr(args, option)
        if value is not None and (isinstance(value, bool) or not isinstance(value, int) or value < 1):
            raise ValueError(f"--{option.replace('_', '-')}: the budget must be a whole number >= 1, got {value!r}")
    if isinstance(args.workers, bool) or not isinstance(args.workers, int) or args.workers < 0:
        raise ValueError(f"--workers: a whole number >= 0 (0: one per core), got {args.workers!r}")
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
    "best_error": float,
    "wall_s": float,
    "curve": list,
}


def read_cell(path: Path, key: dict[str, Any]) -> dict[str, Any]:
    """A finished cell, checked against its ``key`` (prior, method, scenario, seed, budget);
    ``ValueError`` names the file."""
    hint = "delete it to have the cell computed again"
    try:
        cell = json.loads(path.read_bytes().decode("utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as error:
        raise ValueError(f"{path}: not a readable cell ({type(error).__name__}: {error}); {hint}") from None
    if not isinstance(cell, dict):
        raise ValueError(f"{path}: not a cell (a JSON object); {hint}")
    for name, kind in CELL_KEYS.items():
        value = cell.get(name)
        ok = isinstance(value, (int, float)) if kind is float else isinstance(value, kind)
        if not ok or isinstance(value, bool):
            raise ValueError(f"{path}: {name!r} is missing or not a {kind.__name__}; {hint}")
    for name, value in key.items():
        if cell[name] != value:
            raise ValueError(f"{path}: holds {name} {cell[name]!r}, not {value!r}; {hint}")
    if not 1 <= cell["trials"] <= cell["budget"]:
        raise ValueError(f"{path}: {cell['trials']} trials for a budget of {cell['budget']}; {hint}")
    reached = cell["trials_to"]
    if sorted(reached) != sorted(LADDER) or not all(
        v is None or (isinstance(v, int) and 1 <= v <= cell["trials"]) for v in reached.values()
    ):
        raise ValueError(f"{path}: 'trials_to' needs {sorted(LADDER)}, each a trial or null; {hint}")
    return cell


def _check_run_folder(args: Args) -> None:
    """Record the settings; refuse to resume a folder written with different budgets or seeds."""
    skip = ("out", "progress_bar", "priors", "methods", "scenarios", "workers", "backend")
    settings = {k: v for k, v in asdict(args).items() if k not in skip}
    settings["seeds"] = list(settings["seeds"])
    cells = args.out / "cells"
    check_output_dir(args.out, "--out")
    if cells.exists() and not cells.is_dir():
        raise ValueError(f"{cells}: exists and is not a folder; this is not a compare run folder")
    resumed = check_run_settings(args.out, settings, cells)
    cells.mkdir(exist_ok=True)
    if resumed:
        _restore_cells(args.out)


def _restore_cells(folder: Path) -> None:
    """Write back the cells that the folder's ``compare.json`` holds and ``cells/`` lacks (a clone of a
    run whose cells were not kept): the settings matched, so they are the cells this run would compute.
    Each is checked like any resumed cell when it is read."""
    report = folder / "compare.json"
    if not report.is_file():
        return
    try:
        cells = json.loads(report.read_bytes().decode("utf-8")).get("cells", [])
    except (OSError, UnicodeDecodeError, json.JSONDecodeError, AttributeError) as error:
        raise ValueError(f"{report}: not readable ({error}); use another --out folder") from None
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
    """Every cell of the run, computing only those not yet in the run folder, in
    :func:`workers` processes (one with a custom ``runner``).

    Everything is validated before the first cell; each finished cell is written at once.
    """
    names = validate(args)
    _check_run_folder(args)
    keys: list[dict[str, Any]] = [
        {"prior": prior, "method": method, "scenario": name, "seed": seed, "budget": budget(args, prior, method, name)}
        for prior in args.priors
        for scenario, name in names.items()
        for method in args.methods
        for seed in args.seeds
    ]
    scenario_of = {name: scenario for scenario, name in names.items()}
    done: dict[int, dict[str, Any]] = {}
    with _locked(args.out):
        todo = []
        for index, key in enumerate(keys):
            path = cell_path(args.out, key["prior"], key["method"], key["scenario"], key["seed"])
            if path.exists():
                done[index] = read_cell(path, key)
            else:
                todo.append(index)

        def finish(index: int, cell: dict[str, Any]) -> None:
            key = keys[index]
            write_json(cell_path(args.out, key["prior"], key["method"], key["scenario"], key["seed"]), cell)
            done[index] = cell
            _progress(cell)

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
            run_calls(run_cell, calls, finish, args.backend, workers(args))
    return [done[index] for index in range(len(keys))]


def main(args: Args) -> list[dict[str, Any]]:
    if args.quick:  # the quick budgets, where no budget was given
        quick: dict[str, Any] = {k: v for k, v in QUICK.items() if getattr(args, k) == getattr(Args, k)}
        args = replace(args, **quick)
    cells = run_cells(args)
    names = list(validate(args).values())
    text = write_report(cells, names, args.out, {"black-box": BLACKBOX, "RL": RL})
    print(text)
    print(f"wrote {args.out}/compare.{{csv,json,md}}, compare_<scenario>.png and one file per cell in {args.out}/cells")
    return cells


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
        "--priors", nargs="+", default=list(PRIORS), help="nominal: start from the nominal solution; none: no prior"
    )
    parser.add_argument(
        "--methods",
        nargs="+",
        default=list(METHODS),
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
    parser.add_argument("--workers", type=int, default=0, help="worker processes (0: one per core)")
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
        priors=tuple(ns.priors),
        methods=tuple(ns.methods),
        scenarios=tuple(ns.scenarios),
        seeds=tuple(seeds),
        workers=ns.workers,
        progress_bar=ns.progress_bar,
        backend=ns.backend,
    )
    return replace(args, **budgets)


def parse(argv: list[str] | None = None) -> Args:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    add_arguments(parser)
    return from_namespace(parser.parse_args(argv))
