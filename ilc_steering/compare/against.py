"""``compare --against DIR``: a new method's cells beside a committed run's, which is only read.

A committed run folder (``results/compare``, or any ``compare --out`` folder) holds ``run.json``
(its settings, the package version and each scenario's config content hash) and its cells, in
``cells/`` or, in a clone that did not keep them, in ``compare.json``. :func:`read_committed`
reads both and refuses a folder that is not a run of this kind; :func:`resolve_settings` takes
every setting the user left at its default from the committed run and refuses one given
otherwise, naming the option; :func:`check_out` keeps the output out of the committed folder.
:mod:`ilc_steering.compare.command` runs the rest: the committed cells are checked one by one and copied
into ``--out`` as they are, and only the cells the committed run lacks are computed, so the
report in ``--out`` is the joint one and the folder resumes like any other.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ilc_steering.compare.cells import CellRecord, read_report
from ilc_steering.engine.provenance import CodeRecord, read_run
from ilc_steering.errors import BadInput
from ilc_steering.output import RECORD_KEYS
from ilc_steering.readers import is_file, read_json
from ilc_steering.schema import check_record

__all__ = [
    "CommittedRun",
    "check_out",
    "committed_cells",
    "copy_committed",
    "describe",
    "joint_cells",
    "read_committed",
    "resolve_settings",
]

Cell = tuple[str, str, str, int]
"""A cell's (prior, method, scenario name, seed)."""
Budget = Callable[[str, str, str], int]
"""The budget of (prior, method, scenario name) [trials]."""

MAX_RUN_BYTES = 16 << 20
"""The largest cell file read from a committed run [bytes]."""


@dataclass(frozen=True)
class CommittedRun:
    """A committed compare run, as read: nothing in it is checked against this version yet."""

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
    return CommittedRun(folder, record, configs, list(cells.values()), failed, run.codes, name)


def _identity(cell: Any, where: str) -> str:
    """A cell's (prior, method, scenario, seed) as text, or ``ValueError`` naming ``where``."""
    names = ("prior", "method", "scenario", "seed")
    if not isinstance(cell, dict) or not all(name in cell for name in names):
        raise BadInput(f"{where}: not a cell (a JSON object with {', '.join(names)})")
    return json.dumps([cell[name] for name in names])


def _same(a: Any, b: Any) -> bool:
    """Equal as JSON: a tuple of seeds equals the list a run record holds."""
    return json.dumps(a, default=str) == json.dumps(b, default=str)


def _option(name: str, value: Any) -> str:
    """A setting as its command-line option."""
    flag = f"--{name.replace('_', '-')}"
    if isinstance(value, bool):
        return flag if value else f"no {flag}"
    if value is None:
        return f"no {flag}"
    if isinstance(value, (list, tuple)):
        return f"{flag} {' '.join(map(str, value))}"
    return f"{flag} {value}"


def describe(settings: dict[str, Any]) -> str:
    """A run's settings as the options that give them (its version last)."""
    options = [_option(name, value) for name, value in settings.items() if name != "version"]
    return f"{' '.join(options)}, ilc-steering {settings.get('version')}"


def resolve_settings(
    committed: CommittedRun, given: dict[str, Any], defaults: dict[str, Any], version: str
) -> dict[str, Any]:
    """The settings to run with: the committed run's wherever ``given`` holds the default (an
    option left out, or given at its default value: the run says which it took, :func:`describe`).

    ``ValueError`` naming ``--against`` and the option if the committed run was made by another
    ``version`` of the package, holds a setting this version has no option for, or if ``given``
    sets an option otherwise than the committed run (its cells would not be comparable)."""
    stored = committed.settings
    if stored.get("version") != version:
        raise _refuse(
            committed.label,
            f"made by ilc-steering {stored.get('version')}, this is {version}: its cells are not comparable "
            f"with this version's; recompute it with {version}, or install {stored.get('version')}",
        )
    values = {}
    for name, value in stored.items():
        if name == "version":
            continue
        if name not in defaults:
            raise _refuse(committed.label, f"its run.json holds a setting {name!r} that this version has no option for")
        if _same(given[name], defaults[name]):
            values[name] = tuple(value) if isinstance(value, list) else value
        elif not _same(given[name], value):
            raise _refuse(
                committed.label,
                f"it was run with {_option(name, value)}, not {_option(name, given[name])}; leave the option out "
                "to take the committed run's",
            )
    return values


