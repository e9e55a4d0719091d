"""``ilc-steering current DIR``: is every result in a folder made by the code in this tree?

A folder is a compare run (``cells/``, or ``compare.json`` in a clone that did not keep them), a
sweep (``rows/`` and ``oracle.json``; a robustness map is one) or a folder that holds such folders
at any depth (``results/``). Each result records its code, the hash of its import closure
(:mod:`~ilc_steering.engine.provenance`); a result is stale when that closure hashes otherwise
today or its packaged config changed, and a report (``compare.json``, ``sweep.json``) when it was
not made from the results the folder holds. The lines say which results, grouped by learner, and
which files changed; the exit code is 0 only when nothing is stale.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from ilc_steering.engine.provenance import read_run, results_hash
from ilc_steering.engine.staleness import freshness
from ilc_steering.output import MAX_RESULT_BYTES
from ilc_steering.readers import is_file, read_json

__all__ = ["check_folders", "run_folders"]


def run_folders(folder: Path) -> list[Path]:
    """``folder`` if it holds a ``run.json``, else every folder below it that does, sorted;
    ``ValueError`` when there is none."""
    if is_file(folder / "run.json"):
        return [folder]
    if not folder.is_dir():
        raise ValueError(f"{folder}: not a folder")
    found = sorted(path.parent for path in folder.rglob("run.json") if is_file(path))
    if not found:
        raise ValueError(f"{folder}: holds no run folder (no run.json in it or below it)")
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


def check_folders(folders: list[Path]) -> tuple[bool, list[str]]:
    """Whether every result below each of ``folders`` is current, and the lines that say so."""
    lines: list[str] = []
    current = True
    for top in folders:
        for folder in run_folders(top):
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
            head = f"{stale} of {len(results)} results stale" if stale else f"all {len(results)} results of this code"
            lines += [f"{folder}: {'STALE' if stale else 'current'}: {head}", *said]
            current &= not stale
    return current, lines
