"""The rows of a robustness map: the grid's true plants, a row's run, and its file.

A row of the grid is one :class:`~ilc_steering.envs.steering_vector_env.ChainedSteeringVectorEnv`
with a true plant per env (:func:`row_plants`); :func:`run_row` builds a learner per plant
through the registry (:mod:`~ilc_steering.agents.registry`) and runs them by the vector form of
the one trial loop (:func:`lockstep`, :func:`~ilc_steering.loop.run_vector_trials`).
:func:`read_row` and :func:`read_oracle` are the resume checkers.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Annotated, Any

import numpy as np
import numpy.typing as npt
from pydantic import Field

from ilc_steering.agents.base import Learner, LearnerContext
from ilc_steering.agents.registry import METHODS, lookup
from ilc_steering.config import SteeringConfig, load_config
from ilc_steering.core.plants import Plant
from ilc_steering.core.score import within_tolerance
from ilc_steering.envs.scenario import Scenario
from ilc_steering.errors import BadInput
from ilc_steering.loop import run_vector_trials
from ilc_steering.oracle import SOLVED
from ilc_steering.output import MAX_RESULT_BYTES, injective_name
from ilc_steering.readers import read_json
from ilc_steering.schema import MethodName, check_record

__all__ = [
    "MAX_GRID",
    "ORACLE",
    "RowRecord",
    "SweepArgs",
    "axis_values",
    "centre_row",
    "centre_values",
    "gain_text",
    "lockstep",
    "map_name",
    "read_oracle",
    "read_row",
    "row_name",
    "row_path",
    "row_plants",
    "run_oracle",
    "run_row",
]

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
    """Points per axis of the map (``--grid``): GRID x GRID true plants, a row of them a cell of the run."""
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
    """[s] a row still running after this is stopped and recorded as failed; None:
    :data:`~ilc_steering.engine.options.DEFAULT_CELL_TIMEOUT`."""
    axes: tuple[tuple[str, float, float], ...] = ()
    """Two plant keys with their ranges ``(key, low, high)`` [the key's unit], e.g.
    ``("steering_offset", -0.03, 0.03)``; empty: the plant's two ``factor_names`` as ratios to
    the nominal ones, from ``low`` to ``high``."""
    oracle: bool = False
    """Also map where the true plant can reach the goal at all (:mod:`ilc_steering.oracle`, which
    knows the true plant: never a learner), and report every map's share of that region."""
    dry_run: bool = False
    """Compute and write nothing: say which rows a run would compute, and its cost."""


def lockstep(
    envs: Any, learners: list[Learner], trials: int, tolerance: Any, seed: int = 0, name: str | None = None
) -> dict[str, Array]:
    """Run ``learners[i]`` on env ``i`` of the vector env ``envs`` by the one trial loop's vector
    form (:func:`~ilc_steering.loop.run_vector_trials`), for at most ``trials`` trials (fewer once
    all are within ``tolerance``). Returns per env ``trials_to`` (the first trial within tolerance,
    0 for none), ``error`` (the true error norm of the last trial) and ``left_chart`` (the
    fraction of trials that left the chart)."""
    count = envs.num_envs
    first = np.zeros(count, dtype=np.int64)
    error = np.full(count, np.nan)
    off_chart = np.zeros(count)

    def record(k: int, rows: list[dict[str, Any]]) -> bool:
        nonlocal error
        for i, row in enumerate(rows):
            if first[i] == 0 and within_tolerance(tolerance, row):
                first[i] = k
        error = np.array([row["true_error_norm"] for row in rows], dtype=np.float64)
        off_chart[:] += np.array([row["left_chart"] for row in rows], dtype=np.float64)
        return bool(np.all(first > 0))

    run = run_vector_trials(envs, learners, trials, seed=seed, callbacks=[record], name=name)
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

    def toward(centre: float, value: float) -> float:  # the user's value itself at reach 1 (1 + (1e-300 - 1) is 0)
        return float(value) if reach == 1.0 else centre + reach * (value - centre)

    points = [(toward(c0, first[row]), toward(c1, b)) for b in second]
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
    result = lockstep(envs, learners, args.trials, config.learning.tolerance, args.seed, method)
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


def gain_text(gain: float) -> str:
    """``gain`` as ``:g`` text where that is the gain exactly (``1``, ``0.5``), else its ``repr``:
    two gains never share a text, so never a file."""
    short = f"{gain:g}"
    return short if float(short) == gain else repr(float(gain))


def map_name(method: str, gain: float) -> str:
    """The file-name part of the map of ``method`` at ``gain``: injective in both."""
    return f"{injective_name(method, METHODS)}_nu{gain_text(gain)}"


def row_name(method: str, nu_b: float, row: int) -> str:
    """The file name (without ``.json``) of a row: injective in the method, the gain and the row."""
    return f"{injective_name(method, METHODS)}__nu{gain_text(nu_b)}__{row:03d}"


def row_path(out: Path, method: str, nu_b: float, row: int, folder: str = "rows") -> Path:
    return out / folder / f"{injective_name(method, METHODS)}__nu{gain_text(nu_b)}__{row:03d}.json"


@dataclass(frozen=True)
class RowRecord:
    """A row's file (``rows/*.json``), as its schema: read back, a row of another shape is refused
    naming the key (:func:`read_row`). Each list holds a value per plant of the row."""

    method: MethodName
    nu_b: float
    row: int
    trials_to: tuple[int, ...]  # [trials] the first trial within the tolerance; 0: never
    error: tuple[Annotated[float, Field(allow_inf_nan=True)], ...]  # the last true error (inf: off the chart)
    left_chart: tuple[float, ...]  # the fraction of trials that left the chart
    wall_s: float  # [s]
    config_sha: str  # the content hash of its config
    version: str  # the ilc-steering version that computed it
    code: str | None = None  # the hash of its code (engine.provenance); None: a row made before rows kept it


def row_roots(method: str, robot: str) -> tuple[str, ...]:
    """Where the computation of a row of ``method`` on a robot whose config class lives in module
    ``robot`` starts: this module, the learner's sources, the robot's module and the packaged
    configs' package (their import closure is the row's code, :mod:`~ilc_steering.engine.closure`)."""
    return (__name__, *lookup(method).sources(), robot, "ilc_steering.configs")


def oracle_roots(robot: str) -> tuple[str, ...]:
    """Where the oracle's map of a robot whose config class lives in module ``robot`` starts."""
    return (__name__, "ilc_steering.oracle", robot, "ilc_steering.configs")


def read_row(path: Path, key: dict[str, Any], size: int, trials: int) -> dict[str, Any]:
    """A finished row, checked against its ``key`` (method, gain, row) and
    value by value: ``size`` plants, ``trials_to`` in ``[0, trials]``, errors >= 0 (not NaN),
    off-chart fractions in [0, 1], a wall time >= 0 s. ``ValueError`` names the file."""
    hint = "delete it to recompute it"
    try:
        row: dict[str, Any] = read_json(path, MAX_RESULT_BYTES)
    except ValueError as error:
        raise BadInput(f"not a sweep row: {error}; {hint}") from None
    check_record(RowRecord, row, path, hint)  # the types, the keys: each value below is of its type
    for name in ("trials_to", "error", "left_chart"):
        if len(row[name]) != size:
            raise BadInput(
                f"{path}: {name}: needs {size} values (a row of {size} plants), got {len(row[name])}; {hint}"
            )
    for name, value in key.items():
        if row.get(name) != value:
            raise BadInput(f"{path}: holds {name} {row.get(name)!r}, not {value!r}; {hint}")
    problem = None
    if not all(0 <= t <= trials for t in row["trials_to"]):
        problem = f"trials_to holds a value outside the whole numbers 0 to the budget {trials}"
    elif not all(e >= 0 for e in row["error"]):  # NaN fails e >= 0
        problem = "error holds a value that is not an error >= 0"
    elif not all(0 <= f <= 1 for f in row["left_chart"]):
        problem = "left_chart holds a value outside the fractions [0, 1]"
    elif not row["wall_s"] >= 0:
        problem = f"wall_s {row['wall_s']!r} is not a time >= 0 s"
    if problem:
        raise BadInput(f"{path}: {problem}; {hint}")
    return row


ORACLE = "oracle"
"""The oracle's name in a sweep's results: it knows the true plant, and it is not a learner."""


def read_oracle(path: Path, key: dict[str, Any], size: int) -> dict[str, Any]:
    """The oracle's map, checked against its ``key`` and its shape; ``ValueError`` names the file."""
    hint = "delete it to recompute it"
    try:
        found = read_json(path, MAX_RESULT_BYTES)
    except ValueError as problem:
        raise BadInput(f"not an oracle map: {problem}; {hint}") from None
    if not isinstance(found, dict):
        raise BadInput(f"{path}: not an oracle map (a JSON object); {hint}")
    for name, value in key.items():
        if found.get(name) != value:
            raise BadInput(f"{path}: holds {name} {found.get(name)!r}, not {value!r}; {hint}")
    solvable: Any = found.get("solvable")
    errors: Any = found.get("error")
    shape_ok = all(
        isinstance(grid, list) and len(grid) == size and all(isinstance(r, list) and len(r) == size for r in grid)
        for grid in (solvable, errors)
    )
    if not shape_ok:
        raise BadInput(f"{path}: not a {size} x {size} oracle map; {hint}")
    if not all(isinstance(v, bool) for r in solvable for v in r):
        raise BadInput(f"{path}: solvable holds a value that is not true or false; {hint}")
    if not all(v is None or (isinstance(v, (int, float)) and v >= 0) for r in errors for v in r):
        raise BadInput(f"{path}: error holds a value that is not an error >= 0 or null; {hint}")
    if any(s != (e is not None and e < SOLVED) for rs, re in zip(solvable, errors) for s, e in zip(rs, re)):
        raise BadInput(f"{path}: solvable disagrees with error < {SOLVED:g}; {hint}")
    return found
