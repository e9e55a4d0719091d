"""Robustness maps: trials to tolerance of a learner over a grid of true plants.

Proposition 2 promises convergence "for sufficiently small" model error; a map shows where it
stops. Every point of the grid is a true robot, the config's with its two parameters
(``plant.factor_names``: a car's wheelbase and wheel radius) at the given ratios to the
*nominal* ones; the learner sees the nominal model only, the same at every point. A row of the
grid is one :class:`~ilc_steering.envs.steering_vector_env.ChainedSteeringVectorEnv` with
``true_factors``: one learner per plant, all stepped in lock-step, one compiled call per trial
index (:func:`lockstep`). Each finished row is written at once, so a sweep resumes where it
stopped, on the local machine or on Ray (``--backend ray``, see :mod:`ilc_steering.engine.backends`).

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
import os
import sys
import time
from dataclasses import asdict, dataclass, replace
from dataclasses import fields as dataclass_fields
from typing import Any, get_type_hints

import numpy as np

from ilc_steering import __version__
from ilc_steering.agents.registry import METHODS, REGISTRY, is_custom, lookup
from ilc_steering.config import SteeringConfig, load_config
from ilc_steering.config.loading import resolve_config
from ilc_steering.core.external import is_external
from ilc_steering.engine.options import add_cell_options, check_cell_options
from ilc_steering.engine.provenance import code, record_codes, record_report
from ilc_steering.engine.runs import Cells, RunFolder, compute_cells, dry_run
from ilc_steering.envs.scenario import Scenario
from ilc_steering.errors import BadInput
from ilc_steering.output import MAX_RESULT_BYTES, content_hash, output_folder, write_json
from ilc_steering.readers import read_json
from ilc_steering.sweep.report import write_sweep_report
from ilc_steering.sweep.rows import (
    MAX_GRID,
    ORACLE,
    SweepArgs,
    axis_values,
    gain_text,
    map_name,
    oracle_roots,
    read_oracle,
    read_row,
    row_name,
    row_plants,
    row_roots,
    run_oracle,
    run_row,
)

__all__ = ["Plan", "main", "main_with_failures", "plan", "run_all", "run_rows"]

Row = tuple[str, float, int]
"""A row's (method, gain, row index)."""


@dataclass(frozen=True)
class Plan:
    """A sweep as it will run, resolved and checked once: read by every stage, recomputed by none."""

    args: SweepArgs
    config: SteeringConfig
    """The config, loaded once."""
    digest: str
    """Its content hash."""
    names: list[str]
    """The names of the two axes."""
    rows: tuple[Row, ...]
    """Every row of every map, in order."""
    given: dict[float, float | None]
    """Each gain of the rows -> the gain as given (None: the config's)."""
    warning: str | None = None

    @property
    def settings(self) -> dict[str, Any]:
        """What ``run.json`` records and a resume must match."""
        skip = ("out", "methods", "nu_b", "backend", "workers", "cell_timeout", "oracle", "dry_run")
        settings = {k: v for k, v in asdict(self.args).items() if k not in skip}
        settings["axes"] = [list(axis) for axis in self.args.axes]
        settings["config"] = self.config.name
        settings["version"] = __version__
        return settings

    def key(self, row: Row) -> dict[str, Any]:
        """What a finished row must hold to be this row at all."""
        method, gain, index = row
        return {"method": method, "nu_b": gain, "row": index}

    @property
    def stamp(self) -> dict[str, Any]:
        """What every row (and the oracle) this run computes records besides its result: a finished
        one that records other values (or another code) is stale, and computed again."""
        return {"config_sha": self.digest, "version": __version__}

    @property
    def robot(self) -> str:
        """The module of the config's robot, a root of every row's code."""
        return type(self.config.plant).__module__


