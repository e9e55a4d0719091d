"""What ``compare`` reports from its cells: summaries across seeds, tables, ratios and figures.

One summary row per (prior, method, scenario): for each tolerance of
:data:`~ilc_steering.compare.report.LADDER`, the median trials to it with the interquartile range (order
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

import numpy as np

from ilc_steering.figure_styles import method_styles
from ilc_steering.output import write_figure

if TYPE_CHECKING:
    from matplotlib.figure import Figure
from ilc_steering.tables import markdown_table, write_results

__all__ = [
    "LADDER",
    "LADDER_NAMES",
    "bootstrap_median",
    "profile",
    "profile_figure",
    "quartiles",
    "ratios",
    "scenario_figure",
    "statistic_ci",
    "summarize",
    "write_report",
]

LADDER = {"10cm": 0.1, "1cm": 0.01, "1mm": 1e-3, "0.5mm": 5e-4}
"""Tolerances: the Cartesian error [m] and the orientation error [rad] both within the value (a
chained plant: its error norm ``||z^d - z(T)||``)."""
LADDER_NAMES = {
    "10cm": "10 cm / 0.1 rad",
    "1cm": "1 cm / 0.01 rad",
    "1mm": "1 mm / 1 mrad",
    "0.5mm": "0.5 mm / 0.5 mrad",
}

BOOTSTRAP_RESAMPLES = 2000
CENSORED = 1e15
"""Where a seed that never reached a level stands in a bootstrap (``inf`` has no arithmetic): any
statistic it enters exceeds :data:`UNREACHED`, and is reported as not within the budget."""
UNREACHED = 1e9


def quartiles(values: list[float]) -> tuple[float, float, float]:
    """Quartiles as order statistics (no interpolation): ``inf`` (not reached) stays ``inf``."""
    q1, q2, q3 = np.percentile(np.asarray(values, dtype=np.float64), [25, 50, 75], method="inverted_cdf")
    return float(q1), float(q2), float(q3)


def _median(data: Any, axis: int = -1) -> Any:
    return np.median(data, axis=axis)


def _iqm(data: Any, axis: int = -1) -> Any:
    """The interquartile mean: the mean of the middle half (``scipy.stats.trim_mean``, a quarter cut
    from each end), the aggregate Agarwal et al. (NeurIPS 2021) recommend over few seeds."""
    from scipy.stats import trim_mean

    return trim_mean(data, 0.25, axis=axis)


STATISTICS = {"median": _median, "iqm": _iqm}
"""The statistics of trials to a level across seeds, each with a bootstrap interval."""


def _uncensored(value: float) -> float:
    return math.inf if value > UNREACHED else float(value)


def statistic_ci(values: list[float], statistic: str, seed: int = 0) -> tuple[float, tuple[float, float] | None]:
    """``statistic`` (``median`` or ``iqm``) of ``values`` (trials; ``inf``: not reached) and its
    95 % percentile-bootstrap confidence interval from ``scipy.stats.bootstrap``
    (:data:`BOOTSTRAP_RESAMPLES` resamples of the seeds, seeded); None for fewer than two seeds. A
    statistic or bound that a seed which never got there enters is ``inf`` (:data:`CENSORED`)."""
    from scipy.stats import bootstrap

    function = STATISTICS[statistic]
    data = np.where(np.isinf(values), CENSORED, np.asarray(values, dtype=np.float64))
    value = _uncensored(float(function(data)))
    if data.size < 2:
        return value, None
    if np.all(data == data[0]):  # every resample is the sample: the interval is the point
        return value, (value, value)
    result = bootstrap(
        (data,),
        function,
        n_resamples=BOOTSTRAP_RESAMPLES,
        confidence_level=0.95,
        method="percentile",
        vectorized=True,
        rng=np.random.default_rng(seed),
    )
    low, high = result.confidence_interval
    return value, (_uncensored(float(low)), _uncensored(float(high)))


def bootstrap_median(values: list[float], seed: int = 0) -> tuple[float, float]:
    """The 95 % bootstrap confidence interval of the median (:func:`statistic_ci`); ``(v, v)`` for
    one seed."""
    value, interval = statistic_ci(values, "median", seed)
    return interval if interval is not None else (value, value)


def summarize(cells: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """One summary row per (prior, method, scenario), in the cells' order."""
    groups: dict[tuple[str, str, str], list[dict[str, Any]]] = {}
    for cell in cells:
        groups.setdefault((cell["prior"], cell["scenario"], cell["method"]), []).append(cell)
    rows = []
    for (prior, scenario, method), group in groups.items():
        row: dict[str, Any] = {
            "prior": prior,
            "scenario": scenario,
            "method": method,
            "budget": group[0]["budget"],
            "seeds": len(group),
        }
        for level in LADDER:
            reached = [math.inf if c["trials_to"][level] is None else c["trials_to"][level] for c in group]
            entry: dict[str, Any] = {"q1_median_q3": quartiles(reached)}
            for name in STATISTICS:
                value, interval = statistic_ci(reached, name)
                entry[name] = value
                entry[f"{name}_ci95"] = interval
            entry["reached"] = int(np.isfinite(reached).sum())
            entry["fragile"] = sum(level in c.get("fragile", ()) for c in group)
            row[f"trials_to_{level}"] = entry
        row["best_error_q1_median_q3"] = quartiles([c["best_error"] for c in group])
        row["off_chart_fraction_median"] = float(np.median([c["off_chart_fraction"] for c in group]))
        row["clipped_fraction_median"] = float(np.median([c.get("clipped_fraction", 0.0) for c in group]))
        row["wall_s_median"] = float(np.median([c["wall_s"] for c in group]))
        updates = [c["update_s"] for c in group if c.get("update_s") is not None]
        row["update_s_median"] = float(np.median(updates)) if updates else None
        rows.append(row)
    return rows


