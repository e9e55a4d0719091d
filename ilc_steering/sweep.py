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
per map and one file per row under ``rows/`` (file names injective in the method and the gain:
:func:`gain_text`, :func:`~ilc_steering.output.injective_name`). ``run.json`` holds the settings,
the package version and the config's content hash: a resume with another config of the same
name, or other settings, is refused, saying which; every resumed row is checked value by value
(:func:`read_row`). Repeated methods or gains are refused. A row that raises or outlives
``--cell-timeout`` is recorded under ``failed/`` with its error, its map left out of the summary,
and the others are finished.
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import asdict, dataclass, replace
from dataclasses import fields as dataclass_fields
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from ilc_steering import __version__
from ilc_steering.agents.base import Learner, LearnerContext, close_learner
from ilc_steering.agents.registry import METHODS, REGISTRY, is_custom, lookup
from ilc_steering.backends import MAX_WORKERS, check_workers
from ilc_steering.config import SteeringConfig, load_config
from ilc_steering.core.plants import Plant
from ilc_steering.core.score import TRUE_KEYS, within_tolerance
from ilc_steering.envs.scenario import Scenario
from ilc_steering.inputs import read_json
from ilc_steering.oracle import SOLVED
from ilc_steering.output import (
    MAX_RESULT_BYTES,
    check_output_dir,
    check_run_settings,
    content_hash,
    injective_name,
    write_figure,
    write_json,
)

__all__ = ["SweepArgs", "gain_text", "lockstep", "main", "main_with_failures", "read_row", "run_row"]

Array = npt.NDArray[np.float64]
Mask = npt.NDArray[np.bool_]
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
    cell_timeout: float | None = None
    """[s] a row still running after this is stopped and recorded as failed; None: no limit."""
    axes: tuple[tuple[str, float, float], ...] = ()
    """Two plant keys with their ranges ``(key, low, high)`` [the key's unit], e.g.
    ``("steering_offset", -0.03, 0.03)``; empty: the plant's two ``factor_names`` as ratios
    ``low``-``high`` to the nominal ones."""
    oracle: bool = False
    """Also map where the true plant can reach the goal at all (:mod:`ilc_steering.oracle`, which
    knows the true plant: never a learner), and report every map's share of that region."""


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
    """The values of the first axis (and of the second: both axes share the grid's size)."""
    return np.linspace(args.low, args.high, args.grid)


def axis_values(args: SweepArgs) -> tuple[Array, Array]:
    """The grid's values on each axis: ratios to the nominal parameters, or the given keys' values."""
    if not args.axes:
        return ratios(args), ratios(args)
    return tuple(np.linspace(low, high, args.grid) for _, low, high in args.axes)  # type: ignore[return-value]


def centre_values(args: SweepArgs, config: SteeringConfig) -> tuple[float, float]:
    """Where the map is centred: the nominal parameters (ratio 1), or the config's own values of the keys."""
    if not args.axes:
        return 1.0, 1.0
    return tuple(float(getattr(config.plant, key) or 0.0) for key, _, _ in args.axes)  # type: ignore[return-value]


def row_plants(args: SweepArgs, config: SteeringConfig, row: int, reach: float = 1.0) -> list[Plant]:
    """The true plants of row ``row``: the first axis at its ``row``-th value, the second at each
    of its values; ``reach`` < 1 moves them that fraction of the way from the centre plant
    (:func:`centre_values`), for the oracle's continuation."""
    first, second = axis_values(args)
    c0, c1 = centre_values(args, config)
    a = c0 + reach * (first[row] - c0)
    points = [(a, c1 + reach * (b - c1)) for b in second]
    if not args.axes:
        plant = config.plant.plant()
        base = plant.true_factors()  # the config's true plant: the grid is against the nominal
        return [plant.with_true_factors(np.array(point) / base) for point in points]
    (k0, _, _), (k1, _, _) = args.axes
    plant_config: Any = config.plant  # a robot's config dataclass (the PlantConfig protocol)
    return [replace(plant_config, **{k0: float(x), k1: float(y)}).plant() for x, y in points]


def centre_row(args: SweepArgs, config: SteeringConfig) -> int:
    return int(np.argmin(np.abs(axis_values(args)[0] - centre_values(args, config)[0])))


