"""Robustness maps: trials to tolerance of a learner over a grid of true plants.

Proposition 2 promises convergence "for sufficiently small" model error; a map shows where it
stops. Every point of the grid is a true robot, the config's with its two parameters
(``plant.factor_names``: a car's wheelbase and wheel radius) at the given ratios to the
*nominal* ones; the learner sees the nominal model only, the same at every point. A row of the
grid is one :class:`~ilc_steering.envs.steering_vector_env.ChainedSteeringVectorEnv` with
``true_factors``: one learner per plant, all stepped in lock-step, one compiled call per trial
index (:func:`lockstep`). Each finished row is written at once, so a sweep resumes where it
stopped, on the local machine or on Ray (``--backend ray``, see :mod:`ilc_steering.backends`).

    ilc-steering sweep forward_parking --methods ilc_paper newton --nu-b 1 0.5 --out runs/sweep

writes ``sweep.json`` / ``sweep.csv`` / ``sweep.md``, a heat map ``sweep_<method>_nu<b>.png``
per map and one file per row under ``rows/``.
"""

from __future__ import annotations

import argparse
import json
import time
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from ilc_steering.agents.base import Learner, LearnerContext
from ilc_steering.config import load_config
from ilc_steering.core.score import TRUE_KEYS, within_tolerance
from ilc_steering.envs.scenario import Scenario
from ilc_steering.output import check_output_dir, check_run_settings, safe_name, write_figure, write_json

__all__ = ["SweepArgs", "lockstep", "main", "run_row"]

Array = npt.NDArray[np.float64]
MAX_GRID = 201
"""The most points per axis: 201 x 201 plants is 40,401 learners."""


@dataclass(frozen=True)
class SweepArgs:
    config: str = "forward_parking"
    """A packaged config name or a YAML path (a one-trial task)."""
    methods: tuple[str, ...] = ("ilc_paper",)
    """Learners: any ``compare`` method but the RL ones, or module:attr."""
    nu_b: tuple[float, ...] = ()
    """Gains of eq. 34 to map (each a map); empty: the config's."""
    grid: int = 41
    """Points per axis."""
    low: float = 0.5
    """Smallest ratio true / nominal on both axes."""
    high: float = 1.5
    """Largest ratio."""
    trials: int = 30
    """Budget per plant [trials]."""
    out: Path = Path("results/sweep")
    """Run folder; an existing one with the same settings is resumed."""
    backend: str = "local"
    """``local`` (worker processes) or ``ray``."""
    workers: int = 0
    """Local worker processes (0: one per core)."""
    seed: int = 0
    """Seed of every learner's own randomness."""


def lockstep(envs: Any, learners: list[Learner], trials: int, tolerance: Any, seed: int = 0) -> dict[str, Array]:
    """Run ``learners[i]`` on env ``i`` of the vector env ``envs``, every learner one trial per
    step, for at most ``trials`` steps (fewer once all are within ``tolerance``).

    Each learner gets its own trial's ``info`` without the true errors, as from
    :func:`ilc_steering.loop.run_trials`. Returns per env ``trials_to`` (the first trial within
    tolerance, 0 for none), ``error`` (the true error norm of the last trial) and ``left_chart``
    (the fraction of trials that left the chart)."""
    count = envs.num_envs
    if len(learners) != count:
        raise ValueError(f"lockstep: one learner per env is needed ({count}), got {len(learners)}")
    observations, _ = envs.reset(seed=seed)
    first = np.zeros(count, dtype=np.int64)
    error = np.full(count, np.nan)
    off_chart = np.zeros(count)
    run = 0
    for k in range(1, trials + 1):
        run = k
        actions = np.array([learner.act(obs) for learner, obs in zip(learners, observations)])
        observations, _, _, _, info = envs.step(actions)
        final = info["final_info"]
        keys = [key for key in final if not key.startswith("_")]
        for i, learner in enumerate(learners):
            row = {key: final[key][i] for key in keys}
            learner.learn({key: value for key, value in row.items() if key not in TRUE_KEYS})
            if first[i] == 0 and within_tolerance(tolerance, row):
                first[i] = k
        error = np.asarray(final["true_error_norm"], dtype=np.float64)
        off_chart += np.asarray(final["left_chart"], dtype=np.float64)
        if np.all(first > 0):
            break
    return {"trials_to": first, "error": error, "left_chart": off_chart / run}