def plan(args: SweepArgs) -> Plan:
    """The frozen plan of ``args``: the config loaded once, every option checked once."""
    from ilc_steering.runner import step_warning

    source = resolve_config(args.config)
    config = load_config(source)
    names = _validate(args, config)
    check_cell_options(args.backend, args.workers, args.cell_timeout)
    gains: list[float | None] = list(args.nu_b) or [None]
    given = {config.learning.nu_b if g is None else g: g for g in gains}
    rows = tuple((m, gain, r) for m in args.methods for gain in given for r in range(args.grid))
    if source.path is not None:  # the rows and the oracle load what the name named now, not what it names later
        args = replace(args, config=os.path.abspath(source.path))
    return Plan(args, config, content_hash(asdict(config)), names, rows, given, step_warning(config))


def _validate(args: SweepArgs, config: SteeringConfig) -> list[str]:
    """Every option checked once, against the config loaded once; returns the axes' names."""
    if config.is_cyclic:
        raise BadInput(f"{args.config}: a cyclic config; sweep maps one-trial tasks")
    if is_external(config.plant.plant()):  # its plants cannot be varied: a map over it would be faked
        model = config.plant.model
        raise BadInput(f"{args.config}: an external plant (plant.model {model}); sweep maps true factors")
    Scenario.from_config(config).refuse_disturbances("sweep")
    import gymnasium as gym

    from ilc_steering.runner import ENV_ID, check_task

    env = gym.make(ENV_ID, config=config)
    check_task(env, args.config)
    env.close()
    for name, value, lo, hi in (("--grid", args.grid, 2, MAX_GRID), ("--trials", args.trials, 1, 100_000)):
        if isinstance(value, bool) or not isinstance(value, int) or not lo <= value <= hi:
            raise BadInput(f"{name} must be a whole number in [{lo}, {hi}], got {value!r}")
    if not (np.isfinite(args.low) and np.isfinite(args.high) and 0 < args.low < args.high <= 100):
        raise BadInput(f"--range must be two ratios 0 < low < high <= 100, got {args.low} {args.high}")
    for gain in args.nu_b:
        if not (np.isfinite(gain) and 0 < gain <= 2):
            raise BadInput(f"--nu-b must be gains in (0, 2], got {gain}")
    for option, values in (("--methods", args.methods), ("--nu-b", args.nu_b)):
        repeated = sorted({str(v) for v in values if list(values).count(v) > 1})
        if repeated:
            raise BadInput(f"{option}: {repeated[0]} is given twice; each map is computed once")
    if not args.methods:
        raise BadInput("--methods: give at least one")
    mappable = [i for i in METHODS if REGISTRY[i].family != "RL"]
    for method in args.methods:
        if method in REGISTRY and REGISTRY[method].family == "RL":
            raise BadInput(f"--methods {method}: RL trains a network per plant; sweep maps {tuple(mappable)}")
        if method not in REGISTRY and not is_custom(method):
            raise BadInput(f"--methods: unknown method {method!r}; choose from {mappable}")
        if is_custom(method):
            lookup(method)  # imported now: a factory that cannot be imported is refused before any row
    if not args.axes:
        return list(config.plant.plant().factor_names)
    _check_axes(args, config)
    return [key for key, _, _ in args.axes]


def _real_keys(plant_class: type) -> set[str]:
    """The keys of a plant config that take a real number (``float``, or ``float | None``): what a
    map's axis can vary; a whole number (``encoder_pulses``), a flag or a choice cannot take a grid's
    values. Every field but ``model`` when the class's annotations cannot be resolved (a user's robot)."""
    names = [f.name for f in dataclass_fields(plant_class) if f.name != "model"]
    try:
        hints = get_type_hints(plant_class)
    except Exception:  # a user's annotations naming what its module does not import
        return set(names)
    return {name for name in names if hints.get(name) in (float, float | None)}