def _trials(value: float, budget: int) -> str:
    return f"> {budget}" if math.isinf(value) else f"{value:.0f}"


def _interval(interval: Any, budget: int) -> str:
    if interval is None:
        return ""
    low, high = (math.inf if v is None else v for v in interval)
    return f" [{_trials(low, budget)}, {_trials(high, budget)}]"


def _statistic(entry: dict[str, Any], name: str, budget: int) -> str:
    """``value [95 % CI]``, trials; ``> budget`` where the seeds that never got there decide it."""
    value = math.inf if entry[name] is None else entry[name]
    shown = _trials(value, budget) if math.isinf(value) or name == "median" else f"{value:.1f}"
    interval = entry[f"{name}_ci95"]
    if interval is not None and all(v is None or math.isinf(v) for v in interval) and math.isinf(value):
        return shown  # no seed got there: nothing to bound
    return shown + _interval(interval, budget)


def _reached(entry: dict[str, Any], budget: int, seeds: int) -> str:
    mark = " †" if entry.get("fragile") else ""
    return f"{_statistic(entry, 'median', budget)} ({entry['reached']}/{seeds}){mark}"


def _main_table(rows: list[dict[str, Any]], prior: str) -> str:
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


def _iqm_table(rows: list[dict[str, Any]], prior: str) -> str:
    header = ["scenario", "method", *(LADDER_NAMES[level] for level in LADDER)]
    lines = []
    for row in (r for r in rows if r["prior"] == prior):
        cells = [_statistic(row[f"trials_to_{level}"], "iqm", row["budget"]) for level in LADDER]
        lines.append([row["scenario"], row["method"], *cells])
    return markdown_table(header, lines, [False, False, *[True] * len(LADDER)])


def _median_trials(row: dict[str, Any], level: str) -> float:
    return float(row[f"trials_to_{level}"]["median"])