def ratios(args: SweepArgs) -> Array:
    return np.linspace(args.low, args.high, args.grid)


def run_row(args: SweepArgs, method: str, nu_b: float | None, row: int) -> dict[str, Any]:
    """Row ``row`` of the map of ``method`` (gain ``nu_b``, ``None`` for the config's): the first
    factor at ``ratios[row]``, the second at every ratio."""
    from ilc_steering.compare import Args as CompareArgs
    from ilc_steering.compare import make_learner
    from ilc_steering.envs.steering_vector_env import ChainedSteeringVectorEnv

    config = load_config(args.config)
    axis = ratios(args)
    grid = np.column_stack([np.full(axis.size, axis[row]), axis])
    base = config.plant.plant().true_factors()  # the config's true plant: the grid is against the nominal
    envs = ChainedSteeringVectorEnv(axis.size, config, true_factors=grid / base)
    learning = config.learning
    context = LearnerContext(
        envs.nominal_model,
        envs.single_action_space,  # type: ignore[arg-type]
        envs.single_observation_space,  # type: ignore[arg-type]
        args.seed,
        learning.nu_a,
        learning.nu_b if nu_b is None else nu_b,
        cost=learning.cost,
    )
    learners = [make_learner(CompareArgs(), method, config.name, context) for _ in range(axis.size)]
    start = time.perf_counter()
    try:
        result = lockstep(envs, learners, args.trials, learning.tolerance, args.seed)
    finally:
        for learner in learners:
            close = getattr(learner, "close", None)
            if callable(close):
                close()
    return {
        "method": method,
        "nu_b": context.nu_b,
        "row": row,
        "trials_to": result["trials_to"].tolist(),
        "error": result["error"].tolist(),
        "left_chart": result["left_chart"].tolist(),
        "wall_s": time.perf_counter() - start,
    }


def _validate(args: SweepArgs) -> tuple[str, list[str]]:
    from ilc_steering.compare import BLACKBOX, MODEL_METHODS, RL, is_custom

    config = load_config(args.config)
    if config.is_cyclic:
        raise ValueError(f"{args.config}: a cyclic config; sweep maps one-trial tasks")
    Scenario.from_config(config).refuse_disturbances("sweep")
    for name, value, lo, hi in (("--grid", args.grid, 2, MAX_GRID), ("--trials", args.trials, 1, 100_000)):
        if isinstance(value, bool) or not isinstance(value, int) or not lo <= value <= hi:
            raise ValueError(f"{name} must be a whole number in [{lo}, {hi}], got {value!r}")
    if not (np.isfinite(args.low) and np.isfinite(args.high) and 0 < args.low < args.high <= 100):
        raise ValueError(f"--range must be two ratios 0 < low < high <= 100, got {args.low} {args.high}")
    for gain in args.nu_b:
        if not (np.isfinite(gain) and 0 < gain <= 2):
            raise ValueError(f"--nu-b must be gains in (0, 2], got {gain}")
    if args.backend not in ("local", "ray"):
        raise ValueError(f"--backend must be local or ray, got {args.backend!r}")
    if not args.methods:
        raise ValueError("--methods: give at least one")
    for method in args.methods:
        if method in RL:
            raise ValueError(
                f"--methods {method}: RL trains a network per plant; sweep maps {MODEL_METHODS + BLACKBOX}"
            )
        if method not in MODEL_METHODS + BLACKBOX and not is_custom(method):
            raise ValueError(f"--methods: unknown method {method!r}; choose from {list(MODEL_METHODS + BLACKBOX)}")
    return config.name, list(config.plant.plant().factor_names)


