"""One engine for grids of cells: the run folder, its lock and resume, and every cell run once.

``compare`` (a cell: one learner on one scenario, seed and prior) and ``sweep`` (a row of a
robustness map) are thin layers on it. A command resolves its arguments once into a frozen plan
(:class:`~ilc_steering.compare.plan.Plan`, :class:`~ilc_steering.sweep.command.Plan`): every option checked,
every config loaded and hashed, every cell's key and budget known. The engine then

1. prepares the run folder (:meth:`RunFolder.prepare`): ``run.json`` records the settings, the
   package version and the content hash of each config; a resume with other settings, another
   version or another config under a name is refused, saying which
   (:func:`~ilc_steering.output.check_run_settings`);
2. holds an exclusive lock on it (:meth:`RunFolder.locked`): two runs never share a folder;
3. reads every finished result back through the command's checker (a resume never trusts a file
   it did not check), keeps those that are current (each records its code, the hash of the
   files its computation depends on, and what the command stamps on it: its config's content
   hash; :mod:`~ilc_steering.engine.provenance`) and computes the others, missing or stale
   (:func:`compute_cells`), in worker processes or Ray tasks (:mod:`~ilc_steering.engine.backends`);
4. writes each result the moment it arrives (finish), or its error under ``failed/`` (fail,
   named on stderr too); a resume computes the failed ones again.
"""

from __future__ import annotations

import fcntl
import os
import sys
import time
from collections.abc import Callable, Collection, Hashable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from typing import Any, Generic, TypeVar

from ilc_steering.engine.backends import run_calls
from ilc_steering.engine.options import cell_bound
from ilc_steering.engine.provenance import code, machine, provenance, record_codes
from ilc_steering.errors import BadInput
from ilc_steering.output import (
    MAX_RESULT_BYTES,
    RECORD_KEYS,
    check_output_dir,
    check_output_file,
    check_run_settings,
    differences,
    open_lock,
    record_session,
    write_json,
)
from ilc_steering.readers import is_file, read_json

__all__ = [
    "Cells",
    "Outcome",
    "Progress",
    "RunFolder",
    "Survey",
    "compute_cells",
    "dry_run",
    "stale_lines",
    "survey",
]

K = TypeVar("K", bound=Hashable)


@dataclass(frozen=True)
class RunFolder:
    """A run folder: ``run.json``, one file per finished result under ``results``, ``failed/``."""

    out: Path
    """The folder (``--out``)."""
    results: str
    """The sub-folder of finished results: ``cells`` or ``rows``."""
    command: str
    """The command that owns it, for messages: ``compare`` or ``sweep``."""

    def prepare(self, settings: dict[str, Any], configs: dict[str, str], reports: Sequence[str] = ()) -> bool:
        """Check the folder (``--out``), the files the report will write there (``reports``: each
        absent or a regular file, checked now, not after every cell has run) and its ``run.json``
        against ``settings``, record them with the configs' content hashes, and make the results
        folder; True if it resumes a run."""
        check_output_dir(self.out, "--out")
        for name in reports:
            check_output_file(self.out / name, "--out")
        results = self.out / self.results
        if results.exists() and not results.is_dir():
            raise BadInput(f"{results}: exists and is not a folder; this is not a {self.command} run folder")
        written = [self.out / name for name in reports]
        resumed = check_run_settings(self.out, settings, results, configs, provenance(), written, self.command)
        results.mkdir(exist_ok=True)
        return resumed

    def check(self, settings: dict[str, Any]) -> None:
        """:meth:`prepare`'s check of ``run.json`` against ``settings``, reading only (``--dry-run``)."""
        path = self.out / "run.json"
        if not is_file(path):
            return
        stored = read_json(path, MAX_RESULT_BYTES)
        if not isinstance(stored, dict):
            raise BadInput(f"{path}: not a run record (a JSON object); use another --out folder")
        stored = {k: v for k, v in stored.items() if k not in RECORD_KEYS}
        if stored != settings:
            raise BadInput(f"{path} was written with other settings: {differences(stored, settings)}")

    @contextmanager
    def locked(self) -> Iterator[None]:
        """Hold an exclusive lock on the folder: a second run on it is refused at once."""
        handle = open_lock(self.out / ".lock")  # a FIFO or a link loop in its place is refused, never waited on
        try:
            try:
                fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                raise BadInput(f"{self.out}: another {self.command} is running on this folder") from None
            try:
                yield
            finally:
                fcntl.flock(handle, fcntl.LOCK_UN)
        finally:
            os.close(handle)

    def path(self, name: str, failed: bool = False) -> Path:
        """The file of the result named ``name`` (or of its failure)."""
        return self.out / ("failed" if failed else self.results) / f"{name}.json"


