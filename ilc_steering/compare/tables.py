"""The comparison's tables in the README and the docs, generated from a committed run.

A Markdown file holds a generated table between two markers::

    <!-- compare-table: headline-1cm -->
    ...
    <!-- /compare-table -->

``ilc-steering tables results/compare --into README.md docs/comparison.md`` rewrites every such block
from the run's ``compare.json`` (its cells, summarized as ``compare`` summarizes them,
:mod:`~ilc_steering.compare.report`); ``--check`` rewrites nothing and exits 1 if a block differs,
which is what the tests run: a table in the docs is always the committed run's.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable
from dataclasses import fields, replace
from functools import partial
from pathlib import Path
from typing import Any

from ilc_steering.compare import cells as compare_cells
from ilc_steering.compare.args import Args
from ilc_steering.compare.report import iqm_table, main_table, ratio_table, statistic
from ilc_steering.compare.stats import LADDER_NAMES, ratios, summarize
from ilc_steering.engine.provenance import RunRecord, read_run
from ilc_steering.errors import BadInput
from ilc_steering.output import write_atomic
from ilc_steering.readers import read_text
from ilc_steering.tables import markdown_table

__all__ = ["BLOCK", "TABLES", "budget_check", "check", "headline", "render", "write"]

BLOCK = re.compile(r"(<!-- compare-table: ([a-z0-9.-]+) -->\n)(.*?)(<!-- /compare-table -->)", re.DOTALL)
MAX_TEXT_BYTES = 16 << 20


def headline(rows: list[dict[str, Any]], level: str, prior: str = "nominal") -> str:
    """Methods down, scenarios across: the median trials to ``level`` with its 95 % bootstrap
    interval and (seeds that got there / seeds)."""
    scenarios = list(dict.fromkeys(r["scenario"] for r in rows if r["prior"] == prior))
    methods = list(dict.fromkeys(r["method"] for r in rows if r["prior"] == prior))
    by = {(r["method"], r["scenario"]): r for r in rows if r["prior"] == prior}
    lines = []
    for method in methods:
        line = [method]
        for scenario in scenarios:
            row = by.get((method, scenario))
            if row is None:
                line.append("")
                continue
            entry = row[f"trials_to_{level}"]
            line.append(f"{statistic(entry, 'median', row['budget'])} ({entry['reached']}/{row['seeds']})")
        lines.append(line)
    header = ["method", *(s.replace("_", " ") for s in scenarios)]
    return markdown_table(header, lines, [False, *[True] * len(scenarios)])


def budget_check(cells: list[dict[str, Any]], levels: tuple[str, ...] = ("1cm", "0.5mm")) -> str:
    """Per method: its budget, and at each level the most trials its best seed needed on any
    (prior, scenario), against half the budget: a budget is ample when it is at least twice that."""
    best: dict[tuple[str, str, str], dict[str, float]] = {}
    budgets: dict[str, int] = {}
    for cell in cells:
        key = (cell["method"], cell["prior"], cell["scenario"])
        budgets[cell["method"]] = max(budgets.get(cell["method"], 0), cell["budget"])
        for level in levels:
            reached = cell["trials_to"][level]
            entry = best.setdefault(key, {})
            if reached is not None:
                entry[level] = min(entry.get(level, math.inf), reached)
    lines = []
    for method, budget in budgets.items():
        line = [method, str(budget)]
        for level in levels:
            needed = [e[level] for (m, _, _), e in best.items() if m == method and level in e]
            missed = sum(1 for (m, _, _), e in best.items() if m == method and level not in e)
            worst = max(needed) if needed else math.inf
            text = "no seed of any pair" if not needed else f"{worst:.0f}"
            if needed:
                text += " (ample)" if 2 * worst <= budget else " (**less than twice**)"
            if missed and needed:
                text += f"; none on {missed} of {missed + len(needed)} pairs"
            line.append(text)
        lines.append(line)
    header = [
        "method",
        "budget",
        *(f"best seed's trials to {LADDER_NAMES[level]}, most over (prior, scenario) pairs" for level in levels),
    ]
    return markdown_table(header, lines, [False, True, *[False] * len(levels)])


def _budgets(rows: list[dict[str, Any]]) -> str:
    seen: dict[str, set[int]] = {}
    for row in rows:
        seen.setdefault(row["method"], set()).add(row["budget"])
    return ", ".join(f"{m} {'/'.join(map(str, sorted(b)))}" for m, b in seen.items())


TABLES: dict[str, Callable[[list[dict[str, Any]], list[dict[str, Any]], dict[str, Any]], str]] = {
    "budget-check": lambda rows, entries, run: budget_check(run["cells"]),
    "headline-1cm": lambda rows, entries, run: headline(rows, "1cm"),
    "headline-0.5mm": lambda rows, entries, run: headline(rows, "0.5mm"),
    "nominal": lambda rows, entries, run: main_table(rows, "nominal"),
    "none": lambda rows, entries, run: main_table(rows, "none"),
    "iqm-nominal": lambda rows, entries, run: iqm_table(rows, "nominal"),
    "iqm-none": lambda rows, entries, run: iqm_table(rows, "none"),
    "ratios": lambda rows, entries, run: ratio_table(entries, ["black-box", "RL"]),
    "budgets": lambda rows, entries, run: f"Budgets [trials]: {_budgets(rows)}.\n",
    "run": lambda rows, entries, run: _run_line(run),
}
"""Every table a block may name."""


def _run_line(run: dict[str, Any]) -> str:
    record: RunRecord = run["record"]
    made, sessions = record.provenance, record.sessions
    wall = sum(session.wall_s for session in sessions)
    machine = sessions[-1].machine if sessions else None
    commit = (made.commit if made else None) or "no commit"
    codes = f"code {made.code}" if made and made.code else f"{len(record.codes)} codes (one per learner and robot)"
    seeds, ablation = run.get("seeds"), run.get("ablation_seeds")
    if not (isinstance(seeds, list) and all(type(seed) is int for seed in seeds)) or type(ablation) is not int:
        raise BadInput("run.json: seeds: a list of integers and ablation_seeds: an integer, as compare writes them")
    return (
        f"Made by ilc-steering {made.version if made else None}, {codes} (commit {commit[:12]}), in "
        f"{len(sessions)} session(s) of {wall / 60:.0f} min of wall time in all on "
        f"{machine.cpus if machine else None} cores ({machine.processor if machine else None}, Python "
        f"{machine.python if machine else None}); seeds {seeds} under prior=nominal, "
        f"the first {min(len(seeds), ablation)} under prior=none.\n"
    )


def _cells(folder: Path) -> list[dict[str, Any]]:
    """The cells of ``folder``'s ``compare.json``, each checked as ``compare --against`` checks a
    committed run's: one of its run (a method of this version, one of its scenarios and seeds,
    never twice) and value by value within its budget; ``ValueError`` naming the file and the cell.
    A table never publishes a cell its run could not have made."""
    from ilc_steering import __version__
    from ilc_steering.compare.against import committed_cells, resolve_settings
    from ilc_steering.compare.committed import read_committed
    from ilc_steering.compare.settings import check_options

    committed = read_committed(folder, label=str(folder), cell_files=False)
    defaults = {f.name: f.default for f in fields(Args)}
    settings = resolve_settings(committed, defaults, defaults, __version__)
    try:
        args = check_options(replace(Args(), **settings))
    except ValueError as error:
        raise BadInput(f"{folder / 'run.json'}: {error}") from None
    held, _ = committed_cells(args, committed, committed.configs, partial(compare_cells.budget, args))
    return list(held.values())


def _tables(folder: Path) -> dict[str, str]:
    if not (folder / "compare.json").is_file() or not (folder / "run.json").is_file():
        raise BadInput(f"{folder}: not a compare run folder with compare.json and run.json")
    cells = _cells(folder)
    stored, record = read_run(folder)
    run = {**stored, "record": record}
    from ilc_steering.agents import registry

    rows = summarize(cells)
    entries = ratios(rows, {"black-box": registry.ids("black-box"), "RL": registry.ids("RL")})
    return {name: make(rows, entries, {**run, "cells": cells}) for name, make in TABLES.items()}


def render(text: str, tables: dict[str, str], where: str = "") -> str:
    """``text`` with every block's table replaced by the one it names."""

    _blocks(text, where)

    def replace(match: re.Match[str]) -> str:
        name = match.group(2)
        if name not in tables:
            raise BadInput(f"{where}: a compare-table block names {name!r}; choose from {list(tables)}")
        return match.group(1) + tables[name].rstrip("\n") + "\n" + match.group(4)

    return BLOCK.sub(replace, text)


