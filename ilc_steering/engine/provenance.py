"""What made a run's results, and whether the code in the tree would make them again.

Every result of a run folder (a comparison's cell, a map's row, its oracle) records under
``"code"`` the hash of the files its computation depends on: the import closure of its roots
(:mod:`~ilc_steering.engine.closure`: the cell maker, the env, its learner, its robot, an RL
method's hyperparameter file). ``run.json`` (:class:`~ilc_steering.engine.runs.RunFolder`) holds

- ``codes``: each code its results record -> its roots and every file's own hash, so that a stale
  result names what changed;
- ``provenance``: the package version, the git commit of the tree the first results came from
  (None outside a git checkout) and whether the package differed from it (``dirty``), and the
  versions of the numerical packages;
- ``sessions``: one line per session of work on the folder (when, the wall time, the cells
  computed and failed, the workers, the machine, its commit and packages);
- ``report``: the content hash of the results its report (``compare.json``, ``sweep.json``) was
  made from.

A result is *current* when the closure of its roots hashes today as it did (and its packaged
config has the content it had): a change to ``agents/newton_ilc.py`` stales the results
``newton_ilc`` computed and nothing else; a change to the integrator stales every result it
integrated. A resume recomputes exactly the stale results and keeps the others
(:func:`~ilc_steering.engine.runs.compute_cells`); ``ilc-steering current DIR``
(:mod:`~ilc_steering.engine.staleness`) says which are stale and why, and whether the report is
of the results. A folder a script made (a benchmark's artifacts) records its command and code in
``made.json`` (:func:`record_made`).
"""

from __future__ import annotations

import os
import platform
import subprocess
import sys
from collections.abc import Iterable, Mapping
from dataclasses import asdict, dataclass, field
from functools import cache, lru_cache
from pathlib import Path
from typing import Any

from ilc_steering import __version__
from ilc_steering.engine.closure import closure, code_of
from ilc_steering.errors import BadInput
from ilc_steering.output import RECORD_KEYS

__all__ = [
    "MADE",
    "PACKAGES",
    "CodeRecord",
    "Machine",
    "MadeRecord",
    "Provenance",
    "ProvenanceRecord",
    "RunRecord",
    "Session",
    "changed",
    "code",
    "copy_codes",
    "machine",
    "provenance",
    "read_made",
    "read_run",
    "record_codes",
    "record_made",
    "record_report",
    "results_hash",
]


@dataclass(frozen=True)
class ProvenanceRecord:
    """A ``run.json``'s ``provenance``, as read back (the schema: :mod:`ilc_steering.schema`)."""

    version: str
    commit: str | None
    dirty: bool | None
    packages: dict[str, str]
    code: str | None = None
    """Records written before each result kept its own: one hash of every file (stale today)."""
    files: dict[str, str] = field(default_factory=dict)
    """As ``code``: the files of that hash."""


@dataclass(frozen=True)
class CodeRecord:
    """One code of a run's results: where its computation starts, and the hash of each file it reached."""

    roots: tuple[str, ...]
    files: dict[str, str]


@dataclass(frozen=True)
class Machine:
    """The machine a session ran on."""

    platform: str
    processor: str
    cpus: int | None
    python: str


@dataclass(frozen=True)
class Session:
    """One session of work on a run folder."""

    started: str
    wall_s: float
    computed: int
    failed: int
    workers: int
    backend: str
    commit: str | None
    machine: Machine
    packages: dict[str, str | None] | None = None
    """The numerical packages' versions of this session (None in records written before it was
    kept): a resume keeps the provenance of the first results, and each session says its own."""
    stale: int | None = None
    """The results it found stale and computed again (None in records written before)."""


@dataclass(frozen=True)
class RunRecord:
    """What every ``run.json`` holds besides its command's settings, checked when read back: what
    made it, the packaged configs it used (name -> content hash), the codes of its results, its
    sessions and the results its report was made from."""

    provenance: ProvenanceRecord | None = None
    configs: dict[str, str] = field(default_factory=dict)
    sessions: tuple[Session, ...] = ()
    codes: dict[str, CodeRecord] = field(default_factory=dict)
    report: str | None = None
    command: str | None = None