def _check_axes(args: SweepArgs, config: SteeringConfig) -> None:
    """Two distinct numeric keys of the config's plant, each with a range, every plant of the grid
    valid and of the config's robot (one compiled call per kernel a row needs)."""
    if len(args.axes) != 2:
        raise BadInput(f"--axis: give exactly two (KEY LOW HIGH each), got {len(args.axes)}")
    keys = [key for key, _, _ in args.axes]
    if keys[0] == keys[1]:
        raise BadInput(f"--axis: {keys[0]} is given twice; a map has two different axes")
    plant_config: Any = config.plant
    fields = _real_keys(type(plant_config))
    for key, low, high in args.axes:
        if key not in fields:
            known = key in {f.name for f in dataclass_fields(plant_config)}
            what = "takes no real number (a grid's values)" if known else "not a key of this plant"
            raise BadInput(f"--axis {key}: {what}; choose from {sorted(fields)}")
        if not (np.isfinite(low) and np.isfinite(high) and low < high):
            raise BadInput(f"--axis {key}: a range LOW < HIGH of finite numbers, got {low} {high}")
    if (args.low, args.high) != (SweepArgs.low, SweepArgs.high):
        raise BadInput("--range: the ratio axes' range; with --axis give each axis its own range (KEY LOW HIGH)")
    from ilc_steering.errors import ConfigError

    nominal = Scenario.from_config(config).nominal.solve()
    for key, low, high in args.axes:  # a map varies the true plant; the learner's model stays the nominal one
        for value in (low, high):
            try:
                moved = Scenario.from_config(replace(config, plant=replace(plant_config, **{key: value}))).nominal
            except (ConfigError, ValueError, TypeError):
                continue  # an invalid plant: named below, with the grid's
            if not np.array_equal(moved.solve(), nominal):
                raise BadInput(
                    f"--axis {key}: a nominal parameter (the model the learner sees), not the true plant's; a map "
                    "varies the true plant: give a true_* key or an unmodeled one"
                )
    first, second = axis_values(args)
    (k0, _, _), (k1, _, _) = args.axes
    for x in first:  # every plant of the grid as the loader would check it (a lag below max_step, say)
        for y in second:
            try:
                replace(config, plant=replace(plant_config, **{k0: float(x), k1: float(y)}))
            except (ConfigError, ValueError, TypeError) as error:
                raise BadInput(
                    f"--axis: the grid holds an invalid plant at {k0} = {x:g}, {k1} = {y:g}: {error}"
                ) from None

    kind = config.plant.plant().kind  # a car with and without a servo is one kind: a kernel each per row
    for row in range(args.grid):
        try:
            plants = row_plants(args, config, row)
        except (ConfigError, ValueError, TypeError) as error:
            raise BadInput(f"--axis: the grid holds an invalid plant: {error}") from None
        if any(plant.kind != kind for plant in plants):
            raise BadInput(f"--axis: the grid holds plants of another kind than the config's {kind.name!r}")


def run_rows(args: SweepArgs) -> dict[tuple[str, float], list[dict[str, Any]]]:
    """Every row of every map, computing only those not yet in the run folder (the complete maps)."""
    return run_all(args)[0]


def run_all(args: SweepArgs) -> tuple[dict[tuple[str, float], list[dict[str, Any]]], list[dict[str, Any]]]:
    """The complete maps, and the rows that failed (each written to ``failed/`` with its error)."""
    return execute(plan(args))


