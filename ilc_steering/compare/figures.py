"""The figures of ``compare``: per scenario, every method's best error against trials; the
performance profile (the share of runs that reached a level within ``t`` trials)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ilc_steering.figure_styles import method_styles
from ilc_steering.output import write_figure

if TYPE_CHECKING:
    from matplotlib.figure import Figure
from ilc_steering.compare.stats import LADDER, LADDER_NAMES

__all__ = ["PROFILE_LEVELS", "plot_scenario", "profile", "profile_figure", "scenario_figure"]


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
