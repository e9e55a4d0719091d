"""Output paths: checked before a run starts, written inside the folder the user named, atomically.

A run whose results cannot be written must fail before its first trial, not after its last, so
the CLI checks every output path first (exit 2, naming the option). :func:`write_atomic` is the
one writer of every output file (JSON, CSV, Markdown, PNG): it refuses a target that exists and
is not a regular file (a device node, a FIFO, a folder), writes to a unique temporary name in the
same folder, flushes it to disk, then renames it: a reader sees the whole file or none of it, and
two writers never share a temporary file. A new file gets the mode the umask gives (0644 under
umask 022), a replaced one keeps its mode; a symbolic link to a regular file is written through.
"""

from __future__ import annotations

import argparse
import errno
import hashlib
import io
import json
import os
import re
import shutil
import stat
import tempfile
from collections.abc import Collection, Sequence
from pathlib import Path
from typing import Any

from ilc_steering.errors import BadInput
from ilc_steering.readers import describe, is_file, kind_of, read_json

__all__ = [
    "RECORD_KEYS",
    "check_output_dir",
    "check_output_file",
    "check_reports",
    "check_run_settings",
    "check_writable",
    "content_hash",
    "differences",
    "injective_name",
    "json_text",
    "make_folder",
    "move_all",
    "open_lock",
    "output_file",
    "output_folder",
    "safe_name",
    "write_atomic",
    "write_figure",
    "write_json",
]


def output_file(text: str) -> Path:
    """An option's file path as typed (an ``argparse`` type): refused, in one line, when empty or
    ending in a separator, a folder's name that ``Path`` would strip to a file's (``new.json/``)."""
    if not text:
        raise argparse.ArgumentTypeError("an empty path; give a file's path")
    if text.endswith((os.sep, os.altsep or os.sep)):
        raise argparse.ArgumentTypeError(f"{text}: ends in {text[-1]!r}, a folder's name; give a file's path")
    return Path(text)


def output_folder(text: str) -> Path:
    """An option's folder path as typed (an ``argparse`` type): refused, in one line, when empty
    (``Path("")`` is the working directory, which nobody typed); ``.`` names it."""
    if not text:
        raise argparse.ArgumentTypeError("an empty path; give a folder's path (. for the working directory)")
    return Path(text)


def check_output_dir(path: Path, option: str) -> Path:
    """Create the folder ``path`` if needed and check that files can be written in it; ``ValueError``
    naming ``option`` otherwise (every ``OSError``: a loop of links, a path under a file, a name too long)."""
    if "\x00" in str(path):
        raise BadInput(f"{option}: a path cannot hold a NUL character")
    kind = _not_regular(path, option)
    if kind is not None and kind != "a folder":
        raise BadInput(f"{option} {path}: is {kind}, not a folder")
    try:
        path.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=path, prefix=".write-check-"):
            pass
    except OSError as error:
        raise BadInput(f"{option} {path}: cannot write there ({describe(error)})") from None
    return path


def _not_regular(path: Path, option: str = "") -> str | None:
    """What ``path`` is, when it exists and is not a regular file (symbolic links followed);
    ``ValueError`` naming ``option`` when it cannot be looked at (a loop of links, a name too long)."""
    try:
        mode = os.stat(path).st_mode
    except FileNotFoundError:
        return None  # absent, or a dangling link: written anew (the link's target, see _target)
    except NotADirectoryError:
        raise BadInput(f"{option} {path}: a part of the path is a file, not a folder".lstrip()) from None
    except OSError as error:
        raise BadInput(f"{option} {path}: cannot use it ({describe(error)})".lstrip()) from None
    return None if stat.S_ISREG(mode) else kind_of(mode)


def _target(path: Path) -> Path:
    """The file a write to ``path`` replaces: ``path``, or the file its symbolic links name."""
    return Path(os.path.realpath(path)) if os.path.islink(path) else path