def run_row(args: SweepArgs, method: str, nu_b: float | None, row: int) -> dict[str, Any]:
    """Row ``row`` of the map of ``method`` (gain ``nu_b``, ``None`` for the config's): the first
    axis at its ``row``-th value, the second at every value."""
    from ilc_steering.envs.steering_vector_env import ChainedSteeringVectorEnv

    config = load_config(args.config)
    envs = ChainedSteeringVectorEnv(args.grid, config, true_plants=row_plants(args, config, row))
    context = LearnerContext.from_env(envs, seed=args.seed, nu_b=nu_b)
    spec = lookup(method)
    learners = [spec.make(context, args.trials) for _ in range(args.grid)]
    start = time.perf_counter()
    try:
        result = lockstep(envs, learners, args.trials, config.learning.tolerance, args.seed)
    finally:
        for learner in learners:
            close_learner(learner)
    return {
        "method": method,
        "nu_b": context.nu_b,
        "row": row,
        "trials_to": result["trials_to"].tolist(),
        "error": result["error"].tolist(),
        "left_chart": result["left_chart"].tolist(),
        "wall_s": time.perf_counter() - start,
    }


def run_oracle(args: SweepArgs) -> dict[str, Any]:
    """The oracle's map (it knows the true plant; see :mod:`ilc_steering.oracle`)."""
    from ilc_steering.oracle import oracle_map

    config = load_config(args.config)
    scenario = Scenario.from_config(config)
    start = time.perf_counter()
    found = oracle_map(
        scenario, lambda row, reach: row_plants(args, config, row, reach), args.grid, centre_row(args, config)
    )
    return {**found, "wall_s": time.perf_counter() - start}


def _validate(args: SweepArgs) -> tuple[str, list[str]]:
    config = load_config(args.config)
    if config.is_cyclic:
        raise ValueError(f"{args.config}: a cyclic config; sweep maps one-trial tasks")
    Scenario.from_config(config).refuse_disturbances("sweep")
    import gymnasium as gym

    from ilc_steering.runner import ENV_ID, check_task

    env = gym.make(ENV_ID, config=config)
    check_task(env, args.config)
    env.close()
    for name, value, lo, hi in (("--grid", args.grid, 2, MAX_GRID), ("--trials", args.trials, 1, 100_000)):
        if isinstance(value, bool) or not isinstance(value, int) or not lo <= value <= hi:
            raise ValueError(f"{name} must be a whole number in [{lo}, {hi}], got {value!r}")
    if not (np.isfinite(args.low) and np.isfinite(args.high) and 0 < args.low < args.high <= 100):
        raise ValueError(f"--range must be two ratios 0 < low < high <= 100, got {args.low} {args.high}")
    for gain in args.nu_b:
        if not (np.isfinite(gain) and 0 < gain <= 2):
            raise ValueError(f"--nu-b must be gains in (0, 2], got {gain}")
    for option, values in (("--methods", args.methods), ("--nu-b", args.nu_b)):
        repeated = sorted({str(v) for v in values if list(values).count(v) > 1})
        if repeated:
            raise ValueError(f"{option}: {repeated[0]} is given twice; each map is computed once")
    check_workers(args.workers)
    timeout = args.cell_timeout
    if timeout is not None and not (isinstance(timeout, (int, float)) and np.isfinite(timeout) and timeout > 0):
        raise ValueError(f"--cell-timeout: a time limit > 0 s, got {timeout!r}")
    if args.backend not in ("local", "ray"):
        raise ValueError(f"--backend must be local or ray, got {args.backend!r}")
    if not args.methods:
        raise ValueError("--methods: give at least one")
    mappable = [i for i in METHODS if REGISTRY[i].family != "RL"]
    for method in args.methods:
        if method in REGISTRY and REGISTRY[method].family == "RL":
            raise ValueError(f"--methods {method}: RL trains a network per plant; sweep maps {tuple(mappable)}")
        if method not in REGISTRY and not is_custom(method):
            raise ValueError(f"--methods: unknown method {method!r}; choose from {mappable}")
    if not args.axes:
        return config.name, list(config.plant.plant().factor_names)
    _check_axes(args, config)
    return config.name, [key for key, _, _ in args.axes]


