"""Results of benchmarks and comparisons as JSON, CSV and Markdown, and the timing they share."""

from __future__ import annotations

import csv
import io
import json
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from statistics import median
from typing import Any

from ilc_steering.output import write_atomic

__all__ = ["markdown_table", "median_seconds", "write_results"]


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
    """Write ``stem.json`` (``{"rows": rows, **extra}``), ``stem.csv`` (the rows) and ``stem.md`` to
    ``out``, each through :func:`~ilc_steering.output.write_atomic`."""
    out.mkdir(parents=True, exist_ok=True)
    write_atomic(out / f"{stem}.json", json.dumps({"rows": rows, **(extra or {})}, indent=1, default=str))
    table = io.StringIO(newline="")
    writer = csv.DictWriter(table, fieldnames=list(rows[0]))
    writer.writeheader()
    writer.writerows(rows)
    write_atomic(out / f"{stem}.csv", table.getvalue())
    write_atomic(out / f"{stem}.md", markdown)
