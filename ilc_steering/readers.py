"""One way in for every file the library reads: its size checked before it is read, its depth after.

Configs (YAML), run files (``plot``), the rows and cells of a resumed run, committed runs
(``--against``), a session's files and the oracle all come through :func:`read_text`. What is
looked at without being read is here too: whether an output names one of a command's inputs
(:func:`check_apart`), whether a folder is new or empty (:func:`check_new_folder`). It opens only regular files,
with ``O_NONBLOCK`` so that a FIFO cannot block it (:func:`open_regular`), and turns every
``OSError`` into a one-line ``ValueError`` naming the path. A file larger than its limit is
refused from its size, before a byte is read (and read at most ``limit + 1`` bytes, should it
grow meanwhile), so a 3 GB file costs nothing.
:func:`read_json` then parses it and bounds its nesting (:data:`MAX_DEPTH`), which the parsers
would otherwise meet as a ``RecursionError``. Each error is a ``ValueError`` naming the file.
"""

from __future__ import annotations

import json
import os
import stat
from collections.abc import Collection
from pathlib import Path
from typing import Any

from ilc_steering.errors import BadInput

__all__ = [
    "MAX_DEPTH",
    "check_apart",
    "check_depth",
    "check_new_folder",
    "describe",
    "holds",
    "is_file",
    "kind_of",
    "open_regular",
    "read_bytes",
    "read_json",
    "read_text",
]

MAX_DEPTH = 64
"""The deepest nesting (mappings and lists within one another) of a file the library reads."""


def describe(error: OSError) -> str:
    """An ``OSError`` as a few words (``"Too many levels of symbolic links"``), for a one-line refusal."""
    return error.strerror or type(error).__name__


def kind_of(mode: int) -> str:
    """What a file of mode ``mode`` is, in words."""
    kinds = [(stat.S_ISDIR, "a folder"), (stat.S_ISFIFO, "a FIFO"), (stat.S_ISCHR, "a character device")]
    kinds += [(stat.S_ISBLK, "a block device"), (stat.S_ISSOCK, "a socket")]
    return next((name for test, name in kinds if test(mode)), "not a regular file")


def open_regular(path: Path, origin: str | None = None) -> int:
    """A file descriptor of the regular file ``path``, opened for reading.

    Opened with ``O_NONBLOCK`` so that a FIFO (or a device) cannot block, then checked with
    ``fstat``: anything but a regular file is refused. Every ``OSError`` (a missing file, a
    dangling link, a symbolic-link loop, a path under a regular file, a name too long, no
    permission) is a ``ValueError`` naming ``origin`` (default: the path)."""
    where = origin or str(path)
    flags = os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_NOCTTY", 0) | getattr(os, "O_CLOEXEC", 0)
    try:
        descriptor = os.open(os.fspath(path), flags)
    except (OSError, ValueError) as error:  # ValueError: a NUL in the path
        problem = describe(error) if isinstance(error, OSError) else "a path cannot hold a NUL character"
        raise BadInput(f"{where}: cannot read it: {problem}") from None
    try:
        mode = os.fstat(descriptor).st_mode
        if not stat.S_ISREG(mode):
            raise BadInput(f"{where}: is {kind_of(mode)}, not a regular file")
        os.set_blocking(descriptor, True)
    except BaseException:
        os.close(descriptor)
        raise
    return descriptor


def read_bytes(path: Path, limit: int, origin: str | None = None) -> bytes:
    """The bytes of the regular file ``path`` (:func:`open_regular`), at most ``limit``."""
    where = origin or str(path)
    descriptor = open_regular(path, where)
    try:
        with os.fdopen(descriptor, "rb") as file:
            size = os.fstat(file.fileno()).st_size
            if size > limit:
                raise BadInput(f"{where}: {size} bytes; at most {limit} bytes are read")
            raw = file.read(limit + 1)
    except OSError as error:  # EIO, EISDIR on odd file systems
        raise BadInput(f"{where}: cannot read it: {describe(error)}") from None
    if len(raw) > limit:
        raise BadInput(f"{where}: more than {limit} bytes; at most {limit} bytes are read")
    return raw