def _check_axes(args: SweepArgs, config: SteeringConfig) -> None:
    """Two distinct numeric keys of the config's plant, each with a range, every plant of the grid
    valid and of one kind (one compiled call per row)."""
    if len(args.axes) != 2:
        raise ValueError(f"--axis: give exactly two (KEY LOW HIGH each), got {len(args.axes)}")
    keys = [key for key, _, _ in args.axes]
    if keys[0] == keys[1]:
        raise ValueError(f"--axis: {keys[0]} is given twice; a map has two different axes")
    plant_config: Any = config.plant
    fields = {f.name for f in dataclass_fields(plant_config)} - {"model"}
    for key, low, high in args.axes:
        if key not in fields:
            raise ValueError(f"--axis {key}: not a key of this plant; choose from {sorted(fields)}")
        if not (np.isfinite(low) and np.isfinite(high) and low < high):
            raise ValueError(f"--axis {key}: a range LOW < HIGH of finite numbers, got {low} {high}")
    from ilc_steering.config import ConfigError

    own = config.plant.plant()
    kind = (id(own.kernel()[0]), own.state_dim)
    for row in range(args.grid):
        try:
            plants = row_plants(args, config, row)
        except (ConfigError, ValueError, TypeError) as error:
            raise ValueError(f"--axis: the grid holds an invalid plant: {error}") from None
        if any((id(plant.kernel()[0]), plant.state_dim) != kind for plant in plants):
            raise ValueError(
                "--axis: the grid holds plants of another kind than the config's (a car with and without a "
                "servo, say: a steering offset of exactly 0 without a lag); shift the range or give the config a lag"
            )


def gain_text(gain: float) -> str:
    """``gain`` as ``:g`` text where that is the gain exactly (``1``, ``0.5``), else its ``repr``:
    two gains never share a text, so never a file."""
    short = f"{gain:g}"
    return short if float(short) == gain else repr(float(gain))


def map_name(method: str, gain: float) -> str:
    """The file-name part of the map of ``method`` at ``gain``: injective in both."""
    return f"{injective_name(method, METHODS)}_nu{gain_text(gain)}"


def row_path(out: Path, method: str, nu_b: float, row: int, folder: str = "rows") -> Path:
    return out / folder / f"{injective_name(method, METHODS)}__nu{gain_text(nu_b)}__{row:03d}.json"


def _check_folder(args: SweepArgs) -> str:
    """Record the settings, the version and the config's content hash; refuse to resume a folder
    written with others. Returns the content hash."""
    skip = ("out", "methods", "nu_b", "backend", "workers", "cell_timeout", "oracle")
    settings = {k: v for k, v in asdict(args).items() if k not in skip}
    settings["axes"] = [list(axis) for axis in args.axes]
    config = load_config(args.config)
    settings["config"] = config.name
    settings["version"] = __version__
    digest = content_hash(asdict(config))
    check_output_dir(args.out, "--out")
    rows = args.out / "rows"
    if rows.exists() and not rows.is_dir():
        raise ValueError(f"{rows}: exists and is not a folder; this is not a sweep run folder")
    check_run_settings(args.out, settings, rows, {config.name: digest})
    rows.mkdir(exist_ok=True)
    return digest


def read_row(path: Path, key: dict[str, Any], size: int, trials: int) -> dict[str, Any]:
    """A finished row, checked against its ``key`` (method, gain, row, config hash, version) and
    value by value: ``size`` plants, ``trials_to`` in ``[0, trials]``, errors >= 0 (not NaN),
    off-chart fractions in [0, 1], a wall time >= 0 s. ``ValueError`` names the file."""
    hint = "delete it to recompute it"
    try:
        row = read_json(path, MAX_RESULT_BYTES)
    except ValueError as error:
        raise ValueError(f"not a sweep row: {error}; {hint}") from None
    lists = ("trials_to", "error", "left_chart")
    if not isinstance(row, dict) or not all(isinstance(row.get(k), list) for k in lists):
        raise ValueError(f"{path}: not a sweep row (a JSON object with {list(lists)}); {hint}")
    if not all(len(row[k]) == size for k in lists):
        raise ValueError(f"{path}: not a row of {size} plants; {hint}")
    for name, value in key.items():
        if row.get(name) != value:
            raise ValueError(f"{path}: holds {name} {row.get(name)!r}, not {value!r}; {hint}")

    def number(v: Any) -> bool:
        return isinstance(v, (int, float)) and not isinstance(v, bool)

    problem = None
    if not all(number(t) and float(t).is_integer() and 0 <= t <= trials for t in row["trials_to"]):
        problem = f"trials_to holds a value outside the whole numbers 0 to the budget {trials}"
    elif not all(number(e) and e >= 0 for e in row["error"]):  # NaN fails e >= 0
        problem = "error holds a value that is not an error >= 0"
    elif not all(number(f) and 0 <= f <= 1 for f in row["left_chart"]):
        problem = "left_chart holds a value outside the fractions [0, 1]"
    elif not (number(row.get("wall_s")) and np.isfinite(row["wall_s"]) and row["wall_s"] >= 0):
        problem = f"wall_s {row.get('wall_s')!r} is not a time >= 0 s"
    if problem:
        raise ValueError(f"{path}: {problem}; {hint}")
    return row