def check_output_file(path: Path, option: str) -> Path:
    """Check that the file ``path`` can be written (its folder is created if needed): it must be
    absent or a regular file, its folder writable, its name one the file system takes. Every
    problem is a ``ValueError`` naming ``option``, before any work is done."""
    if "\x00" in str(path):
        raise BadInput(f"{option}: a path cannot hold a NUL character")
    kind = _not_regular(path, option)
    if kind == "a folder":
        raise BadInput(f"{option} {path}: is a folder, not a file")
    if kind is not None:
        raise BadInput(f"{option} {path}: is {kind}, not a regular file; give a file path")
    target = _target(path)
    folder = target.parent
    try:
        if folder.exists() and not folder.is_dir():
            raise BadInput(f"{option} {path}: {folder} is not a folder")
        folder.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=folder, prefix=".write-check-"):
            pass
        if target.exists():
            if not os.access(target, os.W_OK):
                raise BadInput(f"{option} {path}: exists and cannot be written")
        else:  # the name itself (its length, its characters) is the file system's to accept
            os.close(os.open(target, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600))
            os.unlink(target)
    except OSError as error:
        raise BadInput(f"{option} {path}: cannot be written ({describe(error)})") from None
    return path


def check_writable(path: Path, option: str = "output") -> Path:
    """:func:`check_output_file`: call it on every output path before the first trial runs."""
    return check_output_file(Path(path), option)


def open_lock(path: Path, shared: bool = False) -> int:
    """A descriptor of the lock file ``path`` (created if absent, mode 0644 under umask 022), opened so
    that a FIFO cannot block it and checked to be a regular file; ``ValueError`` naming it otherwise.
    Hold ``fcntl.flock`` on it, and ``os.close`` it when the run ends. A ``shared`` lock (a reader's)
    in a folder that cannot be written (read-only, archived) is opened for reading; ``-1`` when it
    cannot be made there: nobody can be writing in that folder."""
    flags = os.O_WRONLY | os.O_CREAT | os.O_APPEND | os.O_NONBLOCK | getattr(os, "O_NOCTTY", 0)
    try:
        descriptor = os.open(path, flags | getattr(os, "O_CLOEXEC", 0), 0o666)
    except OSError as error:  # ENXIO: a FIFO with no reader; ELOOP, EACCES, ...
        if not (shared and error.errno in (errno.EROFS, errno.EACCES, errno.EPERM)):
            raise BadInput(f"{path}: cannot open the run folder's lock ({describe(error)})") from None
        try:
            descriptor = os.open(path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
        except FileNotFoundError:
            return -1
        except OSError as again:
            raise BadInput(f"{path}: cannot open the run folder's lock ({describe(again)})") from None
    mode = os.fstat(descriptor).st_mode
    if not stat.S_ISREG(mode):
        os.close(descriptor)
        raise BadInput(f"{path}: the run folder's lock is {kind_of(mode)}, not a regular file; remove it")
    return descriptor


def move_all(moves: Sequence[tuple[Path, Path]], into: Path, what: str) -> None:
    """Rename each ``(source, target)`` in order into the folder ``into`` (made if absent), all or
    none: after a failure (a target taken, ``into`` a file, a folder that cannot be written, another
    file system) those done are renamed back, ``into`` removed if made for them, and ``ValueError``
    says so, naming ``what`` was being done."""
    done: list[tuple[Path, Path]] = []
    made = not os.path.lexists(into)
    try:
        into.mkdir(exist_ok=True)  # a file there: FileExistsError; a link to a folder: taken
        for source, target in moves:
            if os.path.lexists(target):
                raise FileExistsError(errno.EEXIST, "exists", str(target))
            os.rename(source, target)
            done.append((source, target))
    except BaseException as error:
        for source, target in reversed(done):
            os.rename(target, source)
        if made:
            shutil.rmtree(into, ignore_errors=True)
        if not isinstance(error, OSError):
            raise
        name = error.filename or into
        raise BadInput(f"{what}: cannot move into {name} ({describe(error)}); nothing was changed") from None


def make_folder(folder: Path, files: dict[str, str], what: str) -> None:
    """Make ``folder`` holding ``files`` (name -> text), all or none: built aside in its parent and
    renamed into place (over an empty folder), so a failure leaves no trace of it, nor of the
    folders made for it."""
    missing = [path for path in (folder.parent, *folder.parent.parents) if not os.path.lexists(path)]
    aside: list[Path] = missing[-1:]
    try:
        folder.parent.mkdir(parents=True, exist_ok=True)
        aside.append(Path(tempfile.mkdtemp(dir=folder.parent, prefix=f".{folder.name[:24]}.")))
        for name, text in files.items():
            write_atomic(aside[-1] / name, text)
        os.rename(aside[-1], folder)
    except BaseException as error:
        for path in aside[::-1]:
            shutil.rmtree(path, ignore_errors=True)
        if isinstance(error, OSError):
            raise BadInput(f"{folder}: cannot make {what} there ({describe(error)})") from None
        raise


def check_reports(folder: Path, names: Collection[str], option: str = "--out") -> None:
    """Check, before any work, that each report ``folder/name`` a run writes at its end (``compare.json``,
    ``sweep.md``, a figure) can be written: a FIFO or a folder in its place is refused now, naming it."""
    for name in names:
        check_output_file(Path(folder) / name, f"{option} ({name})")


def safe_name(name: str) -> str:
    """``name`` as a file name: letters, digits, ``_``, ``-`` and ``.`` only, not starting with a dot."""
    cleaned = re.sub(r"[^A-Za-z0-9_.\-]", "_", name).lstrip(".")
    return cleaned[:100] or "run"


def _umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def write_atomic(path: Path, content: str | bytes) -> None:
    """Write ``content`` to ``path`` through a unique temporary file, flushed to disk before the
    rename; ``ValueError`` naming the path if ``path`` exists and is not a regular file, or on any
    ``OSError`` (the temporary file is removed)."""
    path = Path(path)
    kind = _not_regular(path)
    if kind is not None:
        raise BadInput(f"{path}: is {kind}, not a regular file; it is not replaced")
    path = _target(path)  # write the file a link names, keep the link
    try:
        try:
            mode = stat.S_IMODE(os.stat(path).st_mode)
        except FileNotFoundError:
            mode = 0o666 & ~_umask()
        # a short prefix: the temporary name must fit wherever the name itself fits
        handle, temporary = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name[:24]}.", suffix=".tmp")
    except OSError as error:
        raise BadInput(f"{path}: cannot be written ({describe(error)})") from None
    try:
        with os.fdopen(handle, "wb") as file:
            file.write(content.encode("utf-8") if isinstance(content, str) else content)
            file.flush()
            os.fchmod(file.fileno(), mode)
            os.fsync(file.fileno())
        os.replace(temporary, path)
    except OSError as error:
        Path(temporary).unlink(missing_ok=True)
        raise BadInput(f"{path}: cannot be written ({describe(error)})") from None
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise


def json_text(data: Any) -> str:
    """``data`` as the library writes a JSON file: one line, and the newline that ends it."""
    return json.dumps(data) + "\n"


def write_json(path: Path, data: Any) -> None:
    """:func:`write_atomic` of ``data`` as JSON (:func:`json_text`)."""
    write_atomic(path, json_text(data))


def write_figure(path: Path, figure: Any, dpi: float | str = "figure") -> None:
    """:func:`write_atomic` of a Matplotlib ``figure`` as PNG."""
    buffer = io.BytesIO()
    figure.savefig(buffer, format="png", dpi=dpi)
    write_atomic(path, buffer.getvalue())


MAX_RESULT_BYTES = 16 << 20
"""The largest run record, cell or row read back from a run folder [bytes]."""


def content_hash(data: Any) -> str:
    """16 hex digits of the SHA-256 of ``data`` as canonical JSON (sorted keys): equal content, equal hash."""
    text = json.dumps(data, sort_keys=True, default=str, separators=(",", ":"))
    return hashlib.sha256(text.encode("utf-8")).hexdigest()[:16]


def injective_name(name: str, taken: Collection[str] = ()) -> str:
    """A file-name part for ``name`` that no other name maps to.

    ``safe_name(name)`` when it is ``name`` itself; a user's ``module:attr`` whose ``attr`` has no
    ``_`` becomes ``module_attr`` (its last ``_`` marks the colon, so it decodes; ``taken``, the
    library's ids, is avoided); any other name gets ``-`` and a hash of ``name`` appended, so
    ``x_y:z`` (``x_y_z``) and ``x:y_z`` (``x_y_z-<hash>``) never share a file."""
    cleaned = safe_name(name)
    if cleaned == name and "__" not in name:
        return name
    module, colon, attr = name.partition(":")
    plain = f"{module}_{attr}"
    if colon and attr.isidentifier() and "_" not in attr and safe_name(plain) == plain and "__" not in plain:
        if plain not in taken:
            return plain
    return f"{re.sub('_+', '_', cleaned)[:80]}-{content_hash(name)[:8]}"


