"""A comparison's plan run on the engine: :func:`execute`.

:func:`execute` reads the :class:`~ilc_steering.compare.plan.Plan` and the run folder (``--out``)
only: it prepares the folder (:class:`~ilc_steering.engine.runs.RunFolder`; with ``--dry-run``
it only surveys it and says what a run would compute), writes back the cells a clone's
``compare.json`` holds and ``cells/`` lacks, copies the committed cells of ``--against`` as the
plan holds them, and computes every other cell once on the engine
(:func:`~ilc_steering.engine.runs.compute_cells`), each written the moment it finishes.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Callable, Mapping
from dataclasses import replace
from pathlib import Path
from typing import Any

from ilc_steering.compare.against import Cell, copy_committed, describe
from ilc_steering.compare.args import Args
from ilc_steering.compare.cells import cell_name, cell_path, read_cell, read_report, run_cell
from ilc_steering.compare.plan import Plan
from ilc_steering.engine.provenance import copy_codes
from ilc_steering.engine.runs import Cells, RunFolder, compute_cells, dry_run
from ilc_steering.errors import BadInput
from ilc_steering.output import write_json
from ilc_steering.readers import is_file

__all__ = ["Runner", "execute", "workers"]


def _report_cells(folder: Path) -> list[dict[str, Any]]:
    """The cells the folder's ``compare.json`` holds (none without one), checked against its schema."""
    report = folder / "compare.json"
    return read_report(report)["cells"] if is_file(report) else []


def _restore_cells(folder: Path) -> None:
    """Write back the cells that the folder's ``compare.json`` holds and ``cells/`` lacks (a clone of a
    run whose cells were not kept): the settings matched, so they are the cells this run would compute.
    Each is checked like any resumed cell when it is read (its config's hash and version included)."""
    report = folder / "compare.json"
    try:
        cells = _report_cells(folder)
    except ValueError as error:
        raise BadInput(f"{error}; use another --out folder") from None
    restored = 0
    seen: set[Path] = set()
    for cell in cells:
        path = cell_path(folder, cell["prior"], cell["method"], cell["scenario"], cell["seed"])
        if path in seen:
            raise BadInput(f"{report}: holds the cell {path.stem} twice; use another --out folder")
        seen.add(path)
        if not path.exists():
            write_json(path, cell)
            restored += 1
    if restored:
        print(f"restored {restored} cells from {report}", flush=True)


def _progress(cell: dict[str, Any]) -> str:
    reached = cell["trials_to"]
    return (
        f"{cell['prior']:7s} {cell['scenario']:26s} {cell['method']:13s} seed {cell['seed']}: "
        f"best {cell['best_error']:.2e}; 1 cm at trial {reached['1cm'] or '-'}, "
        f"0.5 mm / 0.5 mrad at {reached['0.5mm'] or '-'} ('-': not within {cell['budget']}); "
        f"{100 * cell['off_chart_fraction']:.0f}% off the chart; {cell['wall_s']:.1f} s"
    )


def workers(args: Args) -> int:
    return args.workers or os.cpu_count() or 1


Runner = Callable[..., dict[str, Any]]


def execute(the_plan: Plan, runner: Runner = run_cell) -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
    """Run the cells of ``the_plan``: everything was checked when it was made; each finished cell
    is written the moment it finishes; a cell that raises or outlives ``cell_timeout`` is written
    to ``failed/`` with its error and the run goes on (a resume computes it again)."""
    args = the_plan.args
    for warning in the_plan.warnings:
        print(f"ilc-steering: {warning}", file=sys.stderr, flush=True)
    folder = RunFolder(args.out, "cells", "compare")
    reports = [f"compare.{suffix}" for suffix in ("csv", "json", "md")]
    reports += [f"compare_{name}.png" for name in dict.fromkeys(cell[2] for cell in the_plan.grid)]
    reports.append("compare_profile.png")
    inline = runner is not run_cell
    progress_bar = args.progress_bar  # SB3's bar only where one process runs every cell (see before)

    def call(cell: Cell) -> tuple[Any, ...]:
        prior, method, name, seed = cell
        if inline:
            return args, prior, method, the_plan.scenario_of(name), seed
        budget = the_plan.budgets[prior, method, name]
        return replace(args, progress_bar=progress_bar), prior, method, the_plan.scenario_of(name), seed, budget

    def describe_cell(cell: Cell) -> str:
        prior, method, name, seed = cell
        return f"{prior:7s} {name:26s} {method:13s} seed {seed}"

    cells = Cells(
        keys=the_plan.grid,
        name=lambda cell: cell_name(*cell),
        read=lambda path, cell: read_cell(path, the_plan.identity(cell)),
        call=call,
        stamp=the_plan.stamp,
        roots=the_plan.roots,
        failure=lambda cell, message: {**the_plan.identity(cell), "error": message},
        describe=describe_cell,
        progress=_progress,
        cost=the_plan.cost,
        taken=frozenset(the_plan.held),
    )
    committed = the_plan.committed
    if args.dry_run:
        folder.check(the_plan.settings)
        held = {cell_name(*cell): found for cell, found in the_plan.held.items()}
        listed = {cell_name(c["prior"], c["method"], c["scenario"], c["seed"]): c for c in _report_cells(args.out)}
        for line in dry_run(folder, cells, workers(args), {**listed, **held}):
            print(line, flush=True)
        return [], []
    if folder.prepare(the_plan.settings, the_plan.configs, reports):
        _restore_cells(args.out)

    def before(todo: Mapping[Cell, Path]) -> None:
        nonlocal progress_bar
        progress_bar = args.progress_bar and args.backend != "ray" and min(workers(args), len(todo)) <= 1
        if committed is not None:
            print(
                f"--against {committed.folder}: {len(the_plan.held)} committed cells taken as they are (copied into "
                f"{args.out}/cells), {len(todo)} cells to compute, with its settings: {describe(committed.settings)}",
                flush=True,
            )

    if the_plan.held:
        paths = {cell: folder.path(cell_name(*cell)) for cell in the_plan.grid}
        with folder.locked():
            copy_committed(the_plan.held, paths, lambda path, cell: read_cell(path, the_plan.key(cell)))
            held_codes = {cell.get("code") for cell in the_plan.held.values()}
            copy_codes(args.out, {k: v for k, v in committed.codes.items() if k in held_codes} if committed else {})
    outcome = compute_cells(
        folder,
        cells,
        runner,
        backend=args.backend,
        workers=args.workers,
        timeout=args.cell_timeout,
        inline=inline,
        before=before,
    )
    return outcome.in_order(the_plan.grid)