ORACLE = "oracle"
"""The oracle's name in a sweep's results: it knows the true plant, and it is not a learner."""


def read_oracle(path: Path, key: dict[str, Any], size: int) -> dict[str, Any]:
    """The oracle's map, checked against its ``key`` and its shape; ``ValueError`` names the file."""
    hint = "delete it to recompute it"
    try:
        found = read_json(path, MAX_RESULT_BYTES)
    except ValueError as problem:
        raise ValueError(f"not an oracle map: {problem}; {hint}") from None
    if not isinstance(found, dict):
        raise ValueError(f"{path}: not an oracle map (a JSON object); {hint}")
    for name, value in key.items():
        if found.get(name) != value:
            raise ValueError(f"{path}: holds {name} {found.get(name)!r}, not {value!r}; {hint}")
    solvable: Any = found.get("solvable")
    errors: Any = found.get("error")
    shape_ok = all(
        isinstance(grid, list) and len(grid) == size and all(isinstance(r, list) and len(r) == size for r in grid)
        for grid in (solvable, errors)
    )
    if not shape_ok:
        raise ValueError(f"{path}: not a {size} x {size} oracle map; {hint}")
    if not all(isinstance(v, bool) for r in solvable for v in r):
        raise ValueError(f"{path}: solvable holds a value that is not true or false; {hint}")
    if not all(v is None or (isinstance(v, (int, float)) and v >= 0) for r in errors for v in r):
        raise ValueError(f"{path}: error holds a value that is not an error >= 0 or null; {hint}")
    if any(s != (e is not None and e < SOLVED) for rs, re in zip(solvable, errors) for s, e in zip(rs, re)):
        raise ValueError(f"{path}: solvable disagrees with error < {SOLVED:g}; {hint}")
    return found


def run_rows(args: SweepArgs) -> dict[tuple[str, float], list[dict[str, Any]]]:
    """Every row of every map, computing only those not yet in the run folder (the complete maps)."""
    return run_all(args)[0]


def run_all(args: SweepArgs) -> tuple[dict[tuple[str, float], list[dict[str, Any]]], list[dict[str, Any]]]:
    """The complete maps, and the rows that failed (each written to ``failed/`` with its error);
    each finished row is written the moment it finishes."""
    from ilc_steering.backends import run_calls
    from ilc_steering.runner import step_warning

    _validate(args)
    warning = step_warning(load_config(args.config))
    if warning is not None:
        print(f"ilc-steering: {warning}", file=sys.stderr, flush=True)
    digest = _check_folder(args)
    gains: list[float | None] = list(args.nu_b) or [None]
    config_gain = load_config(args.config).learning.nu_b
    keys = [(m, config_gain if g is None else g, g, r) for m in args.methods for g in gains for r in range(args.grid)]
    rows: dict[tuple[str, float, int], dict[str, Any]] = {}
    failed: dict[tuple[str, float, int], dict[str, Any]] = {}
    todo = {}

    def expected(method: str, gain: float, row: int) -> dict[str, Any]:
        return {"method": method, "nu_b": gain, "row": row, "config_sha": digest, "version": __version__}

    for method, gain, given, row in keys:
        path = row_path(args.out, method, gain, row)
        if path.exists():
            rows[method, gain, row] = read_row(path, expected(method, gain, row), args.grid, args.trials)
        else:
            todo[method, gain, row] = (args, method, given, row)

    def finish(key: tuple[str, float, int], result: dict[str, Any]) -> None:
        result = {**result, "config_sha": digest, "version": __version__}
        write_json(row_path(args.out, *key), result)
        row_path(args.out, *key, folder="failed").unlink(missing_ok=True)
        rows[key] = result

    def fail(key: tuple[str, float, int], message: str) -> None:
        method, gain, row = key
        failed[key] = {"method": method, "nu_b": gain, "row": row, "error": message}
        path = row_path(args.out, *key, folder="failed")
        path.parent.mkdir(exist_ok=True)
        write_json(path, failed[key])
        print(f"{method} nu_b {gain_text(gain)} row {row}: FAILED, recorded in {path}: {message}", flush=True)

    if args.oracle:
        oracle_path = args.out / "oracle.json"
        key = {"method": ORACLE, "config_sha": digest, "version": __version__}
        if oracle_path.exists():
            read_oracle(oracle_path, key, args.grid)
        else:
            print(f"{ORACLE}: where the true plant can reach the goal (it knows the true plant) ...", flush=True)
            write_json(oracle_path, {**key, **run_oracle(args)})
    run_calls(run_row, todo, finish, args.backend, args.workers, fail, args.cell_timeout)
    maps: dict[tuple[str, float], list[dict[str, Any]]] = {}
    for method, gain, _, row in keys:
        if not any((method, gain, r) in failed for r in range(args.grid)):
            maps.setdefault((method, gain), []).append(rows[method, gain, row])
    return maps, [failed[m, g, r] for m, g, _, r in keys if (m, g, r) in failed]