def read_run(folder: Path) -> tuple[dict[str, Any], RunRecord]:
    """``folder/run.json`` as read (the command's settings with it) and its :class:`RunRecord`,
    checked: ``ValueError`` naming the file and the key if it is not a run record or a key is of
    the wrong type, or if it contradicts itself (a code that is not the hash of its files). A
    record is a file on disk: hostile until checked."""
    from ilc_steering.errors import ConfigError
    from ilc_steering.readers import read_json
    from ilc_steering.schema import validate

    path = folder / "run.json"
    stored = read_json(path, 1 << 24)
    if not isinstance(stored, dict):
        raise BadInput(f"{path}: not a run record (a JSON object)")
    parts = {key: stored[key] for key in RECORD_KEYS if key in stored}
    try:
        record: RunRecord = validate(RunRecord, parts)
    except ConfigError as error:
        raise BadInput(f"{path}: {error}") from None
    for digest, made in record.codes.items():
        if code_of(made.files) != digest:
            raise BadInput(
                f"{path}: codes.{digest}: not the hash of its files ({code_of(made.files)}): the record contradicts "
                "itself"
            )
    return stored, record


PACKAGES = (
    "numpy",
    "scipy",
    "numba",
    "gymnasium",
    "torch",
    "stable-baselines3",
    "sb3-contrib",
    "sbx-rl",
    "jax",
    "botorch",
    "cma",
    "highway-env",
    "mujoco",
)
"""The distributions whose versions a run records (those installed)."""

Provenance = dict[str, Any]


@cache
def _closure(roots: tuple[str, ...]) -> tuple[str, tuple[tuple[str, str], ...]]:
    files = closure(roots)
    return code_of(files), tuple(files.items())


def code(roots: Iterable[str]) -> tuple[str, dict[str, str]]:
    """The code of a result whose computation starts at ``roots`` (computed once per process), and its files."""
    digest, files = _closure(tuple(roots))
    return digest, dict(files)


def _git(*args: str) -> str | None:
    from importlib import util

    spec = util.find_spec("ilc_steering")
    if spec is None or not spec.submodule_search_locations:
        return None
    root = Path(next(iter(spec.submodule_search_locations))).parent
    if not (root / ".git").exists():
        return None
    try:
        done = subprocess.run(["git", "-C", str(root), *args], capture_output=True, text=True, timeout=10, check=True)
    except (OSError, subprocess.SubprocessError):
        return None
    return done.stdout.strip()


def _commit() -> dict[str, Any]:
    commit = _git("rev-parse", "HEAD")
    if commit is None:
        return {"commit": None, "dirty": None}
    status = _git("status", "--porcelain", "--", "ilc_steering", "agents", "envs", "configs")
    return {"commit": commit, "dirty": bool(status)}


