"""One way in for every file the library reads: its size checked before it is read, its depth after.

Configs (YAML), run files (``plot``) and the rows and cells of a resumed run all come through
:func:`read_text`: a file larger than its limit is refused from its size, before a byte is read
(and read at most ``limit + 1`` bytes, should it grow meanwhile), so a 3 GB file costs nothing.
:func:`read_json` then parses it and bounds its nesting (:data:`MAX_DEPTH`), which the parsers
would otherwise meet as a ``RecursionError``. Each error is a ``ValueError`` naming the file.
"""

from __future__ import annotations

import json
import os
import stat
from pathlib import Path
from typing import Any

__all__ = ["MAX_DEPTH", "check_depth", "read_json", "read_text"]

MAX_DEPTH = 64
"""The deepest nesting (mappings and lists within one another) of a file the library reads."""


def read_text(path: Path, limit: int, origin: str | None = None) -> str:
    """The UTF-8 text of the regular file ``path``, at most ``limit`` bytes; ``ValueError`` naming
    ``origin`` (default: the path) otherwise."""
    where = origin or str(path)
    try:
        with open(path, "rb") as file:
            info = os.fstat(file.fileno())
            if not stat.S_ISREG(info.st_mode):
                raise ValueError(f"{where}: not a regular file")
            if info.st_size > limit:
                raise ValueError(f"{where}: {info.st_size} bytes; at most {limit} bytes are read")
            raw = file.read(limit + 1)
    except OSError as error:
        raise ValueError(f"{where}: cannot read it: {error.strerror or error}") from None
    if len(raw) > limit:
        raise ValueError(f"{where}: more than {limit} bytes; at most {limit} bytes are read")
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError as error:
        raise ValueError(f"{where}: not UTF-8 text (byte {error.start})") from None


def check_depth(data: Any, origin: str, max_depth: int = MAX_DEPTH) -> None:
    """``ValueError`` if ``data`` nests mappings and lists deeper than ``max_depth`` (walked without recursion)."""
    todo = [(data, 1)]
    while todo:
        item, depth = todo.pop()
        if isinstance(item, (dict, list)):
            if depth > max_depth:
                raise ValueError(f"{origin}: nested deeper than {max_depth} levels")
            todo.extend((value, depth + 1) for value in (item.values() if isinstance(item, dict) else item))


def read_json(path: Path, limit: int, origin: str | None = None) -> Any:
    """The JSON of ``path`` (:func:`read_text`), at most :data:`MAX_DEPTH` deep; ``ValueError`` naming it."""
    where = origin or str(path)
    text = read_text(path, limit, where)
    try:
        data = json.loads(text)
    except json.JSONDecodeError as error:
        raise ValueError(f"{where}: not valid JSON at line {error.lineno}, column {error.colno}: {error.msg}") from None
    except RecursionError:
        raise ValueError(f"{where}: nested deeper than {MAX_DEPTH} levels") from None
    check_depth(data, where)
    return data
