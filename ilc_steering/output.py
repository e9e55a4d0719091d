"""Output paths: checked before a run starts, written inside the folder the user named, atomically.

A run whose results cannot be written must fail before its first trial, not after its last, so
the CLI checks every output path first (exit 2, naming the option). Files are written to a
unique temporary name in the same folder, flushed to disk, then renamed: a reader sees the whole
file or none of it, and two writers never share a temporary file.
"""

from __future__ import annotations

import json
import os
import re
import tempfile
from pathlib import Path
from typing import Any

__all__ = ["check_output_dir", "check_output_file", "check_run_settings", "safe_name", "write_atomic", "write_json"]


def _problem(error: OSError) -> str:
    return error.strerror or str(error)


def check_output_dir(path: Path, option: str) -> Path:
    """Create the folder ``path`` if needed and check that files can be written in it; ``ValueError``
    naming ``option`` otherwise."""
    if path.exists() and not path.is_dir():
        raise ValueError(f"{option} {path}: exists and is not a folder")
    try:
        path.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=path, prefix=".write-check-"):
            pass
    except OSError as error:
        raise ValueError(f"{option} {path}: cannot write there ({_problem(error)})") from None
    return path


def check_output_file(path: Path, option: str) -> Path:
    """Check that the file ``path`` can be written (its folder is created if needed)."""
    if "\x00" in str(path):
        raise ValueError(f"{option}: a path cannot hold a NUL character")
    if path.is_dir():
        raise ValueError(f"{option} {path}: is a folder, not a file")
    folder = path.parent
    if folder.exists() and not folder.is_dir():
        raise ValueError(f"{option} {path}: {folder} is not a folder")
    try:
        folder.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=folder, prefix=".write-check-"):
            pass
    except OSError as error:
        raise ValueError(f"{option} {path}: cannot be written ({_problem(error)})") from None
    if path.exists() and not os.access(path, os.W_OK):
        raise ValueError(f"{option} {path}: exists and cannot be written")
    return path


def safe_name(name: str) -> str:
    """``name`` as a file name: letters, digits, ``_``, ``-`` and ``.`` only, not starting with a dot."""
    cleaned = re.sub(r"[^A-Za-z0-9_.\-]", "_", name).lstrip(".")
    return cleaned[:100] or "run"


def write_atomic(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` through a unique temporary file, flushed to disk before the rename."""
    handle, temporary = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(handle, "w") as file:
            file.write(text)
            file.flush()
            os.fsync(file.fileno())
        os.replace(temporary, path)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise


def write_json(path: Path, data: Any) -> None:
    """:func:`write_atomic` of ``data`` as JSON."""
    write_atomic(path, json.dumps(data))


def check_run_settings(folder: Path, settings: dict[str, Any], results: Path) -> bool:
    """Record ``settings`` in ``folder/run.json``; ``ValueError`` if the folder was written with
    others, or holds results (``results/*.json``) but no record of their settings. Returns whether
    the folder was a run already (a resume)."""
    stored_path = folder / "run.json"
    resumed = stored_path.exists()
    if resumed:
        try:
            stored = json.loads(stored_path.read_bytes().decode("utf-8"))
        except (OSError, UnicodeDecodeError, json.JSONDecodeError) as error:
            raise ValueError(f"{stored_path}: not readable ({error}); use another --out folder") from None
        if stored != settings:
            raise ValueError(f"{stored_path} was written with {stored}, not {settings}: use another --out folder")
    elif results.is_dir() and any(results.glob("*.json")):
        raise ValueError(
            f"{folder}: has results in {results.name}/ but no run.json, so their settings cannot be checked: "
            "use another --out folder"
        )
    write_json(stored_path, settings)
    return resumed
