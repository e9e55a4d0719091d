"""Trials to tolerance: ILC against RL (SB3) and black-box optimizers, across seeds.

Every method is a :class:`~ilc_steering.agents.base.Learner` built from the same
:class:`~ilc_steering.agents.base.LearnerContext` (the nominal model and the env's spaces), run
on ``ilc_steering/ChainedSteering-v0`` by the one trial loop,
:func:`~ilc_steering.loop.run_trials`, which runs and counts every trial it asks for (probes
and random exploration included) up to the budget; a :class:`TrialLog` records the errors.
ILC acts in physical units; the black-box and RL methods, through
:class:`~ilc_steering.agents.adapters.PullLearner`, in the ``[-1, 1]`` box of ``RescaleAction``.

A run folder holds ``run.json`` (the arguments), ``cells/<method>__<scenario>__<seed>.json`` (one
per finished cell, written when it finishes) and, at the end, ``compare.{csv,json,md,png}``.
Running again on the same folder skips the finished cells: an interrupted run resumes and never
recomputes or loses a finished cell.

    ilc-steering compare [--quick] [--out DIR]
    python benchmarks/compare.py [--quick] [--out DIR]
"""

from __future__ import annotations

import argparse
import fcntl
import json
import math
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from ilc_steering.agents.base import Learner, LearnerContext
from ilc_steering.loop import run_trials
from ilc_steering.output import check_output_dir, write_json
from ilc_steering.tables import markdown_table, write_results

__all__ = ["Args", "TrialLog", "main", "make_learner", "parse", "run_cell"]

ENV_ID = "ilc_steering/ChainedSteering-v0"
LOOSE = (0.01, 0.01)  # [m], [rad]; a chained plant: 0.01 on ||z^d - z(T)||
TIGHT = (5e-4, 5e-4)  # [m], [rad]; a chained plant: 5e-4 on ||z^d - z(T)||
MAX_SEED = 2**32 - 1
METHODS = ("ilc", "gauss_newton", "nelder_mead", "cma_es", "ppo", "sac", "td3")
SCENARIOS = ("forward_parking", "forward_parking_saturated", "parallel_parking")


@dataclass(frozen=True)
class Args:
    quick: bool = False
    """Tiny budgets and two seeds: checks that everything runs and writes well-formed output (CI)."""
    out: Path = Path("runs/compare")
    """Run folder; an existing one is resumed."""
    methods: tuple[str, ...] = METHODS
    """Methods to compare."""
    scenarios: tuple[str, ...] = SCENARIOS
    """Packaged configs (simulations 1-3)."""
    seeds: tuple[int, ...] = (0, 1, 2, 3, 4)
    """Seeds; each (method, scenario, seed) is one cell."""
    ilc_trials: int = 30
    """Budget of the ILC agent [trials]."""
    blackbox_trials: int = 3000
    """Budget of each black-box optimizer [trials]."""
    rl_trials: int | None = None
    """Budget of each RL algorithm [trials]; None: ``n_timesteps`` of its hyperparameter file."""
    progress_bar: bool = True
    """SB3's progress bar on RL cells."""


QUICK = {"ilc_trials": 6, "blackbox_trials": 40, "rl_trials": 48, "progress_bar": False}
QUICK_SEEDS = (0, 1)


class TrialLog:
    """A trial-loop callback that keeps every trial's errors: Cartesian [m] and orientation [rad]
    for a robot with a pose, the chained error norm for a chained plant (``cartesian`` holds it
    then, ``orientation`` zeros), the cost every learner minimises, and whether it left the chart."""

    def __init__(self) -> None:
        self.cartesian: list[float] = []
        self.orientation: list[float] = []
        self.left_chart: list[bool] = []

    def __call__(self, k: int, info: dict[str, Any]) -> None:
        self.cartesian.append(float(info.get("cartesian_error", info["error_norm"])))
        self.orientation.append(float(info.get("orientation_error", 0.0)))
        self.left_chart.append(bool(info["left_chart"]))


