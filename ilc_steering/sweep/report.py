"""A sweep's report: one line per map, its heat maps, and the table (``sweep.{csv,json,md}``)."""

from __future__ import annotations

from dataclasses import asdict, dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from ilc_steering.output import MAX_RESULT_BYTES, write_figure
from ilc_steering.readers import read_json
from ilc_steering.schema import check_record
from ilc_steering.sweep.rows import ORACLE, axis_values, centre_values, gain_text, map_name

if TYPE_CHECKING:
    from ilc_steering.config import SteeringConfig
    from ilc_steering.sweep.rows import SweepArgs

__all__ = ["SweepLine", "SweepReport", "plot_map", "read_report", "summary", "write_sweep_report"]


@dataclass(frozen=True)
class SweepLine:
    """A line of ``sweep.json``'s ``rows``: one map (a method at a gain, or the oracle) in numbers."""

    method: str
    nu_b: float | None
    converged_fraction: float  # of the map's plants
    median_trials: float | None  # [trials] over the plants that converged
    max_trials: int | None  # [trials]
    at_nominal: int | None  # [trials] at the centre of the map (the nominal plant)
    wall_s: float | None  # [s]
    of_solvable: float | None = None  # the share of the plants the oracle could solve (a map with an oracle)


@dataclass(frozen=True)
class SweepReport:
    """``sweep.json``, as its schema: the maps' lines, the settings, the axes and the maps
    themselves (older runs wrote no ``values``, ``failed`` or ``solvable``; they still read)."""

    rows: tuple[SweepLine, ...]
    settings: dict[str, Any]
    axes: tuple[str, str]
    ratios: tuple[float, ...]
    maps: dict[str, tuple[tuple[int, ...], ...]]  # map name -> trials to the tolerance per plant (0: never)
    values: tuple[tuple[float, ...], tuple[float, ...]] | None = None
    failed: tuple[dict[str, Any], ...] = ()
    solvable: tuple[tuple[bool, ...], ...] | None = None


def read_report(path: Path) -> dict[str, Any]:
    """``sweep.json`` at ``path``, checked against :class:`SweepReport`: ``ValueError`` names the
    file and the key of the first thing wrong."""
    data: dict[str, Any] = read_json(path, MAX_RESULT_BYTES)
    check_record(SweepReport, data, path)
    return data


Mask = npt.NDArray[np.bool_]


def summary(
    args: SweepArgs,
    config: SteeringConfig,
    maps: dict[tuple[str, float], list[dict[str, Any]]],
    solvable: Mask | None = None,
) -> list[dict[str, Any]]:
    """One line per map: where it converged (and, with the oracle's ``solvable`` map, on which
    share of the region where the true plant can reach the goal), and how fast."""
    lines = []
    first_axis, second_axis = axis_values(args)
    c0, c1 = centre_values(args, config)
    centre = (int(np.argmin(np.abs(first_axis - c0))), int(np.argmin(np.abs(second_axis - c1))))
    if solvable is not None:
        lines.append(
            {
                "method": ORACLE,
                "nu_b": None,
                "converged_fraction": float(solvable.mean()),
                "of_solvable": 1.0,
                "median_trials": None,
                "max_trials": None,
                "at_nominal": None,
                "wall_s": None,
            }
        )
    for (method, gain), rows in maps.items():
        first = np.array([row["trials_to"] for row in rows])
        ok = first > 0
        share = None
        if solvable is not None and solvable.any():
            share = float((ok & solvable).sum() / solvable.sum())
        lines.append(
            {
                "method": method,
                "nu_b": gain,
                "converged_fraction": float(ok.mean()),
                "of_solvable": share,
                "median_trials": float(np.median(first[ok])) if ok.any() else None,
                "max_trials": int(first[ok].max()) if ok.any() else None,
                "at_nominal": int(first[centre]) or None,
                "wall_s": float(sum(row["wall_s"] for row in rows)),
            }
        )
    return lines