@dataclass(frozen=True)
class Cells(Generic[K]):
    """What the engine needs of a command's cells: their keys, in the report's order, and per key."""

    keys: Sequence[K]
    """Every cell, in order."""
    name: Callable[[K], str]
    """The file name of a cell (injective)."""
    read: Callable[[Path, K], dict[str, Any]]
    """The resume checker: a finished cell read back and checked against its key (``ValueError``)."""
    call: Callable[[K], tuple[Any, ...]]
    """The arguments of ``function`` for a cell."""
    stamp: Callable[[K], dict[str, Any]]
    """What every finished cell records besides its result (its config's hash, the version): a
    finished cell that records other values is stale, and computed again."""
    roots: Callable[[K], Sequence[str]]
    """Where a cell's computation starts (:func:`~ilc_steering.engine.closure.closure`): its code,
    the hash of its closure, is stamped on it, and a cell of another code is stale."""
    failure: Callable[[K, str], dict[str, Any]]
    """The record of a failed cell."""
    describe: Callable[[K], str]
    """A cell in a line of text (for its failure)."""
    progress: Callable[[dict[str, Any]], str] | None = None
    """A finished cell in a line of text, printed after the run's progress bar (None: the bar alone)."""
    cost: Callable[[K], float] | None = None
    """A cell's expected cost [s]: the cells run longest first (no worker left alone with a long
    cell at the end), and the time left is estimated from it."""
    taken: Collection[K] = ()
    """Cells whose finished result is taken as it is, whatever its code (a committed run's, under
    ``compare --against``): never stale, never computed."""


class Progress:
    """The progress bar of a run and its estimate of the time left: the expected cost of the cells
    still to finish, scaled by the wall time the finished ones took against their expected cost."""

    WIDTH = 24

    def __init__(self, expected: Mapping[Any, float], workers: int) -> None:
        self.expected = dict(expected)
        self.total = len(self.expected)
        self.left = sum(self.expected.values())
        self.spent = 0.0
        self.done = 0
        self.workers = max(1, workers)
        self.start = time.monotonic()

    def line(self, key: Any) -> str:
        self.done += 1
        cost = self.expected.get(key, 0.0)
        self.left -= cost
        self.spent += cost
        elapsed = time.monotonic() - self.start
        rate = elapsed / self.spent if self.spent > 0 else 1.0 / self.workers
        seconds = max(0.0, self.left * rate)
        filled = round(self.WIDTH * self.done / max(1, self.total))
        bar = "#" * filled + "-" * (self.WIDTH - filled)
        left = f"{seconds / 60:.0f} min" if seconds >= 90 else f"{seconds:.0f} s"
        return f"[{bar}] {self.done}/{self.total} ({100 * self.done / max(1, self.total):.0f}%), about {left} left"


@dataclass
class Outcome(Generic[K]):
    """The finished and the failed cells of a run, by key."""

    done: dict[K, dict[str, Any]] = field(default_factory=dict)
    failed: dict[K, dict[str, Any]] = field(default_factory=dict)

    def in_order(self, keys: Sequence[K]) -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
        return [self.done[k] for k in keys if k in self.done], [self.failed[k] for k in keys if k in self.failed]