def summary(
    args: SweepArgs, maps: dict[tuple[str, float], list[dict[str, Any]]], solvable: Mask | None = None
) -> list[dict[str, Any]]:
    """One line per map: where it converged (and, with the oracle's ``solvable`` map, on which
    share of the region where the true plant can reach the goal), and how fast."""
    lines = []
    config = load_config(args.config)
    first_axis, second_axis = axis_values(args)
    c0, c1 = centre_values(args, config)
    centre = (int(np.argmin(np.abs(first_axis - c0))), int(np.argmin(np.abs(second_axis - c1))))
    if solvable is not None:
        lines.append(
            {
                "method": ORACLE,
                "nu_b": None,
                "converged_fraction": float(solvable.mean()),
                "of_solvable": 1.0,
                "median_trials": None,
                "max_trials": None,
                "at_nominal": None,
                "wall_s": None,
            }
        )
    for (method, gain), rows in maps.items():
        first = np.array([row["trials_to"] for row in rows])
        ok = first > 0
        share = None
        if solvable is not None and solvable.any():
            share = float((ok & solvable).sum() / solvable.sum())
        lines.append(
            {
                "method": method,
                "nu_b": gain,
                "converged_fraction": float(ok.mean()),
                "of_solvable": share,
                "median_trials": float(np.median(first[ok])) if ok.any() else None,
                "max_trials": int(first[ok].max()) if ok.any() else None,
                "at_nominal": int(first[centre]) or None,
                "wall_s": float(sum(row["wall_s"] for row in rows)),
            }
        )
    return lines


def plot_map(
    args: SweepArgs,
    method: str,
    gain: float,
    rows: list[dict[str, Any]],
    names: list[str],
    path: Path,
    solvable: Mask | None = None,
) -> None:
    """The heat map of one map: trials to tolerance over the grid, grey where not within budget,
    and with the oracle's map the edge of the region where the true plant can reach the goal."""
    import matplotlib
    from matplotlib.figure import Figure

    first = np.array([row["trials_to"] for row in rows], dtype=np.float64)
    first[first == 0] = np.nan
    first_axis, second_axis = axis_values(args)
    h0, h1 = 0.5 * (first_axis[1] - first_axis[0]), 0.5 * (second_axis[1] - second_axis[0])
    fig = Figure(figsize=(5.6, 4.6))
    ax = fig.subplots()
    cmap = matplotlib.colormaps["viridis"].with_extremes(bad="#d0d0d0")
    extent = (second_axis[0] - h1, second_axis[-1] + h1, first_axis[0] - h0, first_axis[-1] + h0)
    image = ax.imshow(first, origin="lower", extent=extent, cmap=cmap, aspect="auto", vmin=1)
    fig.colorbar(image, ax=ax, label=f"trials to tolerance (grey: not within {args.trials})")
    if solvable is not None and 0 < solvable.mean() < 1:
        ax.contour(second_axis, first_axis, solvable.astype(float), levels=[0.5], colors="red", linewidths=1.2)
        ax.plot([], [], "r-", label="edge of the oracle's solvable region")
        ax.legend(loc="upper left", bbox_to_anchor=(0.0, -0.14), fontsize=8, frameon=False)
    c0, c1 = centre_values(args, load_config(args.config))
    ax.plot([c1], [c0], "r+", markersize=12)
    unit = " (true / nominal)" if not args.axes else ""
    ax.set_xlabel(f"{names[1]}{unit}")
    ax.set_ylabel(f"{names[0]}{unit}")
    ax.set_title(f"{load_config(args.config).name}: {method}, nu_b = {gain:g}")
    fig.tight_layout()
    write_figure(path, fig, dpi=90)


