"""The robustness maps' tables, from the committed map folders, into the pages that quote them.

    python benchmarks/map_tables.py [--into docs/robustness.md docs/diagnosis.md] [--check]

prints the blocks; ``--into`` rewrites each block between ``<!-- map-table: NAME -->`` and
``<!-- /map-table -->`` in each file; ``--check`` exits 1 if a file's block differs. The blocks:
``robustness`` (``results/robustness/robustness.md``, written by ``python benchmarks/robustness.py
--report --out results/robustness``), ``sweep`` and ``sweep-blackbox`` (the ``sweep.md`` of
``results/sweep`` and ``results/sweep_blackbox``), ``diagnosis-maps`` (the servo and lag maps of
``results/robustness/diagnosis.json``, written by ``python benchmarks/robustness_diagnosis.py --out
results/robustness``).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from ilc_steering.arguments import Parser
from ilc_steering.tables import markdown_table, update_pages

__all__ = ["KIND", "diagnosis_maps", "tables"]

KIND = "map-table"
RESULTS = Path("results")
DIAGNOSIS_MAPS = {
    "parallel_parking_servo": "servo (steering offset x wheel radius, lag 0.05 s)",
    "parallel_parking_lag": "lag (steering lag 0-0.1 s x steering offset)",
}


def _table_lines(path: Path) -> str:
    """The Markdown table of ``path`` (its lines that start with ``|``)."""
    return "".join(line + "\n" for line in path.read_text().splitlines() if line.startswith("|"))


def diagnosis_maps(diagnosis: dict[str, Any]) -> str:
    """The servo and lag maps' shares of their solvable plants, each method a column."""
    maps = diagnosis["maps"]

    def share(line: dict[str, Any]) -> str:
        if line["rows"] < line["of_rows"]:
            raise ValueError(f"diagnosis.json: a map of {line['rows']} of {line['of_rows']} rows; run it to the end")
        return f"{100 * line['converged_of_solvable']:.1f} %"

    def count(value: float | None) -> str:
        return "-" if value is None else f"{value:g}"

    rows = [
        [
            label,
            share(maps[name]),
            count(maps[name]["median_trials"]),
            count(maps[name]["max_trials"]),
            share(maps[f"{name}/newton_ilc"]),
            share(maps[f"{name}/ilc_paper"]),
        ]
        for name, label in DIAGNOSIS_MAPS.items()
    ]
    header = ["map", "`robust_ilc`: converged of solvable", "median trials", "most trials"]
    header += ["`newton_ilc`", "eqs. 33-34"]
    return markdown_table(header, rows, [False, True, True, True, True, True])


def tables(results: Path = RESULTS) -> dict[str, str]:
    """Every block's text by name, from the committed folders under ``results``."""
    return {
        "robustness": _table_lines(results / "robustness/robustness.md"),
        "sweep": _table_lines(results / "sweep/sweep.md"),
        "sweep-blackbox": _table_lines(results / "sweep_blackbox/sweep.md"),
        "diagnosis-maps": diagnosis_maps(json.loads((results / "robustness/diagnosis.json").read_text())),
    }


def main(argv: list[str] | None = None) -> int:
    parser = Parser(description=__doc__.splitlines()[0])
    parser.add_argument("--into", type=Path, nargs="*", default=[])
    parser.add_argument("--check", action="store_true", help="exit 1 if a file's block is not the table")
    parser.add_argument("--results", type=Path, default=RESULTS, help="holds robustness/, sweep/, sweep_blackbox/")
    args = parser.parse_args(argv)
    code, blocks = update_pages(args.into, args.check, lambda: tables(args.results), KIND, "benchmarks/map_tables.py")
    if not (code or args.check or args.into):
        for name, block in blocks.items():
            print(f"{name}:\n{block}")
    return code


if __name__ == "__main__":
    raise SystemExit(main())