def check_out(out: Path, folder: Path) -> None:
    """``ValueError`` if ``out`` is the committed ``folder`` or lies inside it: it is never written."""
    inside = out.resolve()
    committed = folder.resolve()
    if inside == committed or committed in inside.parents:
        raise BadInput(
            f"--out {out}: inside the committed run --against {folder}, which is only read; give another folder"
        )


def committed_cells(
    args: Any, committed: CommittedRun, configs: dict[str, str], budget: Budget
) -> tuple[dict[Cell, dict[str, Any]], dict[str, str]]:
    """The committed run's cells, each checked against its key and value by value, and the
    content hash of every scenario's config; ``ValueError`` if a scenario to run has another
    config than the committed run's cells of that name, or a committed cell is not one of its run."""
    from ilc_steering import __version__
    from ilc_steering.agents.base import PRIORS
    from ilc_steering.agents.registry import METHODS, is_custom
    from ilc_steering.compare.cells import check_cell

    for name, digest in configs.items():
        theirs = committed.configs.get(name)
        if theirs != digest:
            raise BadInput(
                f"{committed.label}: its {name!r} cells were computed with another config (content hash {theirs}, "
                f"this one's {digest}): the same name, another content"
            )
    hint = f"the committed run {committed.label} is not consistent; recompute it"
    held: dict[Cell, dict[str, Any]] = {}
    for where, cell in committed.cells:
        prior, method, scenario, seed = (cell[name] for name in ("prior", "method", "scenario", "seed"))
        known = isinstance(method, str) and (method in METHODS or is_custom(method))
        ours = isinstance(scenario, str) and scenario in committed.configs
        if prior not in PRIORS or not known or not ours or seed not in (args.seeds or ()):
            raise BadInput(
                f"{where}: not a cell of its run (prior {prior!r}, method {method!r}, scenario {scenario!r}, "
                f"seed {seed!r}); {hint}"
            )
        key = {
            "prior": prior,
            "method": method,
            "scenario": scenario,
            "seed": seed,
            "budget": budget(prior, method, scenario),
            "config_sha": committed.configs[scenario],
            "version": __version__,
        }
        held[(prior, method, scenario, seed)] = check_cell(cell, key, where, hint)
    scenarios = dict.fromkeys(cell[2] for cell in held)
    return held, {**{name: committed.configs[name] for name in scenarios}, **configs}


def joint_cells(args: Any, names: list[str], held: dict[Cell, dict[str, Any]]) -> list[Cell]:
    """The cells of an ``--against`` run, in the report's order: every committed one, and those of
    ``args.methods`` on ``names`` under ``args.priors`` that it lacks."""
    from ilc_steering.agents.base import PRIORS
    from ilc_steering.compare.args import seeds_of

    priors = [prior for prior in PRIORS if prior in args.priors or any(cell[0] == prior for cell in held)]
    scenarios = list(dict.fromkeys([*(cell[2] for cell in held), *names]))
    methods = list(dict.fromkeys([*(cell[1] for cell in held), *args.methods]))
    return [
        (prior, method, name, seed)
        for prior in priors
        for name in scenarios
        for method in methods
        for seed in seeds_of(args, prior)
        if (prior, method, name, seed) in held or (method in args.methods and prior in args.priors and name in names)
    ]


def copy_committed(
    held: dict[Cell, dict[str, Any]], paths: dict[Cell, Path], read: Callable[[Path, Cell], Any]
) -> None:
    """Write each committed cell into the run folder (its file ``paths[cell]``) as it is, where it
    lacks it; ``ValueError`` if the folder holds another result for one of them (``read``: the
    resume checker; it is never overwritten)."""
    from ilc_steering.output import write_json

    for cell, path in paths.items():
        found = held.get(cell)
        if found is None:
            continue
        if not path.exists():
            write_json(path, found)
        elif read(path, cell) != found:
            raise BadInput(f"{path}: holds another result than the committed run's; use another --out folder")