def differences(stored: dict[str, Any], settings: dict[str, Any]) -> str:
    """Each key whose value differs, as ``key <stored>, not <settings>``, joined by ``; ``."""
    keys = sorted(set(stored) | set(settings))
    return "; ".join(
        f"{k} {stored.get(k, 'unset')!r}, not {settings.get(k, 'unset')!r}"
        for k in keys
        if stored.get(k) != settings.get(k)
    )


RECORD_KEYS = ("provenance", "configs", "sessions", "codes", "report", "command")
"""The keys of a ``run.json`` that are not its command's settings (the engine's run record)."""


def check_run_settings(
    folder: Path,
    settings: dict[str, Any],
    results: Path,
    configs: dict[str, str] | None = None,
    made_now: dict[str, Any] | None = None,
    reports: Collection[Path] = (),
    command: str | None = None,
) -> bool:
    """Record ``settings``, the content hash of each config (``configs``: name -> hash) and the
    ``command`` in ``folder/run.json``; ``ValueError``, saying which setting differs, if the folder
    was written with other settings, or holds results (``results/*.json``) but no record of their
    settings. Returns whether the folder was a run already (a resume). A config's hash is the one
    of this run: a result of another content is stale, and the engine computes it again
    (:mod:`~ilc_steering.engine.runs`). ``made_now``: what makes the results
    (:func:`~ilc_steering.engine.provenance.provenance`), recorded; a resume of a folder that holds
    results (``results/*.json`` or any of ``reports``) keeps the recorded one (the commit of the
    first results; each session records its own)."""
    stored_path = folder / "run.json"
    resumed = is_file(stored_path)
    kept: dict[str, Any] = {}
    made = made_now
    if resumed:
        stored = read_json(stored_path, MAX_RESULT_BYTES)
        if not isinstance(stored, dict):
            raise BadInput(f"{stored_path}: not a run record (a JSON object); use another --out folder")
        kept = {key: stored.pop(key) for key in RECORD_KEYS if key in stored}
        if stored != settings:
            raise BadInput(
                f"{stored_path} was written with other settings: {differences(stored, settings)}; "
                "use another --out folder"
            )
        held = (results.is_dir() and any(results.glob("*.json"))) or any(is_file(path) for path in reports)
        if held and isinstance(kept.get("provenance"), dict):
            made = kept["provenance"]  # the provenance of the first results, as first recorded
    elif results.is_dir() and any(results.glob("*.json")):
        raise BadInput(
            f"{folder}: has results in {results.name}/ but no run.json, so their settings cannot be checked: "
            "use another --out folder"
        )
    found = kept.get("configs")
    known: dict[str, Any] = found if isinstance(found, dict) else {}
    record = {**settings, **({"configs": {**known, **configs}} if configs is not None else {})}
    for key in ("codes", "report"):
        if key in kept:
            record[key] = kept[key]
    if made is not None:
        record["provenance"] = made
    if command is not None:
        record["command"] = command
    sessions = kept.get("sessions")
    write_json(stored_path, {**record, "sessions": sessions if isinstance(sessions, list) else []})
    return resumed


def record_session(folder: Path, session: dict[str, Any]) -> None:
    """Add ``session`` (when, wall time, cells, machine) to ``folder/run.json``'s ``sessions``."""
    path = folder / "run.json"
    stored = read_json(path, MAX_RESULT_BYTES)
    if isinstance(stored, dict):
        found = stored.get("sessions")
        sessions: list[Any] = found if isinstance(found, list) else []
        write_json(path, {**stored, "sessions": [*sessions, session]})