def packages() -> dict[str, str]:
    """The installed versions of :data:`PACKAGES`."""
    from importlib import metadata

    versions = {}
    for name in PACKAGES:
        try:
            versions[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            continue
    return versions


@lru_cache(maxsize=1)
def _provenance() -> tuple[tuple[str, Any], ...]:
    return tuple({"version": __version__, **_commit(), "packages": packages()}.items())


def provenance() -> Provenance:
    """The package version, the commit (and whether the package differs from it) and the packages
    of this process (computed once per process)."""
    return dict(_provenance())


def machine() -> dict[str, Any]:
    """The machine a session ran on."""
    return {
        "platform": platform.platform(),
        "processor": platform.machine(),
        "cpus": os.cpu_count(),
        "python": sys.version.split()[0],
    }


def changed(then: Mapping[str, str], now: Mapping[str, str]) -> list[str]:
    """The files added, removed or changed between two ``files`` records."""
    return sorted(path for path in then.keys() | now.keys() if then.get(path) != now.get(path))


def record_codes(folder: Path, codes: Mapping[str, Iterable[str]], keep: Iterable[str] | None = None) -> None:
    """Add each code of ``codes`` (code -> its roots) to ``folder/run.json``'s ``codes``, with its
    files; with ``keep`` (the codes the folder's results on disk record), drop every code that is
    neither in ``codes`` nor in ``keep``."""
    from ilc_steering.output import MAX_RESULT_BYTES, write_json
    from ilc_steering.readers import read_json

    path = folder / "run.json"
    stored = read_json(path, MAX_RESULT_BYTES)
    if not isinstance(stored, dict):
        return
    found = stored.get("codes")
    table: dict[str, Any] = found if isinstance(found, dict) else {}
    for digest, roots in codes.items():
        now, files = code(roots)
        if now == digest:
            table[digest] = {"roots": list(roots), "files": files}
    wanted = set(table) if keep is None else {*codes, *keep}
    write_json(path, {**stored, "codes": {k: v for k, v in sorted(table.items()) if k in wanted}})


def copy_codes(folder: Path, codes: Mapping[str, CodeRecord]) -> None:
    """Add ``codes`` (another run's table: the codes of the results copied from it) to
    ``folder/run.json``'s ``codes`` as they were recorded."""
    from dataclasses import asdict

    from ilc_steering.output import MAX_RESULT_BYTES, write_json
    from ilc_steering.readers import read_json

    path = folder / "run.json"
    stored = read_json(path, MAX_RESULT_BYTES)
    if isinstance(stored, dict) and codes:
        found = stored.get("codes")
        table: dict[str, Any] = found if isinstance(found, dict) else {}
        table.update({digest: {**asdict(made), "roots": list(made.roots)} for digest, made in codes.items()})
        write_json(path, {**stored, "codes": dict(sorted(table.items()))})


MADE = "made.json"
"""The record of what scripts made in a folder (a benchmark's artifacts): for each script (by its
path), its command and its code. Several scripts may write into one folder, each its own entry."""


@dataclass(frozen=True)
class MadeRecord:
    """One script's entry of a ``made.json``, as read back: its command, when, and its code."""

    command: str
    made: str
    code: str
    cpu_s: float
    """What making it cost: the CPU time of the script and of the processes it waited for [s]."""
    roots: tuple[str, ...]
    files: dict[str, str]
    provenance: ProvenanceRecord
    machine: Machine


def read_made(folder: Path) -> dict[str, MadeRecord]:
    """``folder/made.json`` (script -> its entry), each entry checked against :class:`MadeRecord`
    and against itself (its code the hash of its files): ``ValueError`` naming the file and the key."""
    from ilc_steering.errors import ConfigError
    from ilc_steering.readers import read_json
    from ilc_steering.schema import validate

    path = folder / MADE
    try:
        records: dict[str, MadeRecord] = validate(dict[str, MadeRecord], read_json(path, 1 << 24))
    except ConfigError as error:
        raise BadInput(f"{path}: {error}") from None
    for script, record in records.items():
        if code_of(record.files) != record.code:
            raise BadInput(f"{path}: {script}.code: not the hash of its files: the record contradicts itself")
    return records


def record_made(out: Path, script: str, argv: Iterable[str] = (), roots: Iterable[str] = ()) -> str:
    """Write ``out/made.json``: the command that made the folder (``script``, the script's path,
    ``__file__``, and its arguments ``argv``) and its code, the import closure of the script, of
    every module of the library this process imported (the learners and robots a registry named by
    string among them) and of ``roots``, and what it cost (CPU seconds, its workers' included);
    returns the code."""
    import resource
    from datetime import datetime, timezone

    from ilc_steering.engine.closure import checkout
    from ilc_steering.output import write_json

    path = Path(script).resolve()
    script = path.relative_to(checkout()).as_posix() if path.is_relative_to(checkout()) else str(path)
    imported = sorted(name for name, module in sys.modules.items() if _library(name, module))
    everything = (script, *imported, *roots)
    digest, files = code(everything)
    used = [resource.getrusage(who) for who in (resource.RUSAGE_SELF, resource.RUSAGE_CHILDREN)]
    record = {
        "command": " ".join(["python", script, *argv]),
        "made": datetime.now(timezone.utc).isoformat(timespec="seconds"),
        "cpu_s": round(sum(u.ru_utime + u.ru_stime for u in used), 1),
        "code": digest,
        "roots": list(everything),
        "files": files,
        "provenance": provenance(),
        "machine": machine(),
    }
    out.mkdir(parents=True, exist_ok=True)
    try:
        others = {name: asdict(made) for name, made in read_made(out).items()} if (out / MADE).is_file() else {}
    except ValueError:
        others = {}  # a broken record of this folder is replaced, not merged
    write_json(out / MADE, dict(sorted({**others, script: record}.items())))
    return digest


def _library(name: str, module: Any) -> bool:
    """A module of the library with a source file (not a namespace, not a built-in), not one that
    keeps the records (:data:`~ilc_steering.engine.closure.BOOKKEEPING`)."""
    from ilc_steering.engine.closure import BOOKKEEPING

    return (
        (name == "ilc_steering" or name.startswith("ilc_steering."))
        and name not in BOOKKEEPING
        and str(getattr(module, "__file__", "") or "").endswith(".py")
    )


def record_report(folder: Path, results: Iterable[dict[str, Any]]) -> None:
    """Record in ``folder/run.json`` which results its report was just made from (their content hash)."""
    from ilc_steering.output import MAX_RESULT_BYTES, write_json
    from ilc_steering.readers import read_json

    path = folder / "run.json"
    stored = read_json(path, MAX_RESULT_BYTES)
    if isinstance(stored, dict):
        write_json(path, {**stored, "report": results_hash(results)})


def results_hash(results: Iterable[dict[str, Any]]) -> str:
    """One hash of a set of results, whatever their order (the timings of the run included)."""
    from ilc_steering.output import content_hash

    return content_hash(sorted(content_hash(result) for result in results))
