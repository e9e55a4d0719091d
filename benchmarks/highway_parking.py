"""ILC on highway-env's parking car (``parking-v0``): trials per goal over seeds 0-19.

For every parking-v0 seed and learner, a run of ``learning.trials`` trials on
:func:`~ilc_steering.envs.highway.highway_config`'s task, counted by two rules, the first trial
counted as 1: the first trial after which parking-v0's own success test passes
(``info["plant"]["is_success"]``, a weighted distance below 0.12) and the first whose true errors
are within 1 cm / 0.01 rad. A seed the generator refuses (no manoeuvre it tries serves it) is a row with its
reason; a goal one chart cannot serve is a manoeuvre of two segments (``segments`` 2), its
errors the worst over its waypoints. A crash is a trial that hit a wall or whose outline came within
:data:`~ilc_steering.envs.highway_plant.WALL_MARGIN` of one (a failed trial). Goals are learned
one after the other in seed order; ``first goal`` and ``later goals``
summarize seed 0's row apart from the rest (no learner here carries anything from one goal to the
next: see ``docs/highway.md``).

    python benchmarks/highway_parking.py [--quick] [--out DIR]

writes ``highway_parking.{csv,json,md}`` (committed in ``docs/highway``), one JSON per (learner,
seed) under ``OUT/cells`` as it finishes: a second call resumes from them. Each cell carries the
fingerprint of what made it (:func:`fingerprint`: the goal's generated config, the library's code,
the packages' versions); a cell of another fingerprint is refused (exit 2, one line), never mixed in
(with ``--quick``, CI's smoke test, it is made again).
One trial is one parking-v0 reset, whatever its segments (``segment_drives`` counts the segments
that drove the car, ``env_steps`` the action steps sent, as HER counts its environment steps;
``refused_trials`` the trials the pre-send check kept from the walls).
"""

from __future__ import annotations

import hashlib
import json
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from statistics import median
from typing import Any

import ilc_steering  # noqa: F401  (registers the envs)
from ilc_steering import segmented
from ilc_steering.arguments import Parser
from ilc_steering.config import load_config
from ilc_steering.engine.provenance import code_files, code_hash, packages
from ilc_steering.envs.highway import highway_config
from ilc_steering.errors import ConfigError
from ilc_steering.output import write_atomic
from ilc_steering.runner import run_ilc
from ilc_steering.tables import markdown_table, write_results

__all__ = ["Args", "main"]

CM, RAD = 0.01, 0.01
"""The tight test [m], [rad]."""


@dataclass(frozen=True)
class Args:
    quick: bool = False
    """Two seeds (a one-segment goal and a manoeuvre), one learner, four trials: checks that the script runs (CI)."""
    seeds: tuple[int, ...] = tuple(range(20))
    """parking-v0's reset seeds: the goals."""
    learners: tuple[str, ...] = ("robust_ilc", "newton_ilc", "ilc")
    """``run --learner`` names."""
    trials: int = 15
    """Trials per goal."""
    out: Path = Path("docs/highway")
    """Where the tables go (cells under ``OUT/cells``)."""


def _first(flags: list[bool]) -> int | None:
    return next((i + 1 for i, flag in enumerate(flags) if flag), None)


def _task(seed: int, trials: int) -> dict[str, Any] | str:
    """The goal's generated config, or why the generator refuses it."""
    try:
        return highway_config(seed, trials=trials)
    except ValueError as error:
        return str(error)


def fingerprint(learner: str, task: dict[str, Any] | str, code: str) -> str:
    """What makes two cells the same computation: the learner, the goal's config (or its refusal),
    the code's hash and the packages' versions."""
    data = json.dumps({"learner": learner, "task": task, "code": code, "packages": packages()}, sort_keys=True)
    return hashlib.sha256(data.encode()).hexdigest()[:16]


def _code() -> str:
    """The hash of the code that makes a cell (the engine's files, and the manoeuvre's learner)."""
    files = code_files()
    files["ilc_steering/segmented.py"] = hashlib.sha256(Path(segmented.__file__).read_bytes()).hexdigest()[:16]
    return code_hash(files)


def _cell(learner: str, seed: int, task: dict[str, Any] | str) -> dict[str, Any]:
    row: dict[str, Any] = {"learner": learner, "seed": seed}
    try:
        if isinstance(task, str):
            raise ValueError(task)
        config = load_config(task)
    except (ConfigError, ValueError) as error:
        return {**row, "refused": str(error)}
    start = time.perf_counter()
    result = run_ilc(config, learner=learner, seed=1)
    records = [r.to_json() for r in result.trials]
    success = [bool(r["plant"]["is_success"]) for r in records]
    tight = [r["cartesian_error"] <= CM and r["orientation_error"] <= RAD for r in records]
    return {
        **row,
        "refused": "",
        "trials_to_success": _first(success),
        "trials_to_1cm": _first(tight),
        "segments": len(config.segment_configs()),
        "segment_drives": sum(r["plant"].get("segments_driven", bool(r["plant"]["actions"])) for r in records),
        "crashes": sum(bool(r["plant"]["crashed"] or r["plant"].get("left_lot")) for r in records),
        "refused_trials": sum(bool(r["plant"].get("refused")) for r in records),
        "first_error_m": records[0]["cartesian_error"],
        "last_error_m": records[-1]["cartesian_error"],
        "last_error_rad": records[-1]["orientation_error"],
        "env_steps": sum(len(r["plant"]["actions"]) for r in records),
        "seconds": time.perf_counter() - start,
    }


