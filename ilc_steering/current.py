"""``ilc-steering current DIR``: is every result in a folder made by the code in this tree?

A folder is a compare run (``cells/``, or ``compare.json`` in a clone that did not keep them), a
sweep (``rows/`` and ``oracle.json``; a robustness map is one), a folder a script made (its
``made.json``: a benchmark's artifacts, one code for all of them), a folder of records kept as
they were measured (its ``kept.json``: a measurement of the code before a fix, a CI machine's
times, a tuning that chose settings; each file named with what it is, the commit that recorded it
and when; reported, never stale: no code of this tree made it, and none should remake it) or a folder
that holds such folders at any depth (``results/``). Each result records its code, the hash of its import closure
(:mod:`~ilc_steering.engine.provenance`); a result is stale when that closure hashes otherwise
today or its packaged config changed, and a report (``compare.json``, ``sweep.json``) when it was
not made from the results the folder holds. The lines say which results, grouped by learner, and
which files changed; the exit code is 0 only when nothing is stale.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ilc_steering.engine.provenance import MADE, CodeRecord, read_made, read_run, results_hash
from ilc_steering.engine.staleness import freshness, staleness
from ilc_steering.errors import BadInput
from ilc_steering.output import MAX_RESULT_BYTES
from ilc_steering.readers import is_file, read_json

__all__ = ["Verdict", "check_folders", "judge", "run_folders"]


KEPT = "kept.json"
"""A folder's records of past measurements, kept as measured: file name -> what, commit, when."""
RECORDS = ("run.json", MADE, KEPT)
"""The records that make a folder one of results: a command's run, what a script made, or what is kept."""


def run_folders(folder: Path) -> list[Path]:
    """``folder`` and every folder below it that holds a ``run.json``, a ``made.json`` or a
    ``kept.json``, sorted; ``BadInput`` when there is none."""
    found = _recorded(folder)
    if not found:
        raise BadInput(f"{folder}: holds no results (no run.json, made.json or kept.json in it or below it)")
    return found


def _recorded(folder: Path) -> list[Path]:
    """:func:`run_folders`, none where there is none."""
    if not folder.is_dir():
        raise BadInput(f"{folder}: not a folder")
    return sorted({path.parent for name in RECORDS for path in folder.rglob(name) if is_file(path)})


def read_kept(folder: Path) -> dict[str, dict[str, str]]:
    """``folder/kept.json``: each kept file's name -> its what, commit and when (strings). ``BadInput``
    names a ``kept.json`` of another shape, or one that names a file the folder does not hold."""
    path = folder / KEPT
    kept = read_json(path, MAX_RESULT_BYTES)
    if not isinstance(kept, dict) or not kept:
        raise BadInput(f"{path}: must map each kept file to its what, commit and when")
    for name, entry in kept.items():
        if not (isinstance(entry, dict) and set(entry) == {"what", "commit", "when"}):
            raise BadInput(f"{path}: {name!r} must be {{what, commit, when}} (strings), got {entry!r:.100}")
        if not all(isinstance(v, str) for v in entry.values()):
            raise BadInput(f"{path}: {name!r} must be {{what, commit, when}} (strings), got {entry!r:.100}")
        if "/" in name or not is_file(folder / name):
            raise BadInput(f"{path}: names {name!r}, which is no file of {folder}")
    return kept


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
    above them (up to ``folder``): results nobody can say are current. A ``kept.json`` records the
    files it names, in its own folder only."""
    made = tuple(name for name in RECORDS if name != KEPT)
    found = []
    for path in sorted([folder, *(p for p in folder.rglob("*") if p.is_dir())]):
        files = {child.name for child in path.iterdir() if child.is_file() and not child.name.startswith(".")}
        if not files:
            continue
        chain = [path, *(folder / part for part in path.relative_to(folder).parents)]
        if any(is_file(part / name) for part in chain for name in made):
            continue
        named = {*read_kept(path), KEPT} if is_file(path / KEPT) else set()
        if files - named:
            found.append(path)
    return found


@dataclass(frozen=True)
class Verdict:
    """What :func:`judge` found."""

    current: bool
    """Whether every result is of the code in this tree."""
    lines: list[str]
    """What it says, folder by folder."""
    cost_s: float | None
    """Seconds of one core that making the stale results again took the last time (None: some have
    no record of what made them, so no one can say)."""


def check_folders(folders: list[Path]) -> tuple[bool, list[str]]:
    """Whether every result below each of ``folders`` is current, and the lines that say so."""
    verdict = judge(folders)
    return verdict.current, verdict.lines


def judge(folders: list[Path]) -> Verdict:
    """Every result below each of ``folders`` judged against the code in this tree."""
    lines: list[str] = []
    current, cost = True, 0.0
    unknown = False
    for top in folders:
        loose = unrecorded(top) if top.is_dir() else []
        for folder in loose:
            current, unknown = False, True
            lines.append(
                f"{folder}: STALE: holds results with no record of what made them (no run.json, made.json or kept.json)"
            )
        for folder in _recorded(top) if loose else run_folders(top):
            if is_file(folder / KEPT):
                kept = read_kept(folder)
                lines += [f"{folder}: kept: {kept_line(name, entry)}" for name, entry in sorted(kept.items())]
                if "run.json" in kept:
                    continue  # a run kept as it was (a tuning's): its cells are not this code's to judge
            if is_file(folder / MADE):
                ok, said, seconds = _made(folder)
                current &= ok
                cost += seconds
                lines += said
            if not is_file(folder / "run.json"):
                continue
            stored, record = read_run(folder)
            results, reported = _results(folder, stored)
            if not results:
                current, unknown = False, True
                lines.append(f"{folder}: STALE: holds no results")
                continue
            stale, said, seconds = freshness(folder, results, "method")
            cost += seconds
            if reported is not None and record.report is not None and record.report != results_hash(reported):
                report = (
                    "sweep.json" if stored.get("command") == "sweep" or (folder / "rows").is_dir() else "compare.json"
                )
                said.append(f"  report {report}: made from other results than the folder holds (run it again)")
                stale += 1
            total = sum(float(r["wall_s"]) for r in results.values() if isinstance(r.get("wall_s"), (int, float)))
            head = f"{stale} of {len(results)} results stale" if stale else f"all {len(results)} results of this code"
            made = f"  making them again costs about {total / 60:.1f} minutes of one core (their wall times)"
            lines += [f"{folder}: {'STALE' if stale else 'current'}: {head}", *said, *([] if stale else [made])]
            current &= not stale
    return Verdict(current, lines, None if unknown else cost)


def kept_line(name: str, entry: dict[str, str]) -> str:
    """What a kept file is, the commit that recorded it and when."""
    return f"{name}: {entry['what']} (recorded {entry['when']} in {entry['commit']}; kept as measured)"


def _made(folder: Path) -> tuple[bool, list[str], float]:
    """Whether what scripts made in ``folder`` is of the code in this tree, the lines that say so,
    and the CPU seconds the stale ones took."""
    current, lines, cost = True, [], 0.0
    for made in read_made(folder).values():
        why = staleness({"code": made.code}, {made.code: CodeRecord(made.roots, made.files)}, {})
        if why:
            current = False
            cost += made.cpu_s
            again = f"run it again (it took {made.cpu_s / 60:.1f} CPU minutes)"
            lines += [f"{folder}: STALE: {why.text()}", f"  made by {made.command} ({made.made}); {again}"]
        else:
            lines.append(f"{folder}: current: made by {made.command} ({made.made}; {made.cpu_s / 60:.1f} CPU minutes)")
    return current, lines, cost
