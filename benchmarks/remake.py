"""Every committed result folder, the commands that make it, and what making it again costs.

    python benchmarks/remake.py [--dry-run] [--only FOLDER ...]

Each folder of :data:`FOLDERS` is judged as ``ilc-steering current`` judges it
(:func:`ilc_steering.current.judge`): current, or stale with the seconds of one core its stale
results took the last time (their recorded wall or CPU times; unknown where a result has no record
of what made it). A stale folder's commands are run in order, from the checkout's root: ``compare``
and ``sweep`` resume (they recompute exactly the stale and missing cells or rows, and keep the
rest), a script makes its artifacts again and records them (``made.json``). ``--dry-run`` prints
the verdicts, the commands and their cost, and runs nothing. A folder of records kept as measured
(``kept.json``) is no folder of this table: nothing remakes it. The exit code is 0 when every
folder is current (after the runs), 1 when one is still stale, the failing command's otherwise.
"""

from __future__ import annotations

import shlex
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

from ilc_steering.arguments import Parser
from ilc_steering.current import judge
from ilc_steering.engine.closure import checkout
from ilc_steering.errors import BadInput

SWEEP = "ilc-steering sweep forward_parking"
FOLDERS: dict[str, tuple[str, ...]] = {
    "results/compare": ("ilc-steering compare --out results/compare",),
    "results/robustness/tasks": ("python benchmarks/runs.py --folder robustness/tasks",),
    "results/robustness": (
        "python benchmarks/robustness.py --out results/robustness",
        "python benchmarks/robustness_diagnosis.py --out results/robustness",
    ),
    "results/sweep": (f"{SWEEP} --methods ilc_paper ilc newton newton_ilc --nu-b 1 0.5 --out results/sweep",),
    "results/sweep_blackbox": (
        f"{SWEEP} --methods least_squares gauss_newton nelder_mead cma_es --grid 21 --trials 1000 "
        "--out results/sweep_blackbox",
    ),
    "results/reproduce": ("python benchmarks/runs.py --folder reproduce",),
    "results/learners": ("python benchmarks/runs.py --folder learners",),
    "results/mario_calibration": ("python benchmarks/calibrate_mario.py",),
    "results/costs": ("python benchmarks/costs.py --out results/costs",),
    "results/disturbances": ("python benchmarks/disturbances.py --out results/disturbances",),
    "results/newton_ilc": ("python benchmarks/newton_ilc.py --out results/newton_ilc",),
    "results/noisy": ("python benchmarks/noisy.py",),
    "results/mujoco": ("python benchmarks/mujoco_car.py",),
    "results/highway/seeds100": (
        "python benchmarks/highway_parking.py --learners robust_ilc --seeds 0-99 --out results/highway/seeds100",
    ),
    "results/highway": (
        "python benchmarks/highway_parking.py",
        "python benchmarks/highway_pictures.py",
        "python benchmarks/highway_pictures.py --seed 12",
        "python benchmarks/highway_her.py",
        "python benchmarks/highway_her.py --zoo-cost 300",
    ),
    "results/benchmarks": (
        "python benchmarks/integrator.py --out results/benchmarks",
        "python benchmarks/throughput.py --out results/benchmarks",
        "python benchmarks/robots.py --first-run --out results/benchmarks",
        "python benchmarks/render.py --out results/benchmarks",
        "python benchmarks/rl_speed.py --out results/benchmarks",
        "python benchmarks/update_cost.py --out results/benchmarks",
    ),
    "results/bad_inputs": ("python benchmarks/bad_inputs.py",),
    "docs/figures": ("python benchmarks/tensorboard_chart.py",),
}
"""Folder (from the checkout's root) -> the commands that make it, in order. A folder's verdict
covers the folders below it (``results/highway`` its ``cells/``); a folder another command makes
is listed on its own, before the folder that holds it."""


@dataclass
class Args:
    dry_run: bool = False
    only: list[str] | None = None


def parse(argv: list[str] | None = None) -> Args:
    parser = Parser(description=__doc__.split("\n\n")[0] if __doc__ else None)
    parser.add_argument("--dry-run", action="store_true", help="print the verdicts and the commands; run nothing")
    parser.add_argument("--only", nargs="+", default=None, metavar="FOLDER", help="these folders only")
    args = parser.parse_args(argv, namespace=Args())
    unknown = sorted(set(args.only or ()) - set(FOLDERS))
    if unknown:
        parser.error(f"--only: {unknown[0]!r} is no folder of the table ({', '.join(FOLDERS)})")
    return args


def verdict(root: Path, folder: str) -> tuple[bool, str]:
    """Whether ``folder`` is current, and a line that says so with the cost of making it again."""
    path = root / folder
    if not path.is_dir():
        return False, f"{folder}: missing"
    try:
        found = judge([path])
    except BadInput as error:  # a record that is not one (a kept.json edited by hand, ...)
        return False, f"{folder}: STALE (its records cannot be read: {error})"
    if found.current:
        return True, f"{folder}: current"
    if found.cost_s is None:
        return False, f"{folder}: STALE (some results have no record of what made them: their cost is unknown)"
    return False, f"{folder}: STALE (about {found.cost_s / 60:.0f} min of one core to make again)"


def main(argv: list[str] | None = None) -> int:
    args = parse(argv)
    root = checkout()
    stale = 0
    for folder in args.only or FOLDERS:
        current, line = verdict(root, folder)
        print(line, flush=True)
        if current:
            continue
        for command in FOLDERS[folder]:
            print(f"  $ {command}", flush=True)
            if args.dry_run:
                continue
            start = time.monotonic()
            argv_ = shlex.split(command)
            if argv_[0] == "python":
                argv_[0] = sys.executable
            code = subprocess.run(argv_, cwd=root, check=False).returncode
            print(f"  exit {code} after {time.monotonic() - start:.0f} s", flush=True)
            if code:
                return code
        if not args.dry_run:
            current, line = verdict(root, folder)
            print(f"  now: {line}", flush=True)
        stale += not current
    return 1 if stale else 0


if __name__ == "__main__":
    sys.exit(main())
