"""What made a run's results, and whether the code in the tree would make them again.

Every run folder's ``run.json`` (``compare`` and ``sweep``, :class:`~ilc_steering.engine.runs.RunFolder`)
records under ``"provenance"``:

- ``code``: a content hash of the code that makes the results (:data:`CODE`: the simulator and
  the robots, the envs, the learners, the RL hyperparameter files, the trial loop and the cell
  and row makers), and ``files``, each of those files' own hash, so that a stale run names what
  changed;
- ``commit``: the git commit of the tree it ran from (None outside a git checkout) and whether
  those files differed from it (``dirty``);
- ``packages``: the versions of the numerical packages the results depend on.

Each session of work on the folder adds a line to ``"sessions"``: when, the wall time, the cells
computed and failed, the workers and the machine. A resume is refused when the code differs
(:func:`check_code`): a folder holds the results of one code. ``ilc-steering current DIR``
(:func:`freshness`) says whether a committed run is current for the code in the tree.

The code that only arranges results (the command line, the reports and figures, the engine, the
backends) is not hashed: changing how a table is drawn does not make a run stale.
"""

from __future__ import annotations

import hashlib
import os
import platform
import subprocess
import sys
from dataclasses import dataclass, field
from functools import lru_cache
from importlib import metadata, util
from pathlib import Path
from typing import Any

from ilc_steering import __version__

__all__ = [
    "CODE",
    "PACKAGES",
    "Machine",
    "Provenance",
    "ProvenanceRecord",
    "RunRecord",
    "Session",
    "check_code",
    "code_files",
    "freshness",
    "machine",
    "provenance",
    "read_run",
]


@dataclass(frozen=True)
class ProvenanceRecord:
    """A ``run.json``'s ``provenance``, as read back (the schema: :mod:`ilc_steering.schema`)."""

    version: str
    code: str
    commit: str | None
    dirty: bool | None
    packages: dict[str, str]
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


@dataclass(frozen=True)
class RunRecord:
    """What every ``run.json`` holds besides its command's settings, checked when read back: what
    made it, the packaged configs it used (name -> content hash) and its sessions."""

    provenance: ProvenanceRecord | None = None
    configs: dict[str, str] = field(default_factory=dict)
    sessions: tuple[Session, ...] = ()


def read_run(folder: Path) -> tuple[dict[str, Any], RunRecord]:
    """``folder/run.json`` as read (the command's settings with it) and its :class:`RunRecord`,
    checked: ``ValueError`` naming the file and the key if it is not a run record or a key is of
    the wrong type, or if its provenance contradicts itself (a code hash that is not the hash of
    its files). A record is a file on disk: hostile until checked."""
    from ilc_steering.errors import ConfigError
    from ilc_steering.readers import read_json
    from ilc_steering.schema import validate

    path = folder / "run.json"
    stored = read_json(path, 1 << 24)
    if not isinstance(stored, dict):
        raise ValueError(f"{path}: not a run record (a JSON object)")
    parts = {key: stored[key] for key in ("provenance", "configs", "sessions") if key in stored}
    try:
        record: RunRecord = validate(RunRecord, parts)
    except ConfigError as error:
        raise ValueError(f"{path}: {error}") from None
    made = record.provenance
    if made is not None and made.files and code_hash(made.files) != made.code:
        raise ValueError(
            f"{path}: provenance.code: {made.code} is not the hash of its provenance.files ({code_hash(made.files)}): "
            "the record contradicts itself"
        )
    return stored, record


CODE: dict[str, tuple[str, ...]] = {
    "ilc_steering.core": ("**/*.py",),
    "ilc_steering.agents": ("**/*.py",),
    "ilc_steering.envs": ("**/*.py",),
    "ilc_steering.configs": ("rl/*.yaml",),
    "ilc_steering": (
        *("errors.py", "entries.py", "boxes.py", "schema.py", "yaml_reader.py", "config/*.py"),
        *("loop.py", "runner.py", "preflight.py", "oracle.py"),
        *("compare/cells.py", "sweep/rows.py"),  # files, not imports: the engine names no command
    ),
}
"""The code that makes a run's results: package -> glob patterns of its files. The scenario
configs are not here: each run records the content hash of every config it used."""
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
)
"""The distributions whose versions a run records (those installed)."""

Provenance = dict[str, Any]


def _folder(package: str) -> Path:
    spec = util.find_spec(package)
    if spec is None or not spec.submodule_search_locations:
        raise RuntimeError(f"{package}: not an installed package")
    return Path(next(iter(spec.submodule_search_locations)))


def _label(package: str) -> str:
    return package.removeprefix("ilc_steering").lstrip(".") or "ilc_steering"


