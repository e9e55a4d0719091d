"""A noisy in-family plant, seeded 100 times: do the learners hold 4 sigma, and is the scatter they report sigma?

Issue 48's Done-when: over 100 seeded runs of the car with additive final-pose noise of known
``sigma`` per coordinate, the last five trials hold ``4 sigma`` in at least 95 % of runs, and the
reported scatter is within a factor 1.5 of ``sigma``.

The plant is simulation 1 (``forward_parking``: the car 10 % larger than the controller's
nominal one, inside the model family of ``newton_ilc`` and ``robust_ilc``) with
``simulation.measurement_noise`` ``sigma`` on each of ``x``, ``y`` [m], ``theta`` and ``phi``
[rad], drawn per trial from the env's seed; the tolerance is ``4 sigma`` (Cartesian [m] and
orientation [rad]). Each run is ``ilc-steering run`` (:func:`~ilc_steering.runner.run_ilc`, seed
``s``, ``trials`` trials): the true errors are scored, the verdict is the run's (converged when
its last :data:`~ilc_steering.core.scatter.HOLD` trials hold the tolerance) and the reported
scatter is the run's own estimate (``scatter`` of ``run --json``: ``cartesian`` [m] pooled over
``x`` and ``y``, ``orientation`` [rad]), divided by ``sigma``.

    python benchmarks/noisy.py [--quick] [--out DIR]

writes ``noisy_runs.{csv,json,md}`` (one row per learner and seed) and ``noisy.{csv,json,md}``
(one row per learner), committed in ``results/noisy`` and quoted by ``docs/noisy.md``. A run
interrupted resumes: every finished run is appended to ``noisy_runs.partial.jsonl`` in ``--out``
(its arguments on the first line) and not run again; the file is removed when the tables are written.
"""

from __future__ import annotations

import dataclasses
import json
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from statistics import median
from typing import Any

from ilc_steering.arguments import Parser
from ilc_steering.config import SteeringConfig, load_config
from ilc_steering.engine.provenance import record_made
from ilc_steering.output import check_output_dir
from ilc_steering.runner import run_ilc
from ilc_steering.tables import markdown_table, write_results

__all__ = ["Args", "main", "noisy_config", "one_run", "summarize"]


@dataclass(frozen=True)
class Args:
    quick: bool = False
    """Two seeds, one learner, six trials: checks that the script runs (CI)."""
    out: Path = Path("results/noisy")
    """Where the tables go."""
    task: str = "forward_parking"
    """The in-family task (a packaged name or a YAML path)."""
    sigma: float = 1e-3
    """[m, rad] the measurement noise's standard deviation, on each coordinate of the final configuration."""
    factor: float = 4.0
    """The tolerance in units of ``sigma`` (Cartesian [m] and orientation [rad])."""
    seeds: int = 100
    """Runs per learner, seeds ``0 .. seeds - 1``."""
    trials: int = 15
    """Trials per run."""
    last: int = 5
    """The last trials of a run that must all hold the tolerance."""
    learners: tuple[str, ...] = ("robust_ilc", "newton_ilc", "ilc_paper")
    """Ids of the learner registry (the paper's law for reference)."""


def noisy_config(task: str, sigma: float, factor: float, trials: int) -> SteeringConfig:
    """``task`` with measurement noise ``sigma`` [m, rad] on every coordinate, a tolerance of
    ``factor * sigma`` and ``trials`` trials."""
    config = load_config(task)
    size = len(config.points()[0][1])
    tolerance = dataclasses.replace(config.learning.tolerance, cartesian=factor * sigma, orientation=factor * sigma)
    return dataclasses.replace(
        config,
        learning=dataclasses.replace(config.learning, tolerance=tolerance, trials=trials),
        simulation=dataclasses.replace(config.simulation, measurement_noise=(sigma,) * size),
    )


def one_run(config: SteeringConfig, learner: str, seed: int, sigma: float, last: int) -> dict[str, Any]:
    """One seeded run: whether its last ``last`` trials hold the tolerance (true errors), the run's
    verdict and its scatter estimate in units of ``sigma``."""
    start = time.perf_counter()
    result = run_ilc(config, learner=learner, seed=seed)
    seconds = time.perf_counter() - start
    verdict = result.verdict
    scatter = verdict.scatter or {}
    tail = result.trials[-last:]
    return {
        "learner": learner,
        "seed": seed,
        "holds_last": verdict.held >= last,
        "held": verdict.held,
        "converged_at": verdict.converged_at,
        "relapses": len(verdict.relapses),
        "scatter_cartesian": scatter.get("cartesian", float("nan")) / sigma,
        "scatter_orientation": scatter.get("orientation", float("nan")) / sigma,
        "worst_last_m": max(r.cartesian_error or 0.0 for r in tail),
        "worst_last_rad": max(r.orientation_error or 0.0 for r in tail),
        "below_floor": bool(verdict.below),
        "seconds": seconds,
    }


def _spread(values: list[float]) -> tuple[float, float, float]:
    """Median, min and max of the finite ``values`` (NaN for none)."""
    finite = [v for v in values if v == v]
    if not finite:
        return float("nan"), float("nan"), float("nan")
    return median(finite), min(finite), max(finite)