def _summary(rows: list[dict[str, Any]], learner: str, trials: int) -> list[str]:
    """A learner's line: goals served and reached, the medians over all goals (a refused or missed
    goal counts as more than the budget) and over the goals served, the first served goal apart."""
    mine = [r for r in rows if r["learner"] == learner]
    served = [r for r in mine if not r["refused"]]
    never = trials + 1

    def count(rs: list[dict[str, Any]], key: str) -> str:
        if not rs:
            return "-"
        value = median([r.get(key) or never for r in rs])
        return f"> {trials}" if value == never else f"{value:g}"

    return [
        learner,
        f"{len(served)}/{len(mine)}",
        f"{sum(1 for r in mine if r.get('trials_to_1cm'))}/{len(mine)}",
        count(mine, "trials_to_success"),
        count(mine, "trials_to_1cm"),
        count(served, "trials_to_success"),
        count(served, "trials_to_1cm"),
        count(served[:1], "trials_to_1cm"),
        count(served[1:], "trials_to_1cm"),
        str(sum(r.get("crashes") or 0 for r in mine)),
    ]


def main(args: Args) -> list[dict[str, Any]]:
    """The table; ``ValueError`` naming the cell when a cell on disk has another fingerprint."""
    seeds, learners, trials = args.seeds, args.learners, args.trials
    if args.quick:
        seeds, learners, trials = (4, 12), ("robust_ilc",), 4
    cells = args.out / "cells"
    cells.mkdir(parents=True, exist_ok=True)
    rows: list[dict[str, Any]] = []
    code = _code()
    for learner in learners:
        for seed in seeds:
            path = cells / f"{learner}_seed{seed}_trials{trials}.json"
            task = _task(seed, trials)
            mark = fingerprint(learner, task, code)
            if path.is_file():
                row = json.loads(path.read_text())
                theirs = row.get("fingerprint") if isinstance(row, dict) else None
                if theirs == mark:
                    rows.append(row)
                    continue
                if not args.quick:  # a smoke test's cell of older code is made again; never mixed in
                    raise ValueError(
                        f"{path}: a cell of another computation (fingerprint {theirs} != {mark}: other code, "
                        "config or packages); give another --out or remove it"
                    )
            row = {**_cell(learner, seed, task), "fingerprint": mark}
            write_atomic(path, json.dumps(row))
            rows.append(row)
            print(json.dumps(row), flush=True)
    header = [
        "learner",
        "goals served",
        "1 cm reached",
        "median to success (all)",
        "median to 1 cm (all)",
        "median to success (served)",
        "median to 1 cm (served)",
        "first served goal",
        "later served goals",
        "crashes",
    ]
    table = markdown_table(header, [_summary(rows, name, trials) for name in learners], [False] + [True] * 9)
    per_seed = markdown_table(
        [
            "learner",
            "seed",
            "to success",
            "to 1 cm",
            "crashes",
            "first error [m]",
            "segments",
            "drives",
            "env steps",
            "refused trials",
            "refused",
        ],
        [
            [
                r["learner"],
                str(r["seed"]),
                str(r.get("trials_to_success") or "-"),
                str(r.get("trials_to_1cm") or "-"),
                str(r.get("crashes", "-")),
                f"{r['first_error_m']:.3g}" if "first_error_m" in r else "-",
                *(str(r.get(key, "-")) for key in ("segments", "segment_drives", "env_steps", "refused_trials")),
                r["refused"][:80],
            ]
            for r in rows
        ],
    )
    markdown = (
        f"# ILC on highway-env's parking car: parking-v0 seeds {seeds[0]}-{seeds[-1]}, {trials} trials per goal\n\n"
        "Trials counted from 1 (the first trial included); a goal not reached counts as more than the budget. "
        "A trial is one parking-v0 reset, whatever its segments; drives counts the segments that drove the car, "
        "env steps the action steps sent (HER's unit), refused trials those the pre-send check kept from a wall.\n\n"
        f"{table}\n{per_seed}"
    )
    keys = list(dict.fromkeys(key for row in rows for key in row))  # a refused goal's row has fewer
    rows = [{key: row.get(key) for key in keys} for row in rows]
    write_results(rows, args.out, "highway_parking", markdown, {"seeds": list(seeds), "trials": trials})
    print(table)
    return rows


if __name__ == "__main__":
    parser = Parser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--trials", type=int, default=Args.trials)
    parser.add_argument("--out", type=Path, default=Args.out)
    parser.add_argument("--learners", default=",".join(Args.learners))
    cli = parser.parse_args()
    try:
        main(Args(cli.quick, Args.seeds, tuple(cli.learners.split(",")), cli.trials, cli.out))
    except ValueError as error:
        print(f"error: {error}", file=sys.stderr)
        raise SystemExit(2) from None