def first_within(log: TrialLog, tolerance: tuple[float, float]) -> int | None:
    """The 1-based index of the first trial within ``tolerance`` (both errors; a chained plant:
    its error norm within the first), or None."""
    ok = (np.asarray(log.cartesian) <= tolerance[0]) & (np.asarray(log.orientation) <= tolerance[1])
    hits = np.flatnonzero(ok)
    return int(hits[0]) + 1 if hits.size else None


def best_so_far(log: TrialLog) -> list[list[float]]:
    """``[trial, best error]`` at every trial that improved the best cost (Cartesian + orientation
    error, or the chained error norm)."""
    error = np.asarray(log.cartesian) + np.asarray(log.orientation)
    best = np.minimum.accumulate(error)
    changed = np.flatnonzero(np.concatenate([[True], best[1:] < best[:-1]]))
    return [[int(i) + 1, float(best[i])] for i in changed]


def budget(args: Args, method: str, scenario: str) -> int:
    from ilc_steering.agents.rl import RL_ALGORITHMS, hyperparameters

    if method == "ilc":
        return args.ilc_trials
    if method in RL_ALGORITHMS:
        return args.rl_trials if args.rl_trials is not None else int(hyperparameters(method, scenario)["n_timesteps"])
    return args.blackbox_trials


def make_learner(args: Args, method: str, scenario: str, context: LearnerContext) -> Learner:
    """The learner of ``method`` for ``scenario`` (its config's name), built from ``context`` alone."""
    from ilc_steering.agents import blackbox, rl
    from ilc_steering.agents.ilc import make_ilc

    if method == "ilc":
        return make_ilc(context)
    if method in rl.RL_ALGORITHMS:
        params = rl.hyperparameters(method, scenario)
        return rl.make_learner(method, params, budget(args, method, scenario), args.progress_bar, context)
    if method in blackbox.BLACKBOX_METHODS:
        return blackbox.make_learner(method, context)
    raise ValueError(f"unknown method {method!r}; choose from {METHODS}")


def run_cell(args: Args, method: str, scenario: str, seed: int) -> dict[str, Any]:
    """One (method, scenario, seed) cell: the method's run within its budget, and what it reached."""
    env = gym.make(ENV_ID, config=scenario)
    unwrapped: Any = env.unwrapped
    config = unwrapped.config
    name = config.name
    trials = budget(args, method, name)
    context = LearnerContext(
        unwrapped.nominal_model,
        unwrapped.action_space,
        unwrapped.observation_space,
        seed,
        config.learning.nu_a,
        config.learning.nu_b,
    )
    learner = make_learner(args, method, name, context)
    log = TrialLog()
    start = time.perf_counter()
    run_trials(env, learner, trials, seed=seed, callbacks=[log])
    wall = time.perf_counter() - start
    curve = best_so_far(log)
    return {
        "method": method,
        "scenario": name,
        "seed": seed,
        "budget": trials,
        "trials": len(log.cartesian),
        "left_chart_fraction": float(np.mean(log.left_chart)) if log.left_chart else 0.0,
        "trials_to_loose": first_within(log, LOOSE),
        "trials_to_tight": first_within(log, TIGHT),
        "best_error": curve[-1][1],
        "wall_s": wall,
        "curve": curve,
    }


def cell_path(out: Path, method: str, scenario: str, seed: int) -> Path:
    return out / "cells" / f"{method}__{scenario}__{seed}.json"


def validate(args: Args) -> dict[str, str]:
    """Check every argument and scenario before the first cell; returns scenario -> config name.

    ``ValueError`` names the argument: unknown or repeated methods, scenarios or seeds, a seed
    outside ``[0, 2**32)``, a cyclic config (``compare`` runs one-trial tasks), two scenarios of
    one name, a budget below 1.
    """
    from ilc_steering.config import load_config

    for option, values in (("--methods", args.methods), ("--scenarios", args.scenarios), ("--seeds", args.seeds)):
        if not values:
            raise ValueError(f"{option}: give at least one")
        repeated = sorted({str(v) for v in values if list(values).count(v) > 1})
        if repeated:
            raise ValueError(f"{option}: {repeated[0]} is given twice; each cell is counted once")
    unknown = [m for m in args.methods if m not in METHODS]
    if unknown:
        raise ValueError(f"--methods: unknown method {unknown[0]!r}; choose from {list(METHODS)}")
    bad = [s for s in args.seeds if isinstance(s, bool) or not isinstance(s, int) or not 0 <= s <= MAX_SEED]
    if bad:
        raise ValueError(f"--seeds: {bad[0]!r} is not a whole number in [0, {MAX_SEED}]")
    for option, value in (("ilc_trials", args.ilc_trials), ("blackbox_trials", args.blackbox_trials)):
        if value < 1:
            raise ValueError(f"{option}: the budget must be >= 1 trial, got {value}")
    if args.rl_trials is not None and args.rl_trials < 1:
        raise ValueError(f"rl_trials: the budget must be >= 1 trial, got {args.rl_trials}")
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
    for method in args.methods:
        for name in names.values():
            budget(args, method, name)  # RL: its hyperparameters exist
    return names


