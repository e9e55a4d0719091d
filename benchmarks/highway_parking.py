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
summarize the first served goal's row apart from the rest. A learner named ``ID+carry`` is ``ID``
carrying its learning from goal to goal (``ilc-steering run A B --carry``): each goal starts from
what the last served goal handed on (its cell keeps what it was handed and hands on, and its
fingerprint holds what it was handed, so a resumed chain is the same computation). Each test
(parking-v0's success, 10 cm / 0.05 rad, 1 cm / 0.01 rad) is counted in trials and in environment
steps, every step of the trials up to the first that passes.

    python benchmarks/highway_parking.py [--quick] [--seeds 0-19] [--learners A,B+carry] [--out DIR]

writes ``highway_parking.{csv,json,md}`` (committed in ``results/highway``), one JSON per (learner,
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
from ilc_steering.agents.registry import lookup
from ilc_steering.arguments import Parser
from ilc_steering.config import load_config
from ilc_steering.engine.provenance import code, packages, record_made
from ilc_steering.envs.highway import highway_config
from ilc_steering.errors import ConfigError
from ilc_steering.output import write_atomic
from ilc_steering.runner import run_ilc
from ilc_steering.tables import markdown_table, write_results

__all__ = ["CARRY", "SUMMARY_HEADER", "Args", "main", "summary"]

CM, RAD = 0.01, 0.01
"""The tight test [m], [rad]."""
LOOSE = (0.10, 0.05)
"""The loose test [m], [rad] (as HER's curve, ``benchmarks/highway_her.py``)."""
CARRY = "+carry"
"""A learner's suffix: it carries its learning from goal to goal."""


@dataclass(frozen=True)
class Args:
    quick: bool = False
    """Two seeds (a one-segment goal and a manoeuvre), one learner, four trials: checks that the script runs (CI)."""
    seeds: tuple[int, ...] = tuple(range(20))
    """parking-v0's reset seeds: the goals."""
    learners: tuple[str, ...] = ("robust_ilc", "robust_ilc+carry", "newton_ilc", "ilc")
    """``run --learner`` names."""
    trials: int = 15
    """Trials per goal."""
    out: Path = Path("results/highway")
    """Where the tables go (cells under ``OUT/cells``)."""


def _first(flags: list[bool]) -> int | None:
    return next((i + 1 for i, flag in enumerate(flags) if flag), None)


def _task(seed: int, trials: int) -> dict[str, Any] | str:
    """The goal's generated config, or why the generator refuses it."""
    try:
        return highway_config(seed, trials=trials)
    except ValueError as error:
        return str(error)


def fingerprint(learner: str, task: dict[str, Any] | str, code: str, carried: dict[str, Any] | None = None) -> str:
    """What makes two cells the same computation: the learner, the goal's config (or its refusal),
    what it was handed by the last goal (``+carry``), the code's hash and the packages' versions."""
    data: dict[str, Any] = {"learner": learner, "task": task, "code": code, "packages": packages()}
    if carried is not None:
        data["carried"] = carried
    return hashlib.sha256(json.dumps(data, sort_keys=True).encode()).hexdigest()[:16]


def roots(learner: str) -> tuple[str, ...]:
    """Where a cell of ``learner`` starts (:mod:`ilc_steering.engine.closure`): this script, the
    learner's sources and highway-env's plant."""
    return (
        "benchmarks/highway_parking.py",
        *lookup(learner.removesuffix(CARRY)).sources(),
        "ilc_steering.envs.highway_plant",
    )


def _code(learner: str) -> str:
    """The hash of the code that makes a cell of ``learner``: its import closure."""
    return code(roots(learner))[0]


def _steps_to(flags: list[bool], steps: list[int]) -> int | None:
    """The environment steps of every trial up to the first whose flag is set."""
    first = _first(flags)
    return None if first is None else sum(steps[:first])


def _cell(learner: str, seed: int, task: dict[str, Any] | str, carried: dict[str, Any] | None) -> dict[str, Any]:
    row: dict[str, Any] = {"learner": learner, "seed": seed}
    try:
        if isinstance(task, str):
            raise ValueError(task)
        config = load_config(task)
    except (ConfigError, ValueError) as error:
        return {**row, "refused": str(error)}
    start = time.perf_counter()
    carry = learner.endswith(CARRY)
    result = run_ilc(config, learner=learner.removesuffix(CARRY), seed=1, carried=carried, transfer=carry)
    records = [r.to_json() for r in result.trials]
    success = [bool(r["plant"]["is_success"]) for r in records]
    tight = [r["cartesian_error"] <= CM and r["orientation_error"] <= RAD for r in records]
    loose = [r["cartesian_error"] <= LOOSE[0] and r["orientation_error"] <= LOOSE[1] for r in records]
    steps = [len(r["plant"]["actions"]) for r in records]
    return {
        **row,
        "refused": "",
        "trials_to_success": _first(success),
        "trials_to_10cm": _first(loose),
        "trials_to_1cm": _first(tight),
        "env_steps_to_success": _steps_to(success, steps),
        "env_steps_to_10cm": _steps_to(loose, steps),
        "env_steps_to_1cm": _steps_to(tight, steps),
        "segments": len(config.segment_configs()),
        "segment_drives": sum(r["plant"].get("segments_driven", bool(r["plant"]["actions"])) for r in records),
        "crashes": sum(bool(r["plant"]["crashed"] or r["plant"].get("left_lot")) for r in records),
        "refused_trials": sum(bool(r["plant"].get("refused")) for r in records),
        "first_error_m": records[0]["cartesian_error"],
        "last_error_m": records[-1]["cartesian_error"],
        "last_error_rad": records[-1]["orientation_error"],
        "env_steps": sum(steps),
        "seconds": time.perf_counter() - start,
        **({"started_from": result.started_from, "carried": result.carried} if carry else {}),
    }


def summary(rows: list[dict[str, Any]], learner: str, trials: int) -> list[str]:
    """A learner's line: goals served; goals that pass each test within the budget; the medians
    over all goals of the trials and environment steps to parking-v0's success and to 1 cm (a
    refused or missed goal counts as more than the budget); trials to 1 cm of the first served
    goal and the median of the later ones; crashes."""
    mine = [r for r in rows if r["learner"] == learner]
    served = [r for r in mine if not r["refused"]]
    never = float("inf")

    def count(rs: list[dict[str, Any]], key: str) -> str:
        if not rs:
            return "-"
        value = median([r.get(key) or never for r in rs])
        return ("> budget" if key.startswith("env") else f"> {trials}") if value == never else f"{value:,g}"

    def passed(key: str) -> str:
        return f"{sum(1 for r in mine if r.get(key))}/{len(mine)}"

    return [
        learner.replace(CARRY, " (carried)"),
        f"{len(served)}/{len(mine)}",
        passed("trials_to_success"),
        passed("trials_to_10cm"),
        passed("trials_to_1cm"),
        count(mine, "trials_to_success"),
        count(mine, "trials_to_1cm"),
        count(mine, "env_steps_to_success"),
        count(mine, "env_steps_to_1cm"),
        count(served[:1], "trials_to_1cm"),
        count(served[1:], "trials_to_1cm"),
        str(sum(r.get("crashes") or 0 for r in mine)),
    ]


SUMMARY_HEADER = [
    "method",
    "goals served",
    "parking-v0 success",
    "10 cm / 0.05 rad",
    "1 cm / 0.01 rad",
    "median trials to success",
    "median trials to 1 cm",
    "median env steps to success",
    "median env steps to 1 cm",
    "first goal: trials to 1 cm",
    "later goals: median to 1 cm",
    "crashes",
]
"""The summary's columns (``benchmarks/highway_table.py`` adds HER's line under them)."""


def main(args: Args) -> list[dict[str, Any]]:
    """The table; ``ValueError`` naming the cell when a cell on disk has another fingerprint."""
    seeds, learners, trials = args.seeds, args.learners, args.trials
    if args.quick:
        seeds, learners, trials = (4, 12), ("robust_ilc" + CARRY,), 4
    cells = args.out / "cells"
    cells.mkdir(parents=True, exist_ok=True)
    rows: list[dict[str, Any]] = []
    for learner in learners:
        made_by = _code(learner)
        carried: dict[str, Any] | None = None  # what the last served goal handed on (``+carry``)
        for seed in seeds:
            path = cells / f"{learner}_seed{seed}_trials{trials}.json"
            task = _task(seed, trials)
            mark = fingerprint(learner, task, made_by, carried)
            if path.is_file():
                row = json.loads(path.read_text())
                theirs = row.get("fingerprint") if isinstance(row, dict) else None
                if theirs == mark:
                    rows.append(row)
                    carried = row.get("carried") or carried
                    continue
                if not args.quick:  # a smoke test's cell of older code is made again; never mixed in
                    raise ValueError(
                        f"{path}: a cell of another computation (fingerprint {theirs} != {mark}: other code, "
                        "config or packages); give another --out or remove it"
                    )
            row = {**_cell(learner, seed, task, carried), "fingerprint": mark}
            write_atomic(path, json.dumps(row))
            rows.append(row)
            carried = row.get("carried") or carried
            print(json.dumps(row), flush=True)
    table = markdown_table(SUMMARY_HEADER, [summary(rows, name, trials) for name in learners], [False] + [True] * 11)
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
    parser.add_argument("--seeds", default="0-19", help="parking-v0 seeds: FIRST-LAST (default: 0-19)")
    cli = parser.parse_args()
    first, _, last = cli.seeds.partition("-")
    if not (first.isdigit() and last.isdigit() and int(first) <= int(last)):
        print(f"error: --seeds: {cli.seeds!r} is not FIRST-LAST (e.g. 0-99)", file=sys.stderr)
        raise SystemExit(2)
    try:
        main(
            Args(
                cli.quick, tuple(range(int(first), int(last) + 1)), tuple(cli.learners.split(",")), cli.trials, cli.out
            )
        )
    except ValueError as error:
        print(f"error: {error}", file=sys.stderr)
        raise SystemExit(2) from None
    record_made(cli.out, __file__, sys.argv[1:])