def summarize(runs: list[dict[str, Any]], learner: str) -> dict[str, Any]:
    """One learner's row: the share of runs whose last trials hold, and the scatter / sigma."""
    mine = [r for r in runs if r["learner"] == learner]
    cart = _spread([r["scatter_cartesian"] for r in mine])
    orient = _spread([r["scatter_orientation"] for r in mine])
    ratios = [r[key] for r in mine for key in ("scatter_cartesian", "scatter_orientation")]
    return {
        "learner": learner,
        "runs": len(mine),
        "hold_share": sum(r["holds_last"] for r in mine) / len(mine),
        "converged_share": sum(r["converged_at"] is not None for r in mine) / len(mine),
        "estimated": sum(r["scatter_cartesian"] == r["scatter_cartesian"] for r in mine),
        "within_1_5": sum(1 / 1.5 <= v <= 1.5 for v in ratios) / len(ratios),
        "runs_within_1_5": sum(
            all(1 / 1.5 <= r[key] <= 1.5 for key in ("scatter_cartesian", "scatter_orientation")) for r in mine
        )
        / len(mine),
        "cartesian_median": cart[0],
        "cartesian_min": cart[1],
        "cartesian_max": cart[2],
        "orientation_median": orient[0],
        "orientation_min": orient[1],
        "orientation_max": orient[2],
        "worst_last_m": max(r["worst_last_m"] for r in mine),
        "worst_last_rad": max(r["worst_last_rad"] for r in mine),
        "seconds_per_run": sum(r["seconds"] for r in mine) / len(mine),
    }


def _resume(path: Path, key: dict[str, Any]) -> list[dict[str, Any]]:
    """The runs an interrupted call with the same arguments ``key`` finished (none if another's)."""
    if not path.exists():
        return []
    lines = path.read_text().splitlines()
    if not lines or json.loads(lines[0]) != key:
        path.unlink()
        return []
    return [json.loads(line) for line in lines[1:] if line.strip()]


def main(args: Args) -> list[dict[str, Any]]:
    out = check_output_dir(args.out, "--out")
    seeds, trials, learners = args.seeds, args.trials, args.learners
    if args.quick:
        seeds, trials, learners = 2, 6, learners[:1]
    config = noisy_config(args.task, args.sigma, args.factor, trials)
    key = {k: str(v) for k, v in dataclasses.asdict(args).items() if k != "out"}
    partial = out / "noisy_runs.partial.jsonl"
    runs = _resume(partial, key)
    done = {(r["learner"], r["seed"]) for r in runs}
    if not runs:
        partial.write_text(json.dumps(key) + "\n")
    start = time.perf_counter()
    for learner in learners:
        for seed in range(seeds):
            if (learner, seed) in done:
                continue
            runs.append(one_run(config, learner, seed, args.sigma, args.last))
            with partial.open("a") as file:
                file.write(json.dumps(runs[-1]) + "\n")
        print(f"{learner}: {seeds} runs, {time.perf_counter() - start:.0f} s so far", flush=True)
    report(runs, args, seeds, trials, learners, time.perf_counter() - start)
    partial.unlink()
    return [summarize(runs, learner) for learner in learners]


def report(
    runs: list[dict[str, Any]], args: Args, seeds: int, trials: int, learners: tuple[str, ...], seconds: float
) -> None:
    """Write the runs' table and the learners' summary (``noisy_runs``, ``noisy``) to ``args.out``."""
    rows = [summarize(runs, learner) for learner in learners]
    sigma, factor, last = args.sigma, args.factor, args.last
    header = [
        "learner",
        "runs",
        f"last {last} hold {factor:g}σ",
        "converged (the run's verdict)",
        "scatter estimated",
        "scatter / σ, x-y: median [range]",
        "scatter / σ, θ: median [range]",
        "estimates within 1.5×",
        "runs with both within 1.5×",
        f"worst of last {last} [mm]",
        f"worst of last {last} [mrad]",
        "wall / run [s]",
    ]
    table = [
        [
            r["learner"],
            str(r["runs"]),
            f"{100 * r['hold_share']:.0f} %",
            f"{100 * r['converged_share']:.0f} %",
            f"{r['estimated']}/{r['runs']}",
            f"{r['cartesian_median']:.2f} [{r['cartesian_min']:.2f}, {r['cartesian_max']:.2f}]",
            f"{r['orientation_median']:.2f} [{r['orientation_min']:.2f}, {r['orientation_max']:.2f}]",
            f"{100 * r['within_1_5']:.0f} %",
            f"{100 * r['runs_within_1_5']:.0f} %",
            f"{1e3 * r['worst_last_m']:.2f}",
            f"{1e3 * r['worst_last_rad']:.2f}",
            f"{r['seconds_per_run']:.2f}",
        ]
        for r in rows
    ]
    markdown = (
        f"{args.task} with measurement noise σ = {sigma:g} (m, rad) on each coordinate, tolerance {factor:g}σ "
        f"= {factor * sigma:g} m / {factor * sigma:g} rad (true errors), {trials} trials per run, seeds 0-{seeds - 1}. "
        f"Last {last} hold: the share of runs whose last {last} trials are all within the tolerance. Scatter / σ: "
        "the run's own estimate (run --json's scatter) over σ; estimates within 1.5×: the share of the "
        "estimates (both coordinates of every run) between σ/1.5 and 1.5σ; runs with both within: the share of "
        "runs whose two estimates are.\n\n" + markdown_table(header, table, [False] + [True] * 11)
    )
    extra = {"args": {k: str(v) for k, v in dataclasses.asdict(args).items()}, "seconds": seconds}
    write_results(
        runs, args.out, "noisy_runs", markdown_table(list(runs[0]), [[str(v) for v in r.values()] for r in runs])
    )
    write_results(rows, args.out, "noisy", markdown, extra)
    print(markdown)


def parse(argv: list[str] | None = None) -> Args:
    parser = Parser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="two seeds, one learner, six trials")
    parser.add_argument("--out", type=Path, default=Args.out)
    parser.add_argument("--seeds", type=int, default=Args.seeds)
    parser.add_argument("--sigma", type=float, default=Args.sigma)
    return Args(**vars(parser.parse_args(argv)))


if __name__ == "__main__":
    arguments = parse()
    main(arguments)
    record_made(arguments.out, __file__, sys.argv[1:])
