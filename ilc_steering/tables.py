"""Results of benchmarks and comparisons as JSON, CSV and Markdown, and the timing they share."""

from __future__ import annotations

import csv
import io
import json
import re
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from statistics import median
from typing import Any

from ilc_steering.errors import BadInput
from ilc_steering.output import write_atomic

__all__ = ["markdown_table", "median_seconds", "render_blocks", "rewrite_blocks", "update_pages", "write_results"]


def median_seconds(fn: Callable[[], Any], repeats: int) -> float:
    """The median wall time [s] of ``repeats`` calls of ``fn``."""
    samples = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        samples.append(time.perf_counter() - start)
    return median(samples)


def markdown_table(header: Sequence[str], rows: Sequence[Sequence[str]], numeric: Sequence[bool] | None = None) -> str:
    """A GitHub Markdown table; ``numeric`` columns are right-aligned."""
    numeric = numeric if numeric is not None else [False] * len(header)
    lines = ["| " + " | ".join(header) + " |", "| " + " | ".join("---:" if n else "---" for n in numeric) + " |"]
    lines += ["| " + " | ".join(row) + " |" for row in rows]
    return "\n".join(lines) + "\n"


def write_results(
    rows: list[dict[str, Any]], out: Path, stem: str, markdown: str, extra: dict[str, Any] | None = None
) -> None:
    """Write ``stem.json`` (``{"rows": rows, **extra}``), ``stem.csv`` (the rows: a column for every
    key any row has, empty where a row lacks it) and ``stem.md`` to ``out``, each through
    :func:`~ilc_steering.output.write_atomic`."""
    out.mkdir(parents=True, exist_ok=True)
    write_atomic(out / f"{stem}.json", json.dumps({"rows": rows, **(extra or {})}, indent=1, default=str))
    table = io.StringIO(newline="")
    writer = csv.DictWriter(table, fieldnames=list(dict.fromkeys(key for row in rows for key in row)))
    writer.writeheader()
    writer.writerows(rows)
    write_atomic(out / f"{stem}.csv", table.getvalue())
    write_atomic(out / f"{stem}.md", markdown)


def render_blocks(text: str, blocks: dict[str, str], kind: str, where: str) -> str:
    """``text`` with each block between ``<!-- KIND: NAME -->`` and ``<!-- /KIND -->`` rewritten
    to ``blocks[NAME]``: how a page quotes a table generated from an artifact. ``ValueError``
    names a block that is not known or not closed."""
    pattern = re.compile(rf"(<!-- {re.escape(kind)}: ([a-z0-9-]+) -->\n)(.*?)(<!-- /{re.escape(kind)} -->)", re.DOTALL)
    found = pattern.findall(text)
    if text.count(f"<!-- {kind}:") != len(found):
        raise BadInput(f"{where}: a <!-- {kind}: NAME --> marker without its <!-- /{kind} -->")
    for _, name, _, _ in found:
        if name not in blocks:
            raise BadInput(f"{where}: a {kind} block names {name!r}; choose from {list(blocks)}")
    return pattern.sub(lambda m: m.group(1) + blocks[m.group(2)] + m.group(4), text)


def rewrite_blocks(paths: Sequence[Path], blocks: dict[str, str], kind: str, check: bool = False) -> list[Path]:
    """The files of ``paths`` whose ``kind`` blocks are not ``blocks``, each rewritten unless ``check``."""
    stale = []
    for path in paths:
        text = path.read_text()
        new = render_blocks(text, blocks, kind, str(path))
        if new != text:
            stale.append(path)
            if not check:
                write_atomic(path, new)
    return stale


def update_pages(
    paths: Sequence[Path], check: bool, blocks: Callable[[], dict[str, str]], kind: str, script: str
) -> tuple[int, dict[str, str]]:
    """What a script that quotes generated tables does with ``--into paths`` and ``--check``: build
    ``blocks()`` and rewrite (with ``check``: compare) the ``kind`` blocks of ``paths``. Returns the
    exit code and the blocks: 2 with the error on stderr, 1 when ``check`` found a file whose blocks
    differ (each named on stdout with ``script``'s command that rewrites it), else 0."""
    try:
        made = blocks()
        stale = rewrite_blocks(paths, made, kind, check)
    except (OSError, ValueError, KeyError) as error:
        print(f"error: {error}", file=sys.stderr)
        return 2, {}
    for path in stale if check else []:
        print(f"{path}: its {kind} blocks are not the artifacts' (python {script} --into {path})")
    return (1 if check and stale else 0), made