def row_path(out: Path, method: str, nu_b: float, row: int) -> Path:
    return out / "rows" / f"{safe_name(method)}__nu{nu_b:g}__{row:03d}.json"


def _check_folder(args: SweepArgs) -> None:
    """Record the settings; refuse to resume a folder written with others."""
    settings = {k: v for k, v in asdict(args).items() if k not in ("out", "methods", "nu_b", "backend", "workers")}
    settings["config"] = load_config(args.config).name
    check_output_dir(args.out, "--out")
    rows = args.out / "rows"
    if rows.exists() and not rows.is_dir():
        raise ValueError(f"{rows}: exists and is not a folder; this is not a sweep run folder")
    check_run_settings(args.out, settings, rows)
    rows.mkdir(exist_ok=True)


def _read_row(path: Path, size: int) -> dict[str, Any]:
    try:
        row = json.loads(path.read_bytes().decode("utf-8"))
        ok = all(len(row[key]) == size for key in ("trials_to", "error", "left_chart"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError, KeyError, TypeError) as error:
        raise ValueError(f"{path}: not a sweep row ({error}); delete it to recompute it") from None
    if not ok:
        raise ValueError(f"{path}: not a row of {size} plants; delete it to recompute it")
    return row  # type: ignore[no-any-return]


def run_rows(args: SweepArgs) -> dict[tuple[str, float], list[dict[str, Any]]]:
    """Every row of every map, computing only those not yet in the run folder."""
    from ilc_steering.backends import run_calls

    _validate(args)
    _check_folder(args)
    gains: list[float | None] = list(args.nu_b) or [None]
    config_gain = load_config(args.config).learning.nu_b
    keys = [(m, config_gain if g is None else g, g, r) for m in args.methods for g in gains for r in range(args.grid)]
    rows: dict[tuple[str, float, int], dict[str, Any]] = {}
    todo = {}
    for method, gain, given, row in keys:
        path = row_path(args.out, method, gain, row)
        if path.exists():
            rows[method, gain, row] = _read_row(path, args.grid)
        else:
            todo[method, gain, row] = (args, method, given, row)

    def finish(key: tuple[str, float, int], result: dict[str, Any]) -> None:
        write_json(row_path(args.out, *key), result)
        rows[key] = result

    run_calls(run_row, todo, finish, args.backend, args.workers)
    maps: dict[tuple[str, float], list[dict[str, Any]]] = {}
    for method, gain, _, row in keys:
        maps.setdefault((method, gain), []).append(rows[method, gain, row])
    return maps


def summary(args: SweepArgs, maps: dict[tuple[str, float], list[dict[str, Any]]]) -> list[dict[str, Any]]:
    """One line per map: where it converged, and how fast."""
    lines = []
    axis = ratios(args)
    centre = int(np.argmin(np.abs(axis - 1.0)))
    for (method, gain), rows in maps.items():
        first = np.array([row["trials_to"] for row in rows])
        ok = first > 0
        lines.append(
            {
                "method": method,
                "nu_b": gain,
                "converged_fraction": float(ok.mean()),
                "median_trials": float(np.median(first[ok])) if ok.any() else None,
                "max_trials": int(first[ok].max()) if ok.any() else None,
                "at_nominal": int(first[centre, centre]) or None,
                "wall_s": float(sum(row["wall_s"] for row in rows)),
            }
        )
    return lines


def plot_map(
    args: SweepArgs, method: str, gain: float, rows: list[dict[str, Any]], names: list[str], path: Path
) -> None:
    """The heat map of one map: trials to tolerance over the grid, grey where not within budget."""
    import matplotlib
    from matplotlib.figure import Figure

    first = np.array([row["trials_to"] for row in rows], dtype=np.float64)
    first[first == 0] = np.nan
    axis = ratios(args)
    half = 0.5 * (axis[1] - axis[0])
    fig = Figure(figsize=(5.6, 4.6))
    ax = fig.subplots()
    cmap = matplotlib.colormaps["viridis"].with_extremes(bad="#d0d0d0")
    extent = (axis[0] - half, axis[-1] + half, axis[0] - half, axis[-1] + half)
    image = ax.imshow(first, origin="lower", extent=extent, cmap=cmap, aspect="auto", vmin=1)
    fig.colorbar(image, ax=ax, label=f"trials to tolerance (grey: not within {args.trials})")
    ax.plot([1.0], [1.0], "r+", markersize=12)
    ax.set_xlabel(f"{names[1]} (true / nominal)")
    ax.set_ylabel(f"{names[0]} (true / nominal)")
    ax.set_title(f"{load_config(args.config).name}: {method}, nu_b = {gain:g}")
    fig.tight_layout()
    write_figure(path, fig, dpi=90)


def main(args: SweepArgs) -> list[dict[str, Any]]:
    from ilc_steering.tables import markdown_table, write_results

    start = time.perf_counter()
    maps = run_rows(args)
    _, names = _validate(args)
    lines = summary(args, maps)
    for (method, gain), rows in maps.items():
        plot_map(args, method, gain, rows, names, args.out / f"sweep_{safe_name(method)}_nu{gain:g}.png")
    header = ["method", "nu_b", "converged", "median trials", "most trials", "at the nominal plant", "cell time [s]"]
    cells = [
        [
            line["method"],
            f"{line['nu_b']:g}",
            f"{100 * line['converged_fraction']:.1f} %",
            "-" if line["median_trials"] is None else f"{line['median_trials']:g}",
            "-" if line["max_trials"] is None else str(line["max_trials"]),
            "-" if line["at_nominal"] is None else str(line["at_nominal"]),
            f"{line['wall_s']:.1f}",
        ]
        for line in lines
    ]
    table = markdown_table(header, cells, [False, True, True, True, True, True, True])
    grid = {f"{method}__nu{gain:g}": [row["trials_to"] for row in rows] for (method, gain), rows in maps.items()}
    extra = {"settings": {**asdict(args), "out": None}, "axes": names}
    write_results(lines, args.out, "sweep", table, {**extra, "ratios": ratios(args).tolist(), "maps": grid})
    print(table)
    print(
        f"{args.grid} x {args.grid} plants per map, {len(maps)} maps in {time.perf_counter() - start:.1f} s; "
        f"wrote {args.out}/sweep.{{csv,json,md}}, sweep_<method>_nu<b>.png and rows/"
    )
    return lines


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.formatter_class = argparse.ArgumentDefaultsHelpFormatter
    parser.add_argument("config", help="a packaged config name or a YAML path (one-trial task)")
    parser.add_argument("--methods", nargs="+", default=list(SweepArgs.methods), help="learners to map")
    parser.add_argument(
        "--nu-b", type=float, nargs="+", default=[], help="gains of eq. 34, a map each (default: the config's)"
    )
    parser.add_argument("--grid", type=int, default=SweepArgs.grid, help="points per axis")
    parser.add_argument(
        "--range",
        type=float,
        nargs=2,
        default=[SweepArgs.low, SweepArgs.high],
        metavar=("LOW", "HIGH"),
        help="ratios true / nominal on both axes",
    )
    parser.add_argument("--trials", type=int, default=SweepArgs.trials, help="budget per plant")
    parser.add_argument("--out", type=Path, default=SweepArgs.out, help="run folder; an existing one is resumed")
    parser.add_argument(
        "--backend",
        default="local",
        help="local worker processes, or Ray tasks (ray.init(): RAY_ADDRESS for a cluster)",
    )
    parser.add_argument("--workers", type=int, default=0, help="local worker processes (0: one per core)")


def from_namespace(ns: argparse.Namespace) -> SweepArgs:
    return SweepArgs(
        config=ns.config,
        methods=tuple(ns.methods),
        nu_b=tuple(ns.nu_b),
        grid=ns.grid,
        low=ns.range[0],
        high=ns.range[1],
        trials=ns.trials,
        out=ns.out,
        backend=ns.backend,
        workers=ns.workers,
    )
