"""A committed compare run as read from disk, once: :class:`CommittedRun` and :func:`read_committed`.

A committed run folder (``results/compare``, or any ``compare --out`` folder) holds ``run.json``
(its settings, the package version, each scenario's config content hash and the codes its cells
record) and its cells, in ``cells/`` or, in a clone that did not keep them, in ``compare.json``.
:func:`read_committed` reads every file of it once, each checked against its schema, and refuses
a folder that is not a run of this kind. Whatever holds a run against it (``compare --against``,
:mod:`~ilc_steering.compare.against`; ``tables``) reads the :class:`CommittedRun`, never the
folder again.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ilc_steering.agents.base import PRIORS
from ilc_steering.compare.cells import CellRecord, read_report
from ilc_steering.engine.provenance import CodeRecord, read_run
from ilc_steering.errors import BadInput
from ilc_steering.output import RECORD_KEYS
from ilc_steering.readers import is_file, read_json
from ilc_steering.schema import check_record

__all__ = ["MAX_RUN_BYTES", "CommittedRun", "read_committed"]

MAX_RUN_BYTES = 16 << 20
"""The largest cell file read from a committed run [bytes]."""


@dataclass(frozen=True)
class CommittedRun:
    """A committed compare run, as read: each file checked against its schema, nothing in it
    checked against this version yet."""

    folder: Path
    settings: dict[str, Any]
    """``run.json`` without its configs: the budgets, seeds, ``quick`` and ``version``."""
    configs: dict[str, str]
    """Scenario (config) name -> the content hash of the config its cells were computed with."""
    cells: list[tuple[str, Any]] = field(default_factory=list)
    """``(where, cell)``: each cell as read, ``where`` naming its file (or its place in ``compare.json``)."""
    failed: int = 0
    """How many cells the committed run recorded as failed (they are not taken)."""
    codes: dict[str, CodeRecord] = field(default_factory=dict)
    """The codes its cells record (``run.json``'s ``codes``, :mod:`~ilc_steering.engine.provenance`)."""
    label: str = ""
    """How refusals name the run: ``--against DIR`` (or ``DIR`` for ``tables``)."""
    scenarios: tuple[str, ...] = ()
    """The config names it has cells of, in the order of ``configs``."""
    priors: tuple[str, ...] = ()
    """The priors it has cells of, in the order of :data:`~ilc_steering.agents.base.PRIORS`."""


def _refuse(label: str, problem: str) -> ValueError:
    return BadInput(f"{label}: {problem}")


def read_committed(folder: Path, label: str | None = None, cell_files: bool = True) -> CommittedRun:
    """The run record and every cell of the compare run folder ``folder``; ``ValueError`` (one
    line, naming ``label``, by default ``--against DIR``) if it is not one: no ``run.json``, a
    record without the package version or the configs' content hashes (written before they were
    kept, so its cells cannot be vouched for), a cell twice, or no cells. A cell in ``cells/``
    wins over its copy in ``compare.json``; without ``cell_files``, ``compare.json`` alone is read
    (what a clone holds: ``tables`` publishes it)."""
    name = label or f"--against {folder}"
    if not folder.is_dir():
        raise _refuse(name, "not a folder; give a compare run folder (one with run.json)")
    record_path = folder / "run.json"
    if not is_file(record_path):  # a FIFO, a link loop, ...: there, and refused by name when read
        raise _refuse(name, "no run.json, so this is not a compare run folder")
    try:
        stored, run = read_run(folder)  # checked against its schema (engine.provenance.RunRecord)
    except ValueError as error:
        raise _refuse(name, str(error)) from None
    record = dict(stored)
    configs = record.pop("configs", None)
    for key in RECORD_KEYS:
        record.pop(key, None)
    if "version" not in record or not isinstance(configs, dict):
        missing = "package version" if "version" not in record else "content hashes of its configs"
        raise _refuse(
            name,
            f"{record_path} records no {missing} (written before they were kept), so its cells cannot be "
            "checked against this version; recompute the run with this version",
        )
    if not all(isinstance(k, str) and isinstance(v, str) for k, v in configs.items()):
        raise _refuse(name, f"{record_path}: 'configs' must map scenario names to content hashes")
    cells: dict[str, tuple[str, Any]] = {}
    report = folder / "compare.json"
    if is_file(report):
        try:
            listed = read_report(report)["cells"]
        except ValueError as error:
            raise _refuse(name, str(error)) from None
        for index, cell in enumerate(listed):
            identity = _identity(cell, f"{report}: cells[{index}]")
            if identity in cells:
                raise _refuse(
                    name, f"{report} holds the cell {identity} twice ({cells[identity][0]} and cells[{index}])"
                )
            cells[identity] = (f"{report}: cells[{index}]", cell)
    for path in sorted((folder / "cells").glob("*.json")) if cell_files else ():
        try:
            cell = read_json(path, MAX_RUN_BYTES)
            check_record(CellRecord, cell, path)
        except ValueError as error:
            raise _refuse(name, str(error)) from None
        cells[_identity(cell, str(path))] = (str(path), cell)
    if not cells:
        raise _refuse(name, "holds no cells (neither cells/*.json nor compare.json)")
    failed = len(list((folder / "failed").glob("*.json")))
    held = [cell for _, cell in cells.values()]
    scenarios = tuple(scenario for scenario in configs if any(c["scenario"] == scenario for c in held))
    priors = tuple(prior for prior in PRIORS if any(c["prior"] == prior for c in held))
    return CommittedRun(folder, record, configs, list(cells.values()), failed, run.codes, name, scenarios, priors)


def _identity(cell: Any, where: str) -> str:
    """A cell's (prior, method, scenario, seed) as text, or ``ValueError`` naming ``where``."""
    names = ("prior", "method", "scenario", "seed")
    if not isinstance(cell, dict) or not all(name in cell for name in names):
        raise BadInput(f"{where}: not a cell (a JSON object with {', '.join(names)})")
    return json.dumps([cell[name] for name in names])