def execute(the_plan: Plan) -> tuple[dict[tuple[str, float], list[dict[str, Any]]], list[dict[str, Any]]]:
    """Run the rows of ``the_plan`` on the engine (:func:`~ilc_steering.engine.runs.compute_cells`): each
    finished row is written the moment it finishes, a failed one under ``failed/``."""
    args = the_plan.args
    if the_plan.warning is not None:
        print(f"ilc-steering: {the_plan.warning}", file=sys.stderr, flush=True)
    folder = RunFolder(args.out, "rows", "sweep")
    reports = [f"sweep.{suffix}" for suffix in ("csv", "json", "md")]
    reports += [f"sweep_{map_name(m, g)}.png" for m, g in dict.fromkeys((m, g) for m, g, _ in the_plan.rows)]
    reports += ["oracle.json"] if args.oracle else []

    def oracle(todo: Any) -> None:
        if not args.oracle:
            return
        path = args.out / "oracle.json"
        roots = oracle_roots(the_plan.robot)
        stamp = {"method": ORACLE, **the_plan.stamp, "code": code(roots)[0]}
        record_codes(args.out, {stamp["code"]: roots})
        found = read_oracle(path, {"method": ORACLE}, args.grid) if path.exists() else None
        if found is not None and all(found.get(k) == v for k, v in stamp.items()):
            return
        why = "" if found is None else " (the one on disk is stale: another code or config)"
        print(f"{ORACLE}: where the true plant can reach the goal (it knows the true plant){why} ...", flush=True)
        write_json(path, {**stamp, **run_oracle(args)})

    cells = Cells(
        keys=the_plan.rows,
        name=lambda row: row_name(*row),
        read=lambda path, row: read_row(path, the_plan.key(row), args.grid, args.trials),
        call=lambda row: (args, row[0], the_plan.given[row[1]], row[2]),
        stamp=lambda row: the_plan.stamp,
        roots=lambda row: row_roots(row[0], the_plan.robot),
        failure=lambda row, message: {"method": row[0], "nu_b": row[1], "row": row[2], "error": message},
        describe=lambda row: f"{row[0]} nu_b {gain_text(row[1])} row {row[2]}",
    )
    if args.dry_run:
        folder.check(the_plan.settings)
        for line in dry_run(folder, cells, args.workers or os.cpu_count() or 1):
            print(line, flush=True)
        return {}, []
    folder.prepare(the_plan.settings, {the_plan.config.name: the_plan.digest}, reports)
    outcome = compute_cells(
        folder, cells, run_row, backend=args.backend, workers=args.workers, timeout=args.cell_timeout, before=oracle
    )
    maps: dict[tuple[str, float], list[dict[str, Any]]] = {}
    for method, gain, row in the_plan.rows:
        if not any((method, gain, r) in outcome.failed for r in range(args.grid)):
            maps.setdefault((method, gain), []).append(outcome.done[method, gain, row])
    return maps, outcome.in_order(the_plan.rows)[1]


def main(args: SweepArgs) -> list[dict[str, Any]]:
    """Run (or resume) the sweep and write its report; returns one summary line per complete map."""
    return main_with_failures(args)[0]


def main_with_failures(args: SweepArgs) -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
    """:func:`main`, returning the failed rows too; the last line printed says how many failed."""
    start = time.perf_counter()
    the_plan = plan(args)
    maps, failed = execute(the_plan)
    if args.dry_run:
        return [], failed
    total = args.grid * len(args.methods) * max(1, len(args.nu_b))
    if maps:
        solvable = None
        if args.oracle:
            solvable = np.array(read_json(args.out / "oracle.json", MAX_RESULT_BYTES)["solvable"], dtype=np.bool_)
        table, lines = write_sweep_report(args, the_plan.config, the_plan.names, maps, failed, solvable)
        record_report(args.out, [row for rows in maps.values() for row in rows])
        print(table)
        print(
            f"{args.grid} x {args.grid} plants per map, {len(maps)} maps in {time.perf_counter() - start:.1f} s; "
            f"wrote {args.out}/sweep.{{csv,json,md}}, sweep_<method>_nu<b>.png and rows/"
        )
    else:
        lines = []
    if failed:
        line = f"{len(failed)} of {total} rows failed, each recorded with its error in {args.out}/failed"
        print(line, flush=True)
        print(f"ilc-steering: {line}", file=sys.stderr, flush=True)
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
    parser.add_argument(
        "--grid",
        type=int,
        default=SweepArgs.grid,
        help="points per axis of the map: GRID x GRID true plants (not time steps, not cells: a row of GRID plants "
        "is one cell of the run)",
    )
    parser.add_argument(
        "--range",
        type=float,
        nargs=2,
        default=[SweepArgs.low, SweepArgs.high],
        metavar=("LOW", "HIGH"),
        help="ratios true / nominal on both axes",
    )
    parser.add_argument("--trials", type=int, default=SweepArgs.trials, help="budget per plant")
    parser.add_argument("--out", type=output_folder, default=SweepArgs.out, help="run folder; resumed if it exists")
    add_cell_options(parser, "row")
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
            raise BadInput(f"--axis {key}: LOW and HIGH must be numbers, got {low!r} {high!r}") from None
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
        cell_timeout=getattr(ns, "cell_timeout", None),  # suppressed when not given: the plan applies the default
        dry_run=ns.dry_run,
    )
