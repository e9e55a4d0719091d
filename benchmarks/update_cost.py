"""What a ``robust_ilc`` update costs, in its family and outside it, and what ``reproduce`` costs.

Issue 52: "outside the family an update of at most 0.2 s of CPU (median, in a benchmark beside the
in-family update, same run)", and ``ilc-steering reproduce`` with a warm cache in at most 90 s of
CPU. For each seed, ``robust_ilc`` runs

- in its family: ``forward_parking`` and ``parallel_parking`` with the true wheelbase
  :data:`WHEELBASE` times the nominal one (the geometry's family explains every trial);
- outside it: ``experiment_forward`` and ``experiment_parallel`` (backlash, speed lag, encoders,
  noise: no fit reaches ``FIT_TOLERANCE``, every update searches globally);

and every update's CPU time (``time.process_time`` around ``learn``) is kept; the table gives
their median and quartiles per task. Then ``ilc-steering reproduce`` runs in a subprocess (its
CPU from ``resource.getrusage(RUSAGE_CHILDREN)``; run it once before, so the numba cache is warm).

    python benchmarks/update_cost.py [--quick] [--out DIR] [--seeds N] [--no-reproduce]

writes ``update_cost[.LABEL].{csv,json,md}`` (committed in ``results/benchmarks``).
"""

from __future__ import annotations

import dataclasses
import resource
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

import ilc_steering
from ilc_steering.agents.robust_ilc import RobustILC
from ilc_steering.arguments import Parser
from ilc_steering.config import SteeringConfig, load_config
from ilc_steering.engine.provenance import record_made
from ilc_steering.output import check_output_dir
from ilc_steering.runner import run_ilc
from ilc_steering.tables import markdown_table, write_results

__all__ = ["TASKS", "WHEELBASE", "Args", "main"]

WHEELBASE = 1.3
"""The in-family tasks' true wheelbase over the nominal one."""
TASKS: tuple[tuple[str, bool], ...] = (
    ("forward_parking", True),
    ("parallel_parking", True),
    ("experiment_forward", False),
    ("experiment_parallel", False),
)
"""(task, in the family) of every row."""


@dataclass(frozen=True)
class Args:
    quick: bool = False
    """One seed of four trials per task, no ``reproduce``: checks that the script runs (CI)."""
    out: Path = Path("results/update_cost")
    """Where the tables go."""
    seeds: int = 5
    """Seeds per task (1, 2, ...)."""
    reproduce: bool = True
    """Also time ``ilc-steering reproduce`` (a subprocess)."""
    label: str = ""
    """Written as ``update_cost.LABEL.*`` when given (``before``: the code before a change)."""


def task_config(name: str, in_family: bool) -> SteeringConfig:
    """The packaged task ``name``; in the family, with its true wheelbase :data:`WHEELBASE` times the nominal."""
    config = load_config(name)
    if not in_family:
        return config
    plant: Any = config.plant
    return dataclasses.replace(config, plant=dataclasses.replace(plant, true_wheelbase=WHEELBASE * plant.wheelbase))


@contextmanager
def timed_updates() -> Iterator[list[float]]:
    """The CPU time [s] of every ``RobustILC.learn`` called inside, in order."""
    seconds: list[float] = []
    learn = RobustILC.learn

    def timed(self: RobustILC, info: Any) -> None:
        began = time.process_time()
        learn(self, info)
        seconds.append(time.process_time() - began)

    RobustILC.learn = timed  # type: ignore[method-assign]
    try:
        yield seconds
    finally:
        RobustILC.learn = learn  # type: ignore[method-assign]


def reproduce_cpu() -> tuple[float, float]:
    """CPU and wall seconds of ``ilc-steering reproduce`` in a subprocess of this interpreter."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    began = time.perf_counter()
    with tempfile.TemporaryDirectory() as folder:
        command = [sys.executable, "-m", "ilc_steering", "reproduce", "--json-dir", folder]
        subprocess.run(command, check=True, stdout=subprocess.DEVNULL)
    wall = time.perf_counter() - began
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime), wall


def main(args: Args) -> list[dict[str, Any]]:
    out = check_output_dir(args.out, "--out")
    seeds = range(1, 2 if args.quick else args.seeds + 1)
    rows: list[dict[str, Any]] = []
    for name, in_family in TASKS:
        config = task_config(name, in_family)
        with timed_updates() as seconds:
            for seed in seeds:
                run_ilc(config, trials=4 if args.quick else None, learner="robust_ilc", seed=seed)
        q1, median, q3 = np.percentile(seconds, [25, 50, 75])
        row = {
            "task": name,
            "in_family": in_family,
            "seeds": len(seeds),
            "updates": len(seconds),
            "median_s": float(median),
            "q1_s": float(q1),
            "q3_s": float(q3),
            "max_s": float(np.max(seconds)),
            "total_s": float(np.sum(seconds)),
        }
        rows.append(row)
        print(row, flush=True)
    table = [
        [
            str(r["task"]),
            "in" if r["in_family"] else "outside",
            str(r["updates"]),
            f"{r['median_s']:.3f}",
            f"{r['q1_s']:.3f} - {r['q3_s']:.3f}",
            f"{r['max_s']:.3f}",
            f"{r['total_s']:.2f}",
        ]
        for r in rows
    ]
    header = ["task", "family", "updates", "median [s CPU]", "quartiles [s CPU]", "max [s CPU]", "total [s CPU]"]
    markdown = (
        f"CPU seconds per `robust_ilc` update (`time.process_time`), seeds 1-{len(seeds)}, in-family tasks with "
        f"the true wheelbase {WHEELBASE} times the nominal.\n\n"
        + markdown_table(header, table, [False, False, True, True, True, True, True])
    )
    extra: dict[str, Any] = {"args": {k: str(v) for k, v in dataclasses.asdict(args).items()}}
    if args.reproduce and not args.quick:
        cpu, wall = reproduce_cpu()
        extra["reproduce"] = {"cpu_s": cpu, "wall_s": wall}
        markdown += f"\n\n`ilc-steering reproduce` (warm cache): {cpu:.1f} s CPU, {wall:.1f} s wall.\n"
    extra["code"] = str(Path(ilc_steering.__file__).parent)
    write_results(rows, out, f"update_cost.{args.label}" if args.label else "update_cost", markdown, extra)
    print(markdown)
    return rows


def parse(argv: list[str] | None = None) -> Args:
    parser = Parser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="one seed of four trials per task, no reproduce")
    parser.add_argument("--out", type=Path, default=Args.out)
    parser.add_argument("--seeds", type=int, default=Args.seeds)
    parser.add_argument("--label", default=Args.label, help="write update_cost.LABEL.*")
    parser.add_argument("--no-reproduce", dest="reproduce", action="store_false", help="skip ilc-steering reproduce")
    return Args(**vars(parser.parse_args(argv)))


if __name__ == "__main__":
    arguments = parse()
    main(arguments)
    record_made(arguments.out, __file__, sys.argv[1:])