def plot_map(
    args: SweepArgs,
    config: SteeringConfig,
    method: str,
    gain: float,
    rows: list[dict[str, Any]],
    names: list[str],
    path: Path,
    solvable: Mask | None = None,
) -> None:
    """The heat map of one map: trials to tolerance over the grid, grey where not within budget,
    and with the oracle's map the edge of the region where the true plant can reach the goal."""
    import matplotlib
    from matplotlib.figure import Figure

    first = np.array([row["trials_to"] for row in rows], dtype=np.float64)
    first[first == 0] = np.nan
    first_axis, second_axis = axis_values(args)
    h0, h1 = 0.5 * (first_axis[1] - first_axis[0]), 0.5 * (second_axis[1] - second_axis[0])
    fig = Figure(figsize=(5.6, 4.6))
    ax = fig.subplots()
    cmap = matplotlib.colormaps["viridis"].with_extremes(bad="#d0d0d0")
    extent = (second_axis[0] - h1, second_axis[-1] + h1, first_axis[0] - h0, first_axis[-1] + h0)
    image = ax.imshow(first, origin="lower", extent=extent, cmap=cmap, aspect="auto", vmin=1)
    fig.colorbar(image, ax=ax, label=f"trials to tolerance (grey: not within {args.trials})")
    if solvable is not None and 0 < solvable.mean() < 1:
        ax.contour(second_axis, first_axis, solvable.astype(float), levels=[0.5], colors="red", linewidths=1.2)
        ax.plot([], [], "r-", label="edge of the oracle's solvable region")
        ax.legend(loc="upper left", bbox_to_anchor=(0.0, -0.14), fontsize=8, frameon=False)
    c0, c1 = centre_values(args, config)
    ax.plot([c1], [c0], "r+", markersize=12)
    unit = " (true / nominal)" if not args.axes else ""
    ax.set_xlabel(f"{names[1]}{unit}")
    ax.set_ylabel(f"{names[0]}{unit}")
    ax.set_title(f"{config.name}: {method}, nu_b = {gain:g}")
    fig.tight_layout()
    write_figure(path, fig, dpi=90)


def write_sweep_report(
    args: SweepArgs,
    config: SteeringConfig,
    names: list[str],
    maps: dict[tuple[str, float], list[dict[str, Any]]],
    failed: list[dict[str, Any]],
    solvable: Mask | None,
) -> tuple[str, list[dict[str, Any]]]:
    """Write ``sweep.{csv,json,md}`` and a heat map per map into ``args.out``; returns the table
    and the summary's lines."""
    from ilc_steering.tables import markdown_table, write_results

    lines = summary(args, config, maps, solvable)
    for (method, gain), rows in maps.items():
        path = args.out / f"sweep_{map_name(method, gain)}.png"
        plot_map(args, config, method, gain, rows, names, path, solvable)
    header = ["method", "nu_b", "converged", "median trials", "most trials", "at the nominal plant", "cell time [s]"]
    if solvable is not None:
        header.insert(3, "of the solvable region")

    def text(value: Any, form: str) -> str:
        return "-" if value is None else format(value, form)

    cells = []
    for line in lines:
        cell = [
            line["method"] + (" (knows the true plant)" if line["method"] == ORACLE else ""),
            text(line["nu_b"], "g"),
            f"{100 * line['converged_fraction']:.1f} %",
            text(line["median_trials"], "g"),
            text(line["max_trials"], "d"),
            text(line["at_nominal"], "d"),
            text(line["wall_s"], ".1f"),
        ]
        if solvable is not None:
            cell.insert(3, "-" if line["of_solvable"] is None else f"{100 * line['of_solvable']:.1f} %")
        cells.append(cell)
    table = markdown_table(header, cells, [False] + [True] * (len(header) - 1))
    grid = {
        f"{method}__nu{gain_text(gain)}": [row["trials_to"] for row in rows] for (method, gain), rows in maps.items()
    }
    extra = {"settings": {**asdict(args), "out": None}, "axes": names, "failed": failed}
    first_axis, second_axis = axis_values(args)
    values = {"ratios": first_axis.tolist(), "values": [first_axis.tolist(), second_axis.tolist()], "maps": grid}
    if solvable is not None:
        values["solvable"] = solvable.tolist()
    write_results(lines, args.out, "sweep", table, {**extra, **values})
    return table, lines
