"""Robustness maps of every task, read against the oracle: where the true robot can reach the goal.

Each map is an ``ilc-steering sweep --oracle`` run (its own folder under ``--out``, resumable: a
second run recomputes nothing it already holds), of the paper's law, ``newton_ilc`` and
``robust_ilc``; this script runs them in turn and writes one table of every map's shares of the
oracle-solvable region.

    python benchmarks/robustness.py [--quick] [--out DIR] [--grid N] [--workers W]

writes ``robustness.{csv,json,md}`` and one sweep folder per map (committed in ``results/robustness``).
The oracle knows the true plant; it is never a learner (see :mod:`ilc_steering.oracle`).
"""

from __future__ import annotations

import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ilc_steering.arguments import Parser
from ilc_steering.engine.provenance import record_made
from ilc_steering.sweep.command import main as sweep
from ilc_steering.sweep.report import read_report
from ilc_steering.sweep.rows import SweepArgs
from ilc_steering.tables import markdown_table, write_results

__all__ = ["MAPS", "METHODS", "Args", "main"]

METHODS = ("ilc_paper", "newton_ilc", "robust_ilc")
MAPS: dict[str, tuple[str, tuple[tuple[str, float, float], ...], int | None]] = {
    "forward_parking": ("forward_parking", (), None),
    "forward_parking_saturated": ("forward_parking_saturated", (), None),
    "parallel_parking": ("parallel_parking", (), None),
    "unicycle_parking": ("unicycle_parking", (), None),
    "trailer_bay": ("trailer_bay", (("true_hitch_length", 0.15, 0.45), ("true_wheelbase", 0.1, 0.3)), None),
    "parallel_parking_servo": (
        "parallel_parking_servo",
        (("steering_offset", -0.03, 0.03), ("true_wheel_radius", 0.01, 0.03)),
        9,
    ),
    "parallel_parking_lag": (
        "parallel_parking_lag",
        (("steering_lag", 0.0, 0.1), ("steering_offset", -0.03, 0.03)),
        9,
    ),
    "experiment_forward": ("experiment_forward", (), 9),
    "experiment_parallel": ("experiment_parallel", (), 9),
    "experiment_parallel_servo": (
        "experiment_parallel",
        (("steering_lag", 0.0, 0.25), ("steering_backlash", 0.0, 0.02)),
        9,
    ),
    "experiment_parallel_trim": (
        "experiment_parallel",
        (("steering_offset", -0.03, 0.03), ("speed_lag", 0.0, 0.25)),
        9,
    ),
}
"""Map name: config, axes (empty: wheelbase and wheel radius, or the robot's two factors, as
ratios 0.5-1.5 to the nominal ones; else two plant keys with their ranges) and its own grid (None:
``--grid``; the servo car's and the lab robot's maps are coarser, their kernels being the slowest:
section 5's experiments 1 and 2 are mapped over the lab robot's wheelbase and wheel radius, its
other imperfections as configured, and experiment 2 over its steering servo's lag and play and
over its steering trim and drive lag, each from 0 or a step of the integrator's 1/32 s up, as the
plant requires of a lag). The lag map starts
at a lag of 0 s, the lag-free car: the vector env and the oracle measure every plant of a map as
that plant does (a lag-free car its commanded wheel angle, a lagging one its wheel's lag state),
as the single env with that plant would (``tests/test_vector_env.py``)."""


@dataclass(frozen=True)
class Args:
    out: Path = Path("results/robustness")
    """Folder of the table and of one sweep folder per map."""
    grid: int = 15
    """Points per axis of every map."""
    trials: int = 30
    """Budget per plant [trials]."""
    workers: int = 0
    """Local worker processes of each sweep (0: one per core)."""
    quick: bool = False
    """A 3 x 3 grid, 6 trials, the first map only: that the script runs."""
    report: bool = False
    """Write the table from the committed maps' ``sweep.json`` alone, computing nothing: a map's
    methods may lie in ``<map>`` and ``<map>_others`` (two runs of the same settings)."""


