"""What ``compare`` reports from its cells: summaries across seeds, tables, ratios and figures.

One summary row per (prior, method, scenario): for each tolerance of
:data:`~ilc_steering.compare.stats.LADDER`, the median trials to it with the interquartile range (order
statistics, so a seed that never got there stays ``inf``), a 95 % bootstrap confidence interval
of the median, how many seeds got there, and how many of those counts are fragile (a relative
change of 1e-6 in the error would move them: marked ``†`` in the tables); the best true cost, the
off-chart fraction and the wall time. Failed cells are listed apart, never summarized. The ratios
compare ILC (``ilc``) with the best method of each family (black-box, RL) at each tolerance.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ilc_steering.output import write_figure
from ilc_steering.tables import markdown_table, write_results

if TYPE_CHECKING:
    pass
from ilc_steering.compare.figures import plot_scenario, profile_figure
from ilc_steering.compare.stats import LADDER, LADDER_NAMES, ratios, summarize

__all__ = ["NOTE", "failed_table", "iqm_table", "main_table", "ratio_table", "report", "statistic", "write_report"]


def _trials(value: float, budget: int) -> str:
    return f"> {budget}" if math.isinf(value) else f"{value:.0f}"


def _interval(interval: Any, budget: int) -> str:
    if interval is None:
        return ""
    low, high = (math.inf if v is None else v for v in interval)
    return f" [{_trials(low, budget)}, {_trials(high, budget)}]"


def statistic(entry: dict[str, Any], name: str, budget: int) -> str:
    """``value [95 % CI]``, trials; ``> budget`` where the seeds that never got there decide it."""
    value = math.inf if entry[name] is None else entry[name]
    shown = _trials(value, budget) if math.isinf(value) or name == "median" else f"{value:.1f}"
    interval = entry[f"{name}_ci95"]
    if interval is not None and all(v is None or math.isinf(v) for v in interval) and math.isinf(value):
        return shown  # no seed got there: nothing to bound
    return shown + _interval(interval, budget)


def _reached(entry: dict[str, Any], budget: int, seeds: int) -> str:
    mark = " †" if entry.get("fragile") else ""
    return f"{statistic(entry, 'median', budget)} ({entry['reached']}/{seeds}){mark}"


def main_table(rows: list[dict[str, Any]], prior: str) -> str:
    header = [
        "scenario",
        "method",
        "budget",
        *(f"trials to {LADDER_NAMES[level]}" for level in LADDER),
        "best error",
        "off chart",
        "clipped",
        "wall [s]",
        "update [ms]",
    ]
    lines = []
    for row in (r for r in rows if r["prior"] == prior):
        b1, b2, b3 = row["best_error_q1_median_q3"]
        lines.append(
            [
                row["scenario"],
                row["method"],
                str(row["budget"]),
                *(_reached(row[f"trials_to_{level}"], row["budget"], row["seeds"]) for level in LADDER),
                f"{b2:.1e} [{b1:.1e}, {b3:.1e}]",
                f"{100 * row['off_chart_fraction_median']:.0f}%",
                f"{100 * row['clipped_fraction_median']:.0f}%",
                f"{row['wall_s_median']:.3g}",
                "-" if row.get("update_s_median") is None else f"{1e3 * row['update_s_median']:.3g}",
            ]
        )
    return markdown_table(header, lines, [False, False, *[True] * (len(header) - 2)])


def iqm_table(rows: list[dict[str, Any]], prior: str) -> str:
    header = ["scenario", "method", *(LADDER_NAMES[level] for level in LADDER)]
    lines = []
    for row in (r for r in rows if r["prior"] == prior):
        cells = [statistic(row[f"trials_to_{level}"], "iqm", row["budget"]) for level in LADDER]
        lines.append([row["scenario"], row["method"], *cells])
    return markdown_table(header, lines, [False, False, *[True] * len(LADDER)])


def ratio_table(entries: list[dict[str, Any]], families: list[str]) -> str:
    header = ["prior", "scenario", "tolerance", "ilc"]
    for family in families:
        header += [f"best {family}", "x ilc"]
    lines = []
    for e in entries:
        row = [e["prior"], e["scenario"], LADDER_NAMES[e["tolerance"]]]
        row.append("not within the budget" if math.isinf(e["ilc"]) else f"{e['ilc']:.0f}")
        for family in families:
            best = e.get(family)
            if best is None:
                row += ["-", "-"]
            elif math.isinf(best["median"]):
                row += ["none within the budget", "-"]
            else:
                row += [f"{best['method']}: {best['median']:.0f}", f"{best['ratio']:.3g}"]
        lines.append(row)
    return markdown_table(header, lines, [False, False, False, True, *[False, True] * len(families)])


NOTE = (
    "Median [95 % bootstrap confidence interval] (k/n) of the trials to each level across seeds; (k/n): seeds that "
    "reached it within the budget; a seed that never did counts as more than the budget, so a median or bound it "
    "decides reads '> budget'. Intervals: scipy.stats.bootstrap, percentile method, 2000 resamples of the seeds. "
    "Every trial counts: probes, random exploration and RL's deterministic trials included. "
    "Errors are those of the true final configuration (the noisy scenario measures with noise). Best error: median "
    "[interquartile range] of the lowest true Cartesian error [m] + orientation error [rad] (a chained plant: error "
    "norm) of any trial, 1000 added for a trial that left the chart. Off chart: the median fraction of trials that "
    "left the chart; clipped: of actions the env clipped to its box. "
    "A level is met when the error is at most the level; †: in some seed, a relative change of 1e-6 in the "
    "error would move this count (the error lands on the level, and the integrator's last digits decide).\n"
)


def failed_table(failed: list[dict[str, Any]]) -> str:
    lines = [
        [f["prior"], f["scenario"], f["method"], str(f["seed"]), " ".join(f["error"].split())[:300]] for f in failed
    ]
    return markdown_table(["prior", "scenario", "method", "seed", "error"], lines, [False] * 3 + [True, False])


def report(
    rows: list[dict[str, Any]],
    entries: list[dict[str, Any]],
    families: list[str],
    failed: list[dict[str, Any]] | None = None,
) -> str:
    priors = list(dict.fromkeys(r["prior"] for r in rows))
    parts = []
    if failed:
        parts += [f"### {len(failed)} failed cells (not in the tables below; a resume computes them again)\n"]
        parts += [failed_table(failed)]
    for prior in priors:
        parts += [f"### prior={prior}\n", main_table(rows, prior)]
    parts.append(NOTE)
    if entries:
        title = f"### Ratios: median trials of the best {' and the best '.join(families)} method over ILC's\n"
        parts += [title, ratio_table(entries, families)]
    for prior in priors:
        parts += [
            f"### prior={prior}: interquartile mean of the trials [95 % bootstrap confidence interval]\n",
            iqm_table(rows, prior),
        ]
    return "\n".join(parts)


def _finite(data: Any) -> Any:
    """``data`` with every infinite float (not reached) as ``None``: strict JSON has no infinity."""
    if isinstance(data, float) and math.isinf(data):
        return None
    if isinstance(data, dict):
        return {k: _finite(v) for k, v in data.items()}
    if isinstance(data, (list, tuple)):
        return [_finite(v) for v in data]
    return data


def write_report(
    cells: list[dict[str, Any]],
    scenarios: list[str],
    out: Path,
    families: dict[str, tuple[str, ...]],
    failed: list[dict[str, Any]] | None = None,
    groups: Mapping[str, Sequence[str]] | None = None,
) -> str:
    """``compare.{csv,json,md}`` and ``compare_<scenario>.png`` in ``out``, ratios over ``families``
    of methods (name -> method ids), the ``failed`` cells listed, the figures coloured by the
    families of ``groups`` (default: ``families``); returns the Markdown."""
    rows = summarize(cells)
    entries = ratios(rows, families)
    text = report(rows, entries, list(families), failed)
    flat = []
    for cell in cells:
        flat.append(
            {
                **{k: v for k, v in cell.items() if k not in ("curve", "trials_to", "fragile")},
                **{f"trials_to_{level}": cell["trials_to"][level] for level in LADDER},
                "fragile": " ".join(cell.get("fragile", [])),
            }
        )
    extra = {"summary": _finite(rows), "ratios": _finite(entries), "cells": cells, "failed": failed or []}
    write_results(flat, out, "compare", text, extra)
    styles = families if groups is None else groups
    for scenario in scenarios:
        if any(c["scenario"] == scenario for c in cells):
            plot_scenario(cells, scenario, out / f"compare_{scenario}.png", styles)
    write_figure(out / "compare_profile.png", profile_figure(cells, styles), dpi=100)
    return text