def read_text(path: Path, limit: int, origin: str | None = None) -> str:
    """The UTF-8 text of the regular file ``path``, at most ``limit`` bytes; ``ValueError`` naming
    ``origin`` (default: the path) otherwise."""
    where = origin or str(path)
    raw = read_bytes(path, limit, where)
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError as error:
        raise BadInput(f"{where}: not UTF-8 text (byte {error.start})") from None


def check_apart(outputs: Collection[tuple[str, Path]], inputs: Collection[Path]) -> None:
    """Refuse, before anything is written, an output (``(option, path)``) that names one of the
    command's ``inputs``, whatever the way: the same path, a link to it, another name of the file."""

    def identity(path: Path) -> tuple[Any, ...]:
        try:
            found = os.stat(path)
        except (OSError, ValueError):
            return ("path", os.path.realpath(path))
        return ("file", found.st_dev, found.st_ino)

    taken = {identity(path): path for path in inputs}
    taken.update({("path", os.path.realpath(path)): path for path in inputs})
    for option, path in outputs:
        source = taken.get(identity(path), taken.get(("path", os.path.realpath(path))))
        if source is not None:
            raise BadInput(f"{option} {path}: is {source}, which this command reads; write somewhere else")


def check_new_folder(folder: Path, what: str) -> Path:
    """``folder`` if ``what`` (a session) can start there: absent, or an empty folder (the one a link
    names); ``ValueError`` saying why not (a file, not empty, a loop of links, ...)."""
    try:
        mode = os.stat(folder).st_mode
        empty = not stat.S_ISDIR(mode) or not any(os.scandir(folder))
    except FileNotFoundError:
        return folder
    except OSError as error:
        raise BadInput(f"{folder}: cannot start {what} there ({describe(error)})") from None
    if not stat.S_ISDIR(mode) or not empty:
        problem = "exists and is not empty" if stat.S_ISDIR(mode) else f"is {kind_of(mode)}, not a folder"
        raise BadInput(f"{folder}: {problem}; {what} starts in a new or empty folder")
    return Path(os.path.realpath(folder))


def holds(path: Path, text: str, limit: int) -> bool:
    """Whether the regular file ``path`` holds ``text`` (UTF-8, at most ``limit`` bytes); a file that
    cannot be read does not."""
    try:
        return read_text(path, limit) == text
    except ValueError:
        return False


def is_file(path: Path) -> bool:
    """Whether ``path`` names something (a regular file or not: reading it says which); never raises.

    ``Path.exists`` raises on a name too long or a folder without permission; a run's reader asks
    this instead and leaves the refusal, with its reason, to :func:`read_text`."""
    try:
        os.stat(path)
    except FileNotFoundError:
        return os.path.islink(path)  # a dangling link is there, and refused when read
    except (OSError, ValueError):
        return True  # there is a problem: reading it names it
    return True


def check_depth(data: Any, origin: str, max_depth: int = MAX_DEPTH) -> None:
    """``ValueError`` if ``data`` nests mappings and lists deeper than ``max_depth`` (walked without recursion)."""
    todo = [(data, 1)]
    while todo:
        item, depth = todo.pop()
        if isinstance(item, (dict, list)):
            if depth > max_depth:
                raise BadInput(f"{origin}: nested deeper than {max_depth} levels")
            todo.extend((value, depth + 1) for value in (item.values() if isinstance(item, dict) else item))


def read_json(path: Path, limit: int, origin: str | None = None) -> Any:
    """The JSON of ``path`` (:func:`read_text`), at most :data:`MAX_DEPTH` deep; ``ValueError`` naming it."""
    where = origin or str(path)
    text = read_text(path, limit, where)
    try:
        data = json.loads(text)
    except json.JSONDecodeError as error:
        raise BadInput(f"{where}: not valid JSON at line {error.lineno}, column {error.colno}: {error.msg}") from None
    except RecursionError:
        raise BadInput(f"{where}: nested deeper than {MAX_DEPTH} levels") from None
    check_depth(data, where)
    return data