def committed_lines(out: Path, name: str) -> dict[str, dict[str, Any]]:
    """The summary lines of map ``name`` by method, from ``out/name`` then ``out/name_others``,
    whose settings must be the same but for the methods."""
    lines: dict[str, dict[str, Any]] = {}
    first: dict[str, Any] | None = None
    for folder in (out / name, out / f"{name}_others"):
        if not (folder / "sweep.json").exists():
            continue
        summary = read_report(folder / "sweep.json")
        settings = {
            k: v
            for k, v in summary["settings"].items()
            if k not in ("methods", "oracle", "out", "workers", "cell_timeout")
        }
        if first is not None and settings != first:
            raise ValueError(f"{folder}: not a run of {out / name}'s settings; it cannot complete that map")
        first = first or settings
        for line in summary["rows"]:
            lines.setdefault(line["method"], line)
    oracle = lines.get("oracle")
    if oracle is not None and oracle["converged_fraction"] == 1.0:  # all solvable: the share of it is the share
        lines = {m: {**line, "of_solvable": line["converged_fraction"]} if m != "oracle" else line
                 for m, line in lines.items()}  # fmt: skip
    return lines


def _run(args: Args, name: str, config: str, axes: Any, size: int, trials: int) -> list[dict[str, Any]]:
    """Map ``name`` computed (or resumed) with the oracle and every method: its summary lines."""
    return sweep(
        SweepArgs(
            config=config,
            methods=METHODS,
            grid=size,
            trials=trials,
            out=args.out / name,
            workers=args.workers,
            axes=axes,
            oracle=True,
        )
    )


def main(args: Args) -> list[dict[str, Any]]:
    grid, trials = (3, 6) if args.quick else (args.grid, args.trials)
    maps = dict(list(MAPS.items())[:1]) if args.quick else MAPS
    rows: list[dict[str, Any]] = []
    for name, (config, axes, own_grid) in maps.items():
        size = grid if args.quick or own_grid is None else own_grid
        if args.report and not (args.out / name / "sweep.json").exists():
            print(f"{name}: not computed yet (no {args.out / name / 'sweep.json'})")
            missing: dict[str, Any] = {"map": name, "grid": size, "axes": "-", "solvable": None}
            rows.append(missing | {k: None for m in METHODS for k in (f"{m}_of_solvable", f"{m}_median")})
            continue
        if args.report:
            by_method = committed_lines(args.out, name)
        else:
            by_method = {line["method"]: line for line in _run(args, name, config, axes, size, trials)}
        row: dict[str, Any] = {
            "map": name,
            "grid": size,
            "axes": " x ".join(read_report(args.out / name / "sweep.json")["axes"]),
            "solvable": by_method["oracle"]["converged_fraction"],
        }
        for method in METHODS:
            row[f"{method}_of_solvable"] = by_method[method]["of_solvable"]
            row[f"{method}_median"] = by_method[method]["median_trials"]
        rows.append(row)

    def share(value: float | None) -> str:
        return "-" if value is None else f"{100 * value:.1f} %"

    def median(value: float | None) -> str:
        return "-" if value is None else f"{value:g}"

    header = [
        "map",
        "axes",
        "grid",
        "oracle: solvable",
        *(f"{m}: converged of solvable (median trials)" for m in METHODS),
    ]
    cells = [
        [
            row["map"],
            row["axes"],
            f"{row['grid']} x {row['grid']}",
            share(row["solvable"]),
            *(f"{share(row[m + '_of_solvable'])} ({median(row[m + '_median'])})" for m in METHODS),
        ]
        for row in rows
    ]
    table = markdown_table(header, cells, [False, False, True, True, True, True, True])
    settings = {"grid": grid, "trials": trials, "methods": list(METHODS)}
    write_results(rows, args.out, "robustness", table, {"settings": settings})
    print(table)
    return rows


def parse(argv: list[str] | None = None) -> Args:
    parser = Parser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Args.out)
    parser.add_argument("--grid", type=int, default=Args.grid)
    parser.add_argument("--trials", type=int, default=Args.trials)
    parser.add_argument("--workers", type=int, default=Args.workers)
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--report", action="store_true", help="the table from the committed maps, computing nothing")
    ns = parser.parse_args(argv)
    return Args(out=ns.out, grid=ns.grid, trials=ns.trials, workers=ns.workers, quick=ns.quick, report=ns.report)


if __name__ == "__main__":
    arguments = parse()
    try:
        main(arguments)
    except ValueError as error:  # a committed map of the wrong shape (--report), named in one line
        print(f"robustness: {error}", file=sys.stderr)
        sys.exit(2)
    record_made(arguments.out, __file__, sys.argv[1:])