def ratios(rows: list[dict[str, Any]], families: dict[str, tuple[str, ...]]) -> list[dict[str, Any]]:
    """Per (prior, scenario, tolerance): ILC's median trials and, per family of methods, the best
    one's median (the fewest; ``inf`` when none got there in half the seeds) with its ratio to ILC."""
    out = []
    for prior, scenario in dict.fromkeys((r["prior"], r["scenario"]) for r in rows):
        group = {r["method"]: r for r in rows if r["prior"] == prior and r["scenario"] == scenario}
        if "ilc" not in group:
            continue
        for level in LADDER:
            ilc = _median_trials(group["ilc"], level)
            entry: dict[str, Any] = {"prior": prior, "scenario": scenario, "tolerance": level, "ilc": ilc}
            for family, methods in families.items():
                medians = {m: _median_trials(group[m], level) for m in methods if m in group}
                if medians:
                    best = min(medians, key=lambda m: medians[m])
                    entry[family] = {"method": best, "median": medians[best], "ratio": medians[best] / ilc}
            out.append(entry)
    return out


def _ratio_table(entries: list[dict[str, Any]], families: list[str]) -> str:
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


def _failed_table(failed: list[dict[str, Any]]) -> str:
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
        parts += [_failed_table(failed)]
    for prior in priors:
        parts += [f"### prior={prior}\n", _main_table(rows, prior)]
    parts.append(NOTE)
    if entries:
        title = f"### Ratios: median trials of the best {' and the best '.join(families)} method over ILC's\n"
        parts += [title, _ratio_table(entries, families)]
    for prior in priors:
        parts += [
            f"### prior={prior}: interquartile mean of the trials [95 % bootstrap confidence interval]\n",
            _iqm_table(rows, prior),
        ]
    return "\n".join(parts)


def _step_curve(curve: list[list[float]], trials: int, grid: np.ndarray) -> np.ndarray:
    """The best-so-far step function on ``grid`` (NaN past the run's last trial)."""
    at, best = np.array([p[0] for p in curve]), np.array([p[1] for p in curve])
    values = best[np.searchsorted(at, grid, side="right") - 1]
    return np.where(grid <= trials, values, np.nan)


LEGEND_ROWS = 26
"""The most legend entries (methods and family headings) in one column of a comparison figure."""


def scenario_figure(
    cells: list[dict[str, Any]], scenario: str, groups: Mapping[str, Sequence[str]] | None = None
) -> Figure:
    """Best error so far against trials, log-log, one panel per prior: the median across seeds,
    the interquartile band shaded. Each method in its family's colour (``groups``: family ->
    methods; :func:`~ilc_steering.figure_styles.method_styles`) with its own marker and line
    style, under one legend beside the panels, grouped by family."""
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D

    priors = list(dict.fromkeys(c["prior"] for c in cells))
    methods = list(dict.fromkeys(c["method"] for c in cells if c["scenario"] == scenario))
    styles = method_styles(methods, groups or {})
    figure = Figure(figsize=(5.6 * len(priors) + 2.4, 4.8), layout="constrained")
    axes = figure.subplots(1, len(priors), squeeze=False)[0]
    handles: dict[str, Any] = {}
    for ax, prior in zip(axes, priors):
        for index, method in enumerate(methods):
            runs = [c for c in cells if c["scenario"] == scenario and c["method"] == method and c["prior"] == prior]
            if not runs:
                continue
            style = styles[method]
            grid = np.unique(np.geomspace(1, max(r["trials"] for r in runs), 200).astype(int))
            values = np.array([_step_curve(r["curve"], r["trials"], grid) for r in runs])
            q1, q2, q3 = np.nanpercentile(values, [25, 50, 75], axis=0)
            (line,) = ax.plot(
                grid,
                q2,
                color=style.colour,
                marker=style.marker,
                linestyle=style.linestyle,
                markersize=4,
                markevery=(0.013 * (index % 7), 0.09),  # staggered: equal curves still show every marker
                label=method,
            )
            handles.setdefault(method, line)
            ax.fill_between(grid, q1, q3, color=style.colour, alpha=0.12, linewidth=0)
        for tolerance, style_name in ((2 * LADDER["1cm"], ":"), (2 * LADDER["0.5mm"], "--")):
            ax.axhline(tolerance, color="grey", linestyle=style_name, linewidth=0.8)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("trials")
        ax.set_ylabel("best true error so far [m + rad]")
        ax.set_title(f"{scenario.replace('_', ' ')}, prior {prior}", fontsize=9)
        ax.grid(True, which="major", alpha=0.3)
    entries: list[tuple[Any, str]] = []
    for family in dict.fromkeys(styles[m].family for m in handles):
        entries.append((Line2D([], [], linestyle="none"), f"{family}:"))  # a heading: no line, no marker
        entries += [(handles[m], m) for m in handles if styles[m].family == family]
    columns = 1 + (len(entries) - 1) // LEGEND_ROWS  # a second column before the legend outgrows the figure
    figure.legend(*zip(*entries), loc="outside right upper", fontsize=7, handlelength=3, frameon=False, ncols=columns)
    figure.suptitle(
        "Best error against trials: median and interquartile range across seeds\n"
        "(dotted: 1 cm + 0.01 rad, dashed: 0.5 mm + 0.5 mrad)",
        fontsize=9,
    )
    return figure