CELL_KEYS = {
    "method": str,
    "scenario": str,
    "seed": int,
    "budget": int,
    "trials": int,
    "best_error": float,
    "wall_s": float,
    "curve": list,
}


def read_cell(path: Path, method: str, scenario: str, seed: int, budget: int) -> dict[str, Any]:
    """A finished cell, checked against its key and the run's budget; ``ValueError`` names the file."""
    hint = "delete it to have the cell computed again"
    try:
        cell = json.loads(path.read_bytes().decode("utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as error:
        raise ValueError(f"{path}: not a readable cell ({type(error).__name__}: {error}); {hint}") from None
    if not isinstance(cell, dict):
        raise ValueError(f"{path}: not a cell (a JSON object); {hint}")
    for key, kind in CELL_KEYS.items():
        value = cell.get(key)
        ok = isinstance(value, (int, float)) if kind is float else isinstance(value, kind)
        if not ok or isinstance(value, bool):
            raise ValueError(f"{path}: {key!r} is missing or not a {kind.__name__}; {hint}")
    expected = {"method": method, "scenario": scenario, "seed": seed, "budget": budget}
    for key, value in expected.items():
        if cell[key] != value:
            raise ValueError(f"{path}: holds {key} {cell[key]!r}, not {value!r}; {hint}")
    if not 1 <= cell["trials"] <= budget:
        raise ValueError(f"{path}: {cell['trials']} trials for a budget of {budget}; {hint}")
    return cell


def _check_run_folder(args: Args) -> None:
    """Record the arguments; refuse to resume a folder written with different budgets or seeds."""
    settings = {k: v for k, v in asdict(args).items() if k not in ("out", "progress_bar", "methods", "scenarios")}
    settings["seeds"] = list(settings["seeds"])
    stored_path = args.out / "run.json"
    cells = args.out / "cells"
    check_output_dir(args.out, "--out")
    if cells.exists() and not cells.is_dir():
        raise ValueError(f"{cells}: exists and is not a folder; this is not a compare run folder")
    if stored_path.exists():
        try:
            stored = json.loads(stored_path.read_bytes().decode("utf-8"))
        except (OSError, UnicodeDecodeError, json.JSONDecodeError) as error:
            raise ValueError(f"{stored_path}: not readable ({error}); use another --out folder") from None
        if stored != settings:
            raise ValueError(f"{stored_path} was written with {stored}, not {settings}: use another --out folder")
    elif cells.is_dir() and any(cells.glob("*.json")):
        raise ValueError(
            f"{args.out}: has cells but no run.json, so their settings cannot be checked: use another --out folder"
        )
    cells.mkdir(exist_ok=True)
    write_json(stored_path, settings)


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


def run_cells(args: Args, runner: Callable[[Args, str, str, int], dict[str, Any]] = run_cell) -> list[dict[str, Any]]:
    """Every cell of the run, computing only those not yet in the run folder.

    Everything is validated before the first cell; each finished cell is written at once.
    """
    names = validate(args)
    _check_run_folder(args)
    cells = []
    with _locked(args.out):
        for scenario, name in names.items():
            for method in args.methods:
                for seed in args.seeds:
                    path = cell_path(args.out, method, name, seed)
                    if path.exists():
                        cells.append(read_cell(path, method, name, seed, budget(args, method, name)))
                        continue
                    cell = runner(args, method, scenario, seed)
                    write_json(path, cell)
                    cells.append(cell)
                    reached = cell["trials_to_tight"] or "-"
                    print(
                        f"{name:26s} {method:13s} seed {seed}: best {cell['best_error']:.2e} "
                        f"(0.5 mm / 0.5 mrad reached at trial {reached}; - for not within the budget) "
                        f"in {cell['wall_s']:.1f} s",
                        flush=True,
                    )
    return cells


def _quartiles(values: list[float]) -> tuple[float, float, float]:
    """Quartiles as order statistics (no interpolation), so a seed that never reached the
    tolerance (``inf``) stays ``inf`` instead of turning the interpolation into NaN."""
    q1, q2, q3 = np.percentile(np.asarray(values, dtype=np.float64), [25, 50, 75], method="inverted_cdf")
    return float(q1), float(q2), float(q3)


def _count(values: list[float], budget: int) -> str:
    q1, q2, q3 = _quartiles(values)
    if math.isinf(q2):
        return f"> {budget}"

    def text(v: float) -> str:
        return f"> {budget}" if math.isinf(v) else f"{v:.0f}"

    return f"{q2:.0f} [{text(q1)}, {text(q3)}]"


@dataclass
class Summary:
    method: str
    scenario: str
    budget: int
    seeds: int
    loose: list[float] = field(default_factory=list)
    tight: list[float] = field(default_factory=list)
    best: list[float] = field(default_factory=list)
    wall: list[float] = field(default_factory=list)

    def row(self) -> dict[str, Any]:
        return {
            "method": self.method,
            "scenario": self.scenario,
            "budget": self.budget,
            "seeds": self.seeds,
            "reached_loose": int(np.isfinite(self.loose).sum()),
            "reached_tight": int(np.isfinite(self.tight).sum()),
            "trials_to_loose_q1_median_q3": _quartiles(self.loose),
            "trials_to_tight_q1_median_q3": _quartiles(self.tight),
            "best_error_q1_median_q3": _quartiles(self.best),
            "wall_s_median": float(np.median(self.wall)),
        }


def summarize(cells: list[dict[str, Any]]) -> list[Summary]:
    groups: dict[tuple[str, str], Summary] = {}
    for c in cells:
        s = groups.setdefault((c["scenario"], c["method"]), Summary(c["method"], c["scenario"], c["budget"], 0))
        s.seeds += 1
        s.loose.append(c["trials_to_loose"] if c["trials_to_loose"] is not None else math.inf)
        s.tight.append(c["trials_to_tight"] if c["trials_to_tight"] is not None else math.inf)
        s.best.append(c["best_error"])
        s.wall.append(c["wall_s"])
    return list(groups.values())


def report(summaries: list[Summary]) -> str:
    header = [
        "scenario",
        "method",
        "budget",
        "trials to 1 cm / 0.01 rad",
        "trials to 0.5 mm / 0.5 mrad",
        "best error [m + rad]",
        "wall [s]",
    ]
    rows = []
    for s in summaries:
        b1, b2, b3 = _quartiles(s.best)
        rows.append(
            [
                s.scenario,
                s.method,
                str(s.budget),
                f"{_count(s.loose, s.budget)} ({int(np.isfinite(s.loose).sum())}/{s.seeds})",
                f"{_count(s.tight, s.budget)} ({int(np.isfinite(s.tight).sum())}/{s.seeds})",
                f"{b2:.1e} [{b1:.1e}, {b3:.1e}]",
                f"{np.median(s.wall):.3g}",
            ]
        )
    note = (
        "\nMedian [interquartile range] across seeds (order statistics); "
        "(k/n): seeds that reached the tolerance within the budget. "
        "Every trial counts, probes and random exploration included. Best error: the lowest Cartesian error [m] "
        "+ orientation error [rad] of any trial within the budget.\n"
    )
    return markdown_table(header, rows, [False, False, True, True, True, True, True]) + note


def plot(cells: list[dict[str, Any]], scenarios: tuple[str, ...], path: Path) -> None:
    """Best error so far against trials, log-log: the median across seeds, the interquartile band shaded."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(scenarios), figsize=(5.5 * len(scenarios), 4.4), squeeze=False)
    methods = list(dict.fromkeys(c["method"] for c in cells))
    palette = plt.get_cmap("tab10").colors  # type: ignore[attr-defined]
    colours = dict(zip(methods, palette))
    for ax, scenario in zip(axes[0], scenarios):
        for method in methods:
            runs = [c for c in cells if c["scenario"] == scenario and c["method"] == method]
            if not runs:
                continue
            grid = np.unique(np.geomspace(1, max(r["trials"] for r in runs), 200).astype(int))
            values = np.array([_step_curve(r["curve"], r["trials"], grid) for r in runs])
            q1, q2, q3 = np.nanpercentile(values, [25, 50, 75], axis=0)
            ax.plot(grid, q2, color=colours[method], label=method)
            ax.fill_between(grid, q1, q3, color=colours[method], alpha=0.2, linewidth=0)
        for tol, style in ((sum(LOOSE), ":"), (sum(TIGHT), "--")):
            ax.axhline(tol, color="grey", linestyle=style, linewidth=0.8)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("trials")
        ax.set_ylabel("best Cartesian [m] + orientation [rad] error so far")
        ax.set_title(scenario)
        ax.grid(True, which="major", alpha=0.3)
    axes[0][0].legend(fontsize=8)
    fig.suptitle(
        "Best error against trials (median and interquartile range across seeds; "
        "dotted: 1 cm + 0.01 rad, dashed: 0.5 mm + 0.5 mrad)",
        fontsize=9,
    )
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _step_curve(curve: list[list[float]], trials: int, grid: np.ndarray) -> np.ndarray:
    """The best-so-far step function on ``grid`` (NaN past the run's last trial)."""
    at, best = np.array([p[0] for p in curve]), np.array([p[1] for p in curve])
    values = best[np.searchsorted(at, grid, side="right") - 1]
    return np.where(grid <= trials, values, np.nan)


def main(args: Args) -> list[dict[str, Any]]:
    if args.quick:
        args = Args(**{**asdict(args), **QUICK, "quick": True})
    cells = run_cells(args)
    names = list(validate(args).values())
    summaries = summarize(cells)
    text = report(summaries)
    rows = [{k: v for k, v in c.items() if k != "curve"} for c in cells]
    write_results(rows, args.out, "compare", text, {"summary": [s.row() for s in summaries], "cells": cells})
    plot(cells, tuple(names), args.out / "compare.png")
    print(text)
    print(f"wrote {args.out}/compare.{{csv,json,md,png}} and one file per cell in {args.out}/cells")
    return cells


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.formatter_class = argparse.ArgumentDefaultsHelpFormatter
    parser.add_argument(
        "--quick",
        action="store_true",
        help=f"tiny budgets ({QUICK['ilc_trials']} ILC, {QUICK['blackbox_trials']} black-box, {QUICK['rl_trials']} RL "
        f"trials) and, unless --seeds is given, seeds {' '.join(map(str, QUICK_SEEDS))}: checks that everything runs",
    )
    parser.add_argument("--out", type=Path, default=Args.out, help="run folder; an existing one is resumed")
    parser.add_argument("--methods", nargs="+", default=list(METHODS), help=f"any of {' '.join(METHODS)}")
    parser.add_argument(
        "--scenarios", nargs="+", default=list(SCENARIOS), help="packaged config names or YAML paths (one-trial tasks)"
    )
    parser.add_argument(
        "--seeds",
        type=int,
        nargs="+",
        default=argparse.SUPPRESS,
        help=f"whole numbers in [0, {MAX_SEED}] (default: 0 1 2 3 4; with --quick: 0 1)",
    )
    parser.add_argument("--no-progress-bar", action="store_true", help="no SB3 progress bar on RL cells")


def from_namespace(ns: argparse.Namespace) -> Args:
    given = getattr(ns, "seeds", None)
    seeds = given if given is not None else (QUICK_SEEDS if ns.quick else Args.seeds)
    return Args(
        quick=ns.quick,
        out=ns.out,
        methods=tuple(ns.methods),
        scenarios=tuple(ns.scenarios),
        seeds=tuple(seeds),
        progress_bar=not ns.no_progress_bar,
    )


def parse(argv: list[str] | None = None) -> Args:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_arguments(parser)
    return from_namespace(parser.parse_args(argv))
