"""``ilc-steering current DIR``: is every result in a folder made by the code in this tree?

A folder is a compare run (``cells/``, or ``compare.json`` in a clone that did not keep them), a
sweep (``rows/`` and ``oracle.json``; a robustness map is one), a folder a script made (its
``made.json``: a benchmark's artifacts, one code for all of them) or a folder that holds such
folders at any depth (``results/``). Each result records its code, the hash of its import closure
(:mod:`~ilc_steering.engine.provenance`); a result is stale when that closure hashes otherwise
today or its packaged config changed, and a report (``compare.json``, ``sweep.json``) when it was
not made from the results the folder holds. The lines say which results, grouped by learner, and
which files changed; the exit code is 0 only when nothing is stale.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from ilc_steering.engine.provenance import MADE, CodeRecord, read_made, read_run, results_hash
from ilc_steering.engine.staleness import freshness, staleness
from ilc_steering.errors import BadInput
from ilc_steering.output import MAX_RESULT_BYTES
from ilc_steering.readers import is_file, read_json

__all__ = ["check_folders", "run_folders"]


RECORDS = ("run.json", MADE)
"""The records that make a folder one of results: a command's run, or what a script made."""


def run_folders(folder: Path) -> list[Path]:
    """``folder`` and every folder below it that holds a ``run.json`` or a ``made.json``, sorted;
    ``ValueError`` when there is none."""
    if not folder.is_dir():
        raise BadInput(f"{folder}: not a folder")
    found = sorted({path.parent for name in RECORDS for path in folder.rglob(name) if is_file(path)})
    if not found:
        raise BadInput(f"{folder}: holds no results (no run.json or made.json in it or below it)")
    return found


def _results(folder: Path, stored: dict[str, Any]) -> tuple[dict[str, dict[str, Any]], list[dict[str, Any]] | None]:
    """Every result of the run folder, keyed by where it was read, with its config's name under
    ``"config"``; and the results its report should have been made from (None: nothing to check)."""
    found: dict[str, dict[str, Any]] = {}
    if (folder / "rows").is_dir() or stored.get("command") == "sweep":
        for path in sorted((folder / "rows").glob("*.json")):
            found[str(path)] = {**read_json(path, MAX_RESULT_BYTES), "config": stored.get("config")}
        rows = [{k: v for k, v in row.items() if k != "config"} for row in found.values()]
        oracle = folder / "oracle.json"
        if is_file(oracle):
            found[str(oracle)] = {**read_json(oracle, MAX_RESULT_BYTES), "config": stored.get("config")}
        return found, rows
    from ilc_steering.compare.cells import read_report

    cells = sorted((folder / "cells").glob("*.json"))
    for path in cells:
        cell = read_json(path, MAX_RESULT_BYTES)
        found[str(path)] = {**cell, "config": cell.get("scenario")}
    if cells:
        return found, [{k: v for k, v in cell.items() if k != "config"} for cell in found.values()]
    report = folder / "compare.json"
    if is_file(report):  # a clone that kept only the report: its cells are the results
        for index, cell in enumerate(read_report(report)["cells"]):
            found[f"{report}: cells[{index}]"] = {**cell, "config": cell.get("scenario")}
    return found, None


def unrecorded(folder: Path) -> list[Path]:
    """The folders at or below ``folder`` that hold files but no record of what made them, at or
    above them (up to ``folder``): results nobody can say are current."""
    found = []
    for path in sorted([folder, *(p for p in folder.rglob("*") if p.is_dir())]):
        if not any(child.is_file() and not child.name.startswith(".") for child in path.iterdir()):
            continue
        chain = [path, *path.relative_to(folder).parents]
        if not any(is_file(folder / part / name) for part in chain for name in RECORDS if part != path) and not any(
            is_file(path / name) for name in RECORDS
        ):
            found.append(path)
    return found


def check_folders(folders: list[Path]) -> tuple[bool, list[str]]:
    """Whether every result below each of ``folders`` is current, and the lines that say so."""
    lines: list[str] = []
    current = True
    for top in folders:
        for folder in unrecorded(top) if top.is_dir() else ():
            current = False
            lines.append(f"{folder}: STALE: holds results with no record of what made them (no run.json or made.json)")
        for folder in run_folders(top):
            if is_file(folder / MADE):
                ok, said = _made(folder)
                current &= ok
                lines += said
            if not is_file(folder / "run.json"):
                continue
            stored, record = read_run(folder)
            results, reported = _results(folder, stored)
            if not results:
                current = False
                lines.append(f"{folder}: STALE: holds no results")
                continue
            stale, said = freshness(folder, results, "method")
            if reported is not None and record.report is not None and record.report != results_hash(reported):
                report = (
                    "sweep.json" if stored.get("command") == "sweep" or (folder / "rows").is_dir() else "compare.json"
                )
                said.append(f"  report {report}: made from other results than the folder holds (run it again)")
                stale += 1
            cost = sum(float(r["wall_s"]) for r in results.values() if isinstance(r.get("wall_s"), (int, float)))
            head = f"{stale} of {len(results)} results stale" if stale else f"all {len(results)} results of this code"
            made = f"  making them again costs about {cost / 60:.1f} minutes of one core (their wall times)"
            lines += [f"{folder}: {'STALE' if stale else 'current'}: {head}", *said, *([] if stale else [made])]
            current &= not stale
    return current, lines


def _made(folder: Path) -> tuple[bool, list[str]]:
    """Whether what scripts made in ``folder`` is of the code in this tree, and the lines that say so."""
    current, lines = True, []
    for made in read_made(folder).values():
        why = staleness({"code": made.code}, {made.code: CodeRecord(made.roots, made.files)}, {})
        if why:
            current = False
            again = f"run it again (it took {made.cpu_s / 60:.1f} CPU minutes)"
            lines += [f"{folder}: STALE: {why.text()}", f"  made by {made.command} ({made.made}); {again}"]
        else:
            lines.append(f"{folder}: current: made by {made.command} ({made.made}; {made.cpu_s / 60:.1f} CPU minutes)")
    return current, lines