def write(folder: Path, files: list[Path]) -> list[Path]:
    """Rewrite the blocks of ``files`` from the run in ``folder``; returns the files changed."""
    tables = _tables(folder)
    changed = []
    for path in files:
        text = read_text(path, MAX_TEXT_BYTES)
        new = render(text, tables, str(path))
        if new != text:
            write_atomic(path, new)
            changed.append(path)
    return changed


def _blocks(text: str, where: str) -> None:
    """``ValueError`` for a marker that opens no well-formed block (it would be skipped silently)."""
    if text.count("<!-- compare-table:") != len(BLOCK.findall(text)):
        raise BadInput(f"{where}: a <!-- compare-table: NAME --> marker without its <!-- /compare-table --> or a name")


def check(folder: Path, files: list[Path]) -> list[str]:
    """The blocks of ``files`` that differ from the run in ``folder`` (``file: block``)."""
    tables = _tables(folder)
    stale = []
    for path in files:
        text = read_text(path, MAX_TEXT_BYTES)
        _blocks(text, str(path))
        for match in BLOCK.finditer(text):
            name = match.group(2)
            if name not in tables:
                raise BadInput(f"{path}: a compare-table block names {name!r}; choose from {list(tables)}")
            if match.group(3) != tables[name].rstrip("\n") + "\n":
                stale.append(f"{path}: {name}")
    return stale