def compute_cells(
    folder: RunFolder,
    cells: Cells[K],
    function: Callable[..., dict[str, Any]],
    *,
    backend: str = "local",
    workers: int = 0,
    timeout: float | None = None,
    inline: bool = False,
    before: Callable[[Mapping[K, Path]], None] | None = None,
) -> Outcome[K]:
    """Every cell of ``cells`` in ``folder`` (prepared), under its lock: the finished ones read back
    through ``cells.read``, the others computed by ``function(*cells.call(key))`` on ``backend``
    (``inline``: in this process, called as it is: a test's hook), each written as it finishes.
    ``timeout`` [s] bounds each cell (None: the engine's default,
    :data:`~ilc_steering.engine.options.DEFAULT_CELL_TIMEOUT`, applied here). On the local backend
    the cells always run in worker processes that are killed at it, one worker included, so a
    cell stuck in compiled code or one whose learner ends its process (``os._exit``) is that
    cell's failure (:func:`~ilc_steering.engine.backends.run_calls`); on Ray the bound is a Python alarm
    in the cell's task, which a line on stderr says.
    ``before(todo)`` is called once the cells to compute are known (a message)."""
    timeout = cell_bound(timeout)
    outcome: Outcome[K] = Outcome()
    with folder.locked():
        found = survey(folder, cells, outcome)
        todo, stale, stamps = found.todo, found.stale, found.stamps
        computed = {stamp["code"]: cells.roots(key) for key, stamp in stamps.items() if "code" in stamp}
        record_codes(folder.out, computed, found.held)
        if before is not None:
            before(todo)
        if stale:
            print(f"{len(stale)} finished results are stale, computed again:", flush=True)
            for line in stale_lines(stale, cells.describe):
                print(f"  {line}", flush=True)
        if cells.cost is not None:  # the longest first
            expected = {key: float(cells.cost(key)) for key in todo}
            todo = dict(sorted(todo.items(), key=lambda item: -expected[item[0]]))
        else:
            expected = {key: 1.0 for key in todo}
        count = 1 if inline else min(workers or os.cpu_count() or 1, max(1, len(todo)))
        progress = Progress(expected, count)
        started, clock = datetime.now(timezone.utc), time.monotonic()

        def finish(key: K, result: dict[str, Any]) -> None:
            cell = {**result, **stamps[key]}
            write_json(folder.path(cells.name(key)), cell)
            folder.path(cells.name(key), failed=True).unlink(missing_ok=True)
            outcome.done[key] = cell
            text = progress.line(key)
            print(text if cells.progress is None else f"{text} {cells.progress(cell)}", flush=True)

        def fail(key: K, message: str) -> None:
            outcome.failed[key] = cells.failure(key, message)
            path = folder.path(cells.name(key), failed=True)
            path.parent.mkdir(exist_ok=True)
            write_json(path, outcome.failed[key])
            line = f"{cells.describe(key)}: FAILED, recorded in {path}: {message}"
            print(f"{progress.line(key)} {line}", flush=True)
            print(f"ilc-steering: {' '.join(line.split())}", file=sys.stderr, flush=True)

        if inline:
            for key in todo:
                finish(key, function(*cells.call(key)))
        else:
            calls = {key: cells.call(key) for key in todo}
            if backend == "ray" and calls:
                print(
                    f"ilc-steering: --backend ray: each cell's time limit ({timeout:g} s) is a Python alarm in its "
                    "Ray task, which cannot stop compiled code; --backend local can",
                    file=sys.stderr,
                    flush=True,
                )
            try:
                run_calls(function, calls, finish, backend, workers, fail, timeout)
            finally:
                _session(folder, todo, outcome, started, clock, count, backend, len(stale))
    return outcome


@dataclass
class Survey(Generic[K]):
    """A run folder's cells against this run: what is left to compute and why."""

    todo: dict[K, Path] = field(default_factory=dict)
    """The cells still to compute, missing or stale, in order."""
    stale: dict[K, list[str]] = field(default_factory=dict)
    """Each stale cell -> the stamp keys it records otherwise (``code``, ``config_sha``)."""
    stamps: dict[K, dict[str, Any]] = field(default_factory=dict)
    """Every cell's stamp under this run: its code and what the command stamps."""
    held: set[str] = field(default_factory=set)
    """The codes the finished cells on disk record (current or stale)."""
    wall: dict[K, float] = field(default_factory=dict)
    """Each stale cell's wall time when it was computed [s]: what computing it again costs."""