def plot_scenario(
    cells: list[dict[str, Any]], scenario: str, path: Path, groups: Mapping[str, Sequence[str]] | None = None
) -> None:
    """:func:`scenario_figure`, written to ``path`` as PNG."""
    write_figure(path, scenario_figure(cells, scenario, groups), dpi=100)


PROFILE_LEVELS = ("1cm", "0.5mm")
"""The levels of the performance profile's panels."""


def profile(cells: list[dict[str, Any]], level: str, grid: np.ndarray) -> np.ndarray:
    """The share of ``cells`` (runs: one task, one seed) that reached ``level`` within each number
    of trials of ``grid``; a run that never did counts as unsolved everywhere."""
    reached = np.array([np.inf if c["trials_to"][level] is None else c["trials_to"][level] for c in cells])
    return np.asarray((reached[:, None] <= grid[None, :]).mean(axis=0), dtype=np.float64)


def profile_figure(cells: list[dict[str, Any]], groups: Mapping[str, Sequence[str]] | None = None) -> Figure:
    """The performance profile of every method (a data profile in Moré and Wild's sense, the
    score distribution of Agarwal et al.): over every (scenario, seed) run of a prior, the share
    that reached a level within ``t`` trials against ``t``, log-scaled; one panel per prior and level
    of :data:`PROFILE_LEVELS`. Higher and further left is better."""
    from matplotlib.figure import Figure

    priors = list(dict.fromkeys(c["prior"] for c in cells))
    methods = list(dict.fromkeys(c["method"] for c in cells))
    styles = method_styles(methods, groups or {})
    figure = Figure(figsize=(4.6 * len(PROFILE_LEVELS) + 2.4, 3.6 * len(priors)), layout="constrained")
    axes = figure.subplots(len(priors), len(PROFILE_LEVELS), squeeze=False)
    most = max(c["budget"] for c in cells)
    grid = np.unique(np.geomspace(1, most, 400).astype(int))
    handles: dict[str, Any] = {}
    for row, prior in enumerate(priors):
        for column, level in enumerate(PROFILE_LEVELS):
            ax = axes[row][column]
            for index, method in enumerate(methods):
                runs = [c for c in cells if c["prior"] == prior and c["method"] == method]
                if not runs:
                    continue
                style = styles[method]
                (line,) = ax.step(
                    grid,
                    profile(runs, level, grid),
                    where="post",
                    color=style.colour,
                    marker=style.marker,
                    linestyle=style.linestyle,
                    markersize=4,
                    markevery=(0.013 * (index % 7), 0.09),
                    label=method,
                )
                handles.setdefault(method, line)
            ax.set_xscale("log")
            ax.set_ylim(-0.02, 1.02)
            ax.set_xlabel("trials")
            ax.set_ylabel("share of runs (scenario x seed)")
            ax.set_title(f"prior {prior}: reached {LADDER_NAMES[level]}", fontsize=9)
            ax.grid(True, which="major", alpha=0.3)
    figure.legend(
        list(handles.values()), list(handles), loc="outside right upper", fontsize=7, handlelength=3, frameon=False
    )
    figure.suptitle("Performance profile: the share of runs that reached the level within t trials", fontsize=9)
    return figure


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