def main(args: SweepArgs) -> list[dict[str, Any]]:
    """Run (or resume) the sweep and write its report; returns one summary line per complete map."""
    return main_with_failures(args)[0]


def main_with_failures(args: SweepArgs) -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
    """:func:`main`, returning the failed rows too; the last line printed says how many failed."""
    from ilc_steering.tables import markdown_table, write_results

    start = time.perf_counter()
    maps, failed = run_all(args)
    if not maps:
        print(f"{len(failed)} of {len(failed)} rows failed, each recorded with its error in {args.out}/failed")
        return [], failed
    _, names = _validate(args)
    solvable = None
    if args.oracle:
        solvable = np.array(read_json(args.out / "oracle.json", MAX_RESULT_BYTES)["solvable"], dtype=np.bool_)
    lines = summary(args, maps, solvable)
    for (method, gain), rows in maps.items():
        plot_map(args, method, gain, rows, names, args.out / f"sweep_{map_name(method, gain)}.png", solvable)
    header = ["method", "nu_b", "converged", "median trials", "most trials", "at the nominal plant", "cell time [s]"]
    if solvable is not None:
        header.insert(3, "of the solvable region")

    def text(value: Any, form: str) -> str:
        return "-" if value is None else format(value, form)

    cells = []
    for line in lines:
        cell = [
            line["method"] + (" (knows the true plant)" if line["method"] == ORACLE else ""),
            text(line["nu_b"], "g"),
            f"{100 * line['converged_fraction']:.1f} %",
            text(line["median_trials"], "g"),
            text(line["max_trials"], "d"),
            text(line["at_nominal"], "d"),
            text(line["wall_s"], ".1f"),
        ]
        if solvable is not None:
            cell.insert(3, "-" if line["of_solvable"] is None else f"{100 * line['of_solvable']:.1f} %")
        cells.append(cell)
    table = markdown_table(header, cells, [False] + [True] * (len(header) - 1))
    grid = {
        f"{method}__nu{gain_text(gain)}": [row["trials_to"] for row in rows] for (method, gain), rows in maps.items()
    }
    extra = {"settings": {**asdict(args), "out": None}, "axes": names, "failed": failed}
    first_axis, second_axis = axis_values(args)
    values = {"ratios": first_axis.tolist(), "values": [first_axis.tolist(), second_axis.tolist()], "maps": grid}
    if solvable is not None:
        values["solvable"] = solvable.tolist()
    write_results(lines, args.out, "sweep", table, {**extra, **values})
    print(table)
    print(
        f"{args.grid} x {args.grid} plants per map, {len(maps)} maps in {time.perf_counter() - start:.1f} s; "
        f"wrote {args.out}/sweep.{{csv,json,md}}, sweep_<method>_nu<b>.png and rows/"
    )
    total = args.grid * len(args.methods) * max(1, len(args.nu_b))
    if failed:
        print(f"{len(failed)} of {total} rows failed, each recorded with its error in {args.out}/failed")
    else:
        print(f"all {total} rows finished")
    return lines, failed


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
    parser.add_argument(
        "--workers", type=int, default=0, help=f"local worker processes (0: one per core; at most {MAX_WORKERS})"
    )
    parser.add_argument(
        "--cell-timeout",
        type=float,
        default=None,
        metavar="SECONDS",
        help="stop a row still running after this and record it as failed (default: no limit)",
    )
    parser.add_argument(
        "--axis",
        nargs=3,
        action="append",
        metavar=("KEY", "LOW", "HIGH"),
        help="a plant key and its range, twice (e.g. --axis steering_offset -0.03 0.03 --axis true_wheel_radius "
        "0.01 0.03); default: the plant's two factors as ratios over --range",
    )
    parser.add_argument(
        "--oracle",
        action="store_true",
        help="also map where the true plant can reach the goal at all (an oracle that knows the true plant, "
        "never a learner), and give each map's share of that region",
    )


def from_namespace(ns: argparse.Namespace) -> SweepArgs:
    axes = []
    for key, low, high in ns.axis or []:
        try:
            axes.append((key, float(low), float(high)))
        except ValueError:
            raise ValueError(f"--axis {key}: LOW and HIGH must be numbers, got {low!r} {high!r}") from None
    return SweepArgs(
        axes=tuple(axes),
        oracle=ns.oracle,
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
        cell_timeout=ns.cell_timeout,
    )