def survey(
    folder: RunFolder,
    cells: Cells[K],
    outcome: Outcome[K] | None = None,
    held: Mapping[str, dict[str, Any]] | None = None,
) -> Survey[K]:
    """Every cell of ``cells`` in ``folder``, read back through ``cells.read`` where it is finished,
    against the stamp this run gives it; the current ones go into ``outcome.done``. ``held``: cells
    by name that a run would restore before it starts (a report's), taken where no file is."""
    found: Survey[K] = Survey()
    for key in cells.keys:
        if key in cells.taken:  # taken as it is: its code is not this run's to judge
            stamp = found.stamps[key] = cells.stamp(key)
        else:
            stamp = found.stamps[key] = {**cells.stamp(key), "code": code(cells.roots(key))[0]}
        path = folder.path(cells.name(key))
        restored = (held or {}).get(cells.name(key))
        if not path.exists() and restored is None:
            found.todo[key] = path
            continue
        cell = cells.read(path, key) if restored is None or path.exists() else restored
        if isinstance(cell.get("code"), str):
            found.held.add(cell["code"])
        differ = [] if key in cells.taken else [name for name, value in stamp.items() if cell.get(name) != value]
        if differ:
            found.stale[key], found.todo[key] = differ, path
            if isinstance(cell.get("wall_s"), (int, float)):
                found.wall[key] = float(cell["wall_s"])
        elif outcome is not None:
            outcome.done[key] = cell
    return found


def dry_run(
    folder: RunFolder, cells: Cells[K], workers: int, held: Mapping[str, dict[str, Any]] | None = None
) -> list[str]:
    """What a run on ``folder`` would compute, and its estimated cost: the lines ``--dry-run``
    prints (``held``: as :func:`survey`)."""
    found = survey(folder, cells, held=held)
    missing = [key for key in found.todo if key not in found.stale]
    costs = [found.wall.get(key) for key in found.stale]
    costs += [None if cells.cost is None else float(cells.cost(key)) for key in missing]
    known = [c for c in costs if c is not None]
    cost = f"about {sum(known) / 60 / max(1, workers):.1f} min on {workers} workers"
    if len(known) < len(costs):
        cost += f" for {len(known)} of them (the others' cost unknown)"
    lines = [
        f"{folder.out}: {len(cells.keys) - len(found.todo)} of {len(cells.keys)} results current; {len(found.todo)} to "
        f"compute ({len(missing)} missing, {len(found.stale)} stale)" + (f", {cost}" if found.todo else "")
    ]
    lines += [f"  stale: {line}" for line in stale_lines(found.stale, cells.describe)]
    lines += [f"  missing: {cells.describe(key)}" for key in missing[:10]]
    return lines + ([f"  ... and {len(missing) - 10} more missing"] if len(missing) > 10 else [])


def stale_lines(stale: Mapping[Any, list[str]], describe: Callable[[Any], str], most: int = 10) -> list[str]:
    """The stale cells, a line each (at most ``most``, then how many more), with what differs."""
    names = {"code": "code", "config_sha": "config", "version": "version", "implementation": "RL backend"}

    def said(why: list[str]) -> str:
        return " and ".join(names.get(name, name) for name in why) + (" differ" if len(why) > 1 else " differs")

    lines = [f"{describe(key)}: its {said(why)}" for key, why in list(stale.items())[:most]]
    return lines + ([f"... and {len(stale) - most} more"] if len(stale) > most else [])


def _session(
    folder: RunFolder,
    todo: Mapping[Any, Path],
    outcome: Outcome[Any],
    started: datetime,
    clock: float,
    count: int,
    backend: str,
    stale: int = 0,
) -> None:
    """Record a session of work on the folder in its ``run.json`` (an interrupted one too)."""
    if todo:
        record_session(
            folder.out,
            {
                "started": started.isoformat(timespec="seconds"),
                "wall_s": round(time.monotonic() - clock, 1),
                "computed": sum(key in outcome.done for key in todo),
                "failed": len(outcome.failed),
                "workers": count,
                "backend": backend,
                "commit": provenance()["commit"],
                "machine": machine(),
                "packages": provenance()["packages"],
                "stale": stale,
            },
        )