def code_files(roots: dict[str, Path] | None = None) -> dict[str, str]:
    """Each file of :data:`CODE` -> the first 16 hex digits of its SHA-256, keyed by a path that
    is the same in a checkout and an installed wheel (``agents/ilc.py``, ``ilc_steering/loop.py``).
    ``roots``: a folder per package of :data:`CODE` instead of the installed one (a test's copy)."""
    found: dict[str, str] = {}
    for package, patterns in CODE.items():
        root = (roots or {}).get(package) or _folder(package)
        for pattern in patterns:
            for path in sorted(root.glob(pattern)):
                if path.is_file() and "__pycache__" not in path.parts:
                    key = f"{_label(package)}/{path.relative_to(root).as_posix()}"
                    found[key] = hashlib.sha256(path.read_bytes()).hexdigest()[:16]
    return dict(sorted(found.items()))


def code_hash(files: dict[str, str]) -> str:
    """One hash of every file's path and hash."""
    text = "\n".join(f"{path} {digest}" for path, digest in sorted(files.items()))
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def _git(*args: str) -> str | None:
    root = _folder("ilc_steering").parent
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
    paths = ["ilc_steering/core", "agents", "envs", "configs/rl", *(f"ilc_steering/{f}" for f in CODE["ilc_steering"])]
    status = _git("status", "--porcelain", "--", *paths)
    return {"commit": commit, "dirty": bool(status)}


def packages() -> dict[str, str]:
    """The installed versions of :data:`PACKAGES`."""
    versions = {}
    for name in PACKAGES:
        try:
            versions[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            continue
    return versions


@lru_cache(maxsize=1)
def _provenance() -> tuple[tuple[str, Any], ...]:
    files = code_files()
    record = {"version": __version__, "code": code_hash(files), **_commit(), "packages": packages(), "files": files}
    return tuple(record.items())


def provenance() -> Provenance:
    """What :mod:`this module <ilc_steering.engine.provenance>` records of the code in this process
    (computed once per process)."""
    return dict(_provenance())


def machine() -> dict[str, Any]:
    """The machine a session ran on."""
    return {
        "platform": platform.platform(),
        "processor": platform.machine(),
        "cpus": os.cpu_count(),
        "python": sys.version.split()[0],
    }


def changed(then: dict[str, str], now: dict[str, str]) -> list[str]:
    """The files of :data:`CODE` added, removed or changed between two ``files`` records."""
    return sorted(path for path in then.keys() | now.keys() if then.get(path) != now.get(path))


def check_code(stored: Provenance | None, where: Path) -> None:
    """``ValueError`` unless ``stored`` (a ``run.json``'s provenance) is of the code in this
    process: a resume never mixes the results of two codes."""
    now = provenance()
    if not isinstance(stored, dict) or "code" not in stored:
        raise ValueError(
            f"{where}: records no hash of the code that made its results, so a resume cannot prove it is the same "
            "computation; use another --out folder"
        )
    if stored["code"] != now["code"]:
        files = changed(stored.get("files") or {}, now["files"])
        shown = ", ".join(files[:5]) + (f" and {len(files) - 5} more" if len(files) > 5 else "")
        raise ValueError(
            f"{where}: its results were made by other code (code {stored['code']}, now {now['code']}; changed: "
            f"{shown or 'unknown files'}); use another --out folder"
        )


def freshness(folder: Path) -> tuple[bool, list[str]]:
    """Whether the run in ``folder`` is current for the code in this process (and every packaged
    config it used), and the lines that say why."""
    from dataclasses import asdict

    from ilc_steering.config import load_config, packaged_configs
    from ilc_steering.output import content_hash

    _, run = read_run(folder)
    record = run.provenance
    now = provenance()
    lines: list[str] = []
    current = True
    if record is None:
        return False, [f"{folder}: STALE: its run.json records no hash of the code that made it (an older run)"]
    if record.code != now["code"]:
        current = False
        files = changed(record.files, now["files"])
        differ = ", ".join(files)
        lines.append(f"code: made by {record.code}, the tree's is {now['code']}; {len(files)} files differ: {differ}")
    if record.version != now["version"]:
        current = False
        lines.append(f"version: made by ilc-steering {record.version}, the tree is {now['version']}")
    packaged = packaged_configs()
    for name, digest in sorted(run.configs.items()):
        if name not in packaged:
            lines.append(f"config {name}: not a packaged config, not checked")
            continue
        today = content_hash(asdict(load_config(name)))
        if today != digest:
            current = False
            lines.append(f"config {name}: made with content {digest}, the packaged one is {today}")
    before, after = record.packages, now["packages"]
    moved = [
        f"{p} {before.get(p)} -> {after.get(p)}"
        for p in sorted(before.keys() | after.keys())
        if before.get(p) != after.get(p)
    ]
    if moved:
        lines.append("packages (results may differ, the code is not stale for them): " + ", ".join(moved))
    commit = record.commit
    made = f"commit {commit[:12]}{' with local changes' if record.dirty else ''}" if commit else "no commit"
    head = "current" if current else "STALE"
    lines.insert(0, f"{folder}: {head}: made by code {record.code} ({made}); the code in this tree is {now['code']}")
    return current, lines
