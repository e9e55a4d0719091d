"""The paper's figures from a run's JSON (``ilc-steering run --json``, ``plot``, ``reproduce --plots``).

One-trial runs (simulations 1-3; the experiments' Figs. 16-21 are of the same kinds):

- ``trajectory``: the last trial's path, stroboscopic, with the configuration at the end of the
  first trial dotted (Figs. 3, 7, 11, 16, 19);
- ``coordinates``: ``x``, ``y``, ``theta``, ``phi`` over the last trial (Figs. 4, 8, 12);
- ``inputs``: ``u1`` and ``u2`` over the last trial (Figs. 5, 9, 13, 17, 20);
- ``errors``: the Cartesian and orientation errors over the trials, log scale (Figs. 6, 10, 14, 18, 21).

Cyclic runs (simulation 4): ``path``, the path over the first cycles with the arrivals numbered
in order (Fig. 23), and ``waypoint_errors``, each waypoint's errors over the cycles (Figs. 24-25).
Figures are drawn on matplotlib's Agg canvas; no display is needed.
"""

from __future__ import annotations

from dataclasses import dataclass
from math import isfinite
from pathlib import Path
from typing import Any

import matplotlib
import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from ilc_steering.config import SteeringConfig, load_config
from ilc_steering.core.plants import PlantKind
from ilc_steering.core.robots.process import without_program
from ilc_steering.core.trajectory import Trajectory
from ilc_steering.envs.rendering import draw_pose, draw_trial, draw_waypoints, plane, setup_workspace
from ilc_steering.errors import BadInput, ConfigError
from ilc_steering.output import safe_name, write_figure
from ilc_steering.readers import read_json

__all__ = ["Run", "figure_paths", "load_run", "write_plots"]

TRIAL_FIGURES = ("trajectory", "coordinates", "inputs", "errors")
CYCLIC_FIGURES = ("path", "waypoint_errors")
FIRST = "tab:red"
LATER = "tab:orange"


@dataclass(frozen=True)
class Run:
    """A run's JSON, checked: its config and its records in order (for a cyclic run, one per
    waypoint reached, each with its ``cycle`` and waypoint ``index``)."""

    config: SteeringConfig
    records: list[dict[str, Any]]
    cyclic: bool

    @property
    def name(self) -> str:
        return self.config.name

    @property
    def kind(self) -> PlantKind:
        return self.config.plant.kind

    @property
    def has_pose(self) -> bool:
        """The robot has ``x``, ``y``, ``theta``: Cartesian and orientation errors, a workspace drawing."""
        return self.kind.has_pose

    @property
    def robot(self) -> Any:
        """The nominal map the robot is drawn with (a chained plant's has no outline: a point)."""
        return self.config.plant.nominal_map()

    @property
    def dimension(self) -> int | None:
        """``None`` for a robot with a pose, else the chained form's ``n`` (for axis labels)."""
        return None if self.has_pose else self.config.plant.dimension

    def trajectory(self, record: dict[str, Any]) -> Trajectory:
        if "trajectory" not in record:
            raise BadInput(
                f"{self.name}: the run has no trajectories; write it with `ilc-steering run CONFIG --json RUN.json`, "
                "which records them"
            )
        return Trajectory.from_json(record["trajectory"])


def load_run(source: Path | dict[str, Any]) -> Run:
    """A :class:`Run` from a JSON file or its parsed content; ``ValueError`` names what is missing."""
    origin = str(source) if isinstance(source, Path) else "<run>"
    data = read_json(source, MAX_RUN_BYTES) if isinstance(source, Path) else source  # size, then depth
    if (
        not isinstance(data, dict)
        or data.get("kind") not in ("trials", "cycles")
        or not isinstance(data.get("config"), dict)
    ):
        raise BadInput(
            f"{origin}: not a run's JSON (needs 'kind': 'trials' or 'cycles' and a 'config' mapping; "
            "written by `ilc-steering run --json`)"
        )
    try:
        with without_program():  # a run of a robot program is drawn wherever the program is now
            config = load_config(data["config"])
    except ConfigError as error:
        raise BadInput(f"{origin}: its config: {error}") from None
    kind = data["kind"]
    try:
        if kind == "trials":
            records = [dict(r) for r in data["trials"]]
        else:
            records = [{**w, "cycle": c["cycle"]} for c in data["cycles"] for w in c["waypoints"]]
    except (KeyError, TypeError, ValueError) as error:
        raise BadInput(f"{origin}: malformed {kind} list ({error!r})") from None
    if not records:
        raise BadInput(f"{origin}: the run has no {kind}")
    for i, record in enumerate(records):
        problem = _record_problem(record, kind == "cycles", config)
        if problem:
            raise BadInput(f"{origin}: {kind} record {i}: {problem}")
    return Run(config, records, kind == "cycles")


MAX_RUN_BYTES = 64 << 20
"""The largest run JSON ``plot`` reads [bytes]."""


def _record_problem(record: dict[str, Any], cyclic: bool, config: SteeringConfig) -> str | None:
    """What is wrong with one record of a run, or ``None``."""
    numbers = ["error_norm", *(["cartesian_error", "orientation_error"] if config.plant.kind.has_pose else [])]
    integers = ["cycle", "index"] if cyclic else ["trial"]
    for key in integers:
        if not isinstance(record.get(key), int) or isinstance(record.get(key), bool) or record[key] < 0:
            return f"{key!r} must be a whole number >= 0"
    for key in numbers:
        value = record.get(key)
        if not isinstance(value, (int, float)) or isinstance(value, bool) or not isfinite(value) or value < 0:
            return f"{key!r} must be a finite number >= 0, got {value!r:.40}"
    state = record.get("final_state")
    size = config.plant.dimension
    if not isinstance(state, list) or len(state) != size or not all(_finite(v) for v in state):
        return f"'final_state' must be a list of {size} finite numbers"
    if "trajectory" in record:
        return _trajectory_problem(record["trajectory"], size)
    return None


def _finite(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and isfinite(value)


def _trajectory_problem(data: Any, size: int) -> str | None:
    """What is wrong with a recorded trajectory: its keys, its shapes (``t`` ``(S,)``, ``q`` ``(S, n)``,
    ``u`` ``(S, 2)``), a value that is not a finite number, or a time axis that goes back."""
    if not isinstance(data, dict) or not all(key in data for key in ("t", "q", "u")):
        return "'trajectory' must be a mapping with keys t, q and u"
    arrays = {}
    for key in ("t", "q", "u"):
        try:
            arrays[key] = np.asarray(data[key], dtype=np.float64)
        except (TypeError, ValueError):
            return f"'trajectory.{key}' must be a (nested) list of numbers of one shape"
        if not np.all(np.isfinite(arrays[key])):
            return f"'trajectory.{key}' holds a value that is not a finite number (NaN or infinity)"
    t, q, u = arrays["t"], arrays["q"], arrays["u"]
    if t.ndim != 1 or t.size < 1:
        return f"'trajectory.t' must be a list of times [s], got shape {t.shape}"
    if q.shape != (t.size, size):
        return f"'trajectory.q' must be {t.size} configurations of {size} entries (one per time), got shape {q.shape}"
    if u.shape != (t.size, 2):
        return f"'trajectory.u' must be {t.size} pairs of inputs (one per time), got shape {u.shape}"
    if np.any(np.diff(t) < 0):
        at = int(np.argmax(np.diff(t) < 0))
        return f"'trajectory.t' must not decrease (it does after entry {at}: {t[at]:g} s, then {t[at + 1]:g} s)"
    return None


def _title(run: Run) -> str:
    """The scenario's name in words, for titles: ``forward_parking`` -> ``Forward parking``."""
    words = run.name.replace("_", " ").replace("-", " ").strip()
    return words[:1].upper() + words[1:]


def _figure(width: float = 6.4, height: float = 4.8) -> Figure:
    return Figure(figsize=(width, height), dpi=100)


def _time_panels(figure: Figure, t: np.ndarray, series: np.ndarray, labels: list[str]) -> list[Axes]:
    axes = figure.subplots(len(labels), 1, sharex=True, squeeze=False)[:, 0]
    for ax, values, label in zip(axes, series.T, labels):
        ax.plot(t, values, linewidth=1.5)
        ax.set_ylabel(label)
        ax.grid(True, linewidth=0.4, alpha=0.5)
    axes[-1].set_xlabel("t [s]")
    return list(axes)


DOTTED = {"experiment_forward": (1, 3), "experiment_parallel": (1, 2)}
"""The trials whose final configurations the paper's trajectory figure dots (Figs. 16 and 19); the
first trial's for any other run."""


def trajectory_figure(run: Run) -> Figure:
    """Figs. 3, 7, 11, 16, 19: the last trial, stroboscopic, and the ends of earlier trials dotted."""
    last = run.records[-1]
    dotted = [r for r in run.records[:-1] if r["trial"] in DOTTED.get(run.name, (1,))] or [run.records[0]]
    figure = _figure(6.4, 5.6)
    ax = figure.add_subplot()
    task = run.config.task
    draw_waypoints(ax, np.array([task.start, task.goal]), run.robot, ["start", "goal"])  # type: ignore[union-attr]
    draw_trial(ax, run.trajectory(last).q, run.robot, snapshots=10, label=f"trial {last['trial']}")
    for k, record in enumerate(dotted):
        draw_pose(
            ax,
            np.asarray(record["final_state"]),
            run.robot,
            FIRST if k == 0 else LATER,
            linestyle=":",
            label=f"end of trial {record['trial']}",
        )
    ends = ("end of trials " if len(dotted) > 1 else "end of trial ") + " and ".join(str(r["trial"]) for r in dotted)
    setup_workspace(ax, run.dimension, f"{_title(run)}: trajectory during trial {last['trial']} ({ends} dotted)")
    ax.legend(fontsize=8, loc="best")
    return figure


def coordinates_figure(run: Run) -> Figure:
    """Figs. 4, 8, 12: the generalized coordinates over the last trial (the steering limit dashed)."""
    last = run.records[-1]
    trajectory = run.trajectory(last)
    labels = run.kind.coordinate_labels(trajectory.q.shape[1])
    figure = _figure(6.4, 1.6 * len(labels) + 0.8)
    axes = _time_panels(figure, trajectory.t, trajectory.q, labels)
    limit = run.config.plant.steering_limit
    if limit is not None:
        for sign, name in ((1, "+φ_max"), (-1, "−φ_max")):
            axes[3].axhline(sign * limit, color="0.4", linestyle="--", linewidth=0.8, label=name)
            axes[3].annotate(
                f"{name} = {sign * np.degrees(limit):+.4g}°",
                (0.01, sign * limit),
                xycoords=("axes fraction", "data"),
                xytext=(0, -3 if sign > 0 else 3),
                textcoords="offset points",
                va="top" if sign > 0 else "bottom",
                fontsize=7,
                color="0.3",
            )
    figure.suptitle(f"{_title(run)}: generalized coordinates during trial {last['trial']}", fontsize=10)
    figure.tight_layout()
    return figure


def inputs_figure(run: Run) -> Figure:
    """Figs. 5, 9, 13, 17, 20: the inputs the controller commanded in the last trial."""
    last = run.records[-1]
    trajectory = run.trajectory(last)
    labels = list(run.kind.inputs)
    figure = _figure(6.4, 4.0)
    _time_panels(figure, trajectory.t, trajectory.u, labels)
    figure.suptitle(f"{_title(run)}: control inputs during trial {last['trial']}", fontsize=10)
    figure.tight_layout()
    return figure


def _error_series(run: Run, records: list[dict[str, Any]]) -> list[tuple[str, str, list[float], float | None]]:
    """(label, marker, values, tolerance) of each error the run's plant is judged by."""
    tolerance = run.config.learning.tolerance
    if run.has_pose:
        return [
            ("Cartesian [m]", "*", [r["cartesian_error"] for r in records], tolerance.cartesian),
            ("orientation [rad]", "o", [r["orientation_error"] for r in records], tolerance.orientation),
        ]
    return [("||z^d - z(T)||", "o", [r["error_norm"] for r in records], tolerance.error)]


def _log_axis(ax: Axes, xlabel: str, ylabel: str) -> None:
    ax.set_yscale("log")
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.grid(True, which="both", linewidth=0.4, alpha=0.5)


def errors_figure(run: Run) -> Figure:
    """Figs. 6, 10, 14, 18, 21: the final errors over the trials, the tolerances dashed."""
    figure = _figure()
    ax = figure.add_subplot()
    trials = [r["trial"] for r in run.records]
    series = _error_series(run, run.records)
    for (label, marker, values, _), color in zip(series, ("tab:blue", "tab:orange")):
        ax.plot(trials, values, marker=marker, color=color, label=label)
    _tolerance_lines(ax, [(label, tolerance) for label, _, _, tolerance in series])
    _log_axis(ax, "trial", "final error [m], [rad]" if run.has_pose else "final error")
    ax.set_xticks(trials)
    ax.set_title(f"{_title(run)}: final errors over the trials (tolerances dashed)", fontsize=10)
    ax.legend(fontsize=8)
    return figure


def _tolerance_lines(ax: Axes, tolerances: list[tuple[str, float | None]]) -> None:
    """One dashed line per distinct tolerance, its legend entry naming every error it bounds."""
    levels: dict[float, list[str]] = {}
    for label, tolerance in tolerances:
        if tolerance is not None:
            levels.setdefault(tolerance, []).append(label.split(" [")[0])
    for level, names in levels.items():
        ax.axhline(
            level, color="0.35", linestyle="--", linewidth=0.8, label=f"tolerance {level:g} ({', '.join(names)})"
        )


def _waypoint_name(index: int, count: int) -> str:
    return "home" if index == count else f"waypoint {index}"


def path_figure(run: Run, cycles: int = 5) -> Figure:
    """Fig. 23: the path over the first ``cycles`` cycles, each arrival numbered in order."""
    task = run.config.task
    waypoints = np.asarray(task.waypoints)  # type: ignore[union-attr]
    shown = [r for r in run.records if r["cycle"] <= cycles]
    figure = _figure(6.4, 5.6)
    ax = figure.add_subplot()
    draw_waypoints(ax, waypoints, run.robot, ["home", *(f"q{i}" for i in range(1, len(waypoints)))])
    colors = matplotlib.colormaps["viridis"]
    last_cycle = shown[-1]["cycle"]
    arrivals: dict[int, int] = {}  # waypoint index -> arrivals numbered there so far
    for number, record in enumerate(shown, start=1):
        shade = (record["cycle"] - 1) / max(last_cycle - 1, 1)
        color = colors(0.85 * shade)
        path = plane(run.trajectory(record).q, run.has_pose)
        ax.plot(*path.T, color=color, linewidth=1.0, label=f"cycle {record['cycle']}" if record["index"] == 1 else None)
        end = plane(np.asarray(record["final_state"]), run.has_pose)
        ax.plot(*end, ".", color=color, markersize=5)
        # Arrivals at one waypoint land within millimetres: their numbers go in a row beside it.
        k = arrivals.get(record["index"], 0)
        arrivals[record["index"]] = k + 1
        ax.annotate(
            str(number),
            (float(end[0]), float(end[1])),
            xytext=(8 + 11 * k, 8),
            textcoords="offset points",
            fontsize=8,
            color=color,
            arrowprops={"arrowstyle": "-", "color": color, "linewidth": 0.4, "alpha": 0.6},
        )
    setup_workspace(ax, run.dimension, f"{_title(run)}: path over cycles 1-{last_cycle}, arrivals numbered in order")
    ax.legend(fontsize=8, loc="best")
    return figure


def waypoint_errors_figure(run: Run) -> Figure:
    """Figs. 24-25: each waypoint's error over the cycles, one panel per error, log scale."""
    count = len(run.config.task.waypoints)  # type: ignore[union-attr]
    panels = len(_error_series(run, run.records))
    figure = _figure(6.4 * panels / 1.4, 4.4)
    axes = figure.subplots(1, panels, squeeze=False)[0]
    for index in range(1, count + 1):
        records = [r for r in run.records if r["index"] == index]
        for ax, (_, marker, values, _) in zip(axes, _error_series(run, records)):
            ax.plot([r["cycle"] for r in records], values, marker=marker, label=_waypoint_name(index, count))
    for ax, (label, _, _, tolerance) in zip(axes, _error_series(run, run.records)):
        ax.set_title(label.split(" [")[0] + " error", fontsize=9)
        _log_axis(ax, "cycle", label)
        if tolerance is not None:
            ax.axhline(tolerance, color="0.4", linestyle="--", linewidth=0.8)
        ax.set_xticks(sorted({r["cycle"] for r in run.records}))
    axes[0].legend(fontsize=8)
    figure.suptitle(f"{_title(run)}: errors at each waypoint over the cycles (tolerance dashed)", fontsize=10)
    figure.tight_layout()
    return figure


FIGURES = {
    "trajectory": trajectory_figure,
    "coordinates": coordinates_figure,
    "inputs": inputs_figure,
    "errors": errors_figure,
    "path": path_figure,
    "waypoint_errors": waypoint_errors_figure,
}


def write_plots(source: Run | Path | dict[str, Any], out: Path) -> list[Path]:
    """Write the run's figures as ``out/<scenario>_<figure>.png`` and return their paths."""
    run = source if isinstance(source, Run) else load_run(source)
    figures = [FIGURES[kind](run) for kind in (CYCLIC_FIGURES if run.cyclic else TRIAL_FIGURES)]
    out.mkdir(parents=True, exist_ok=True)
    paths = figure_paths(out, run.name, run.cyclic)
    for path, figure in zip(paths, figures):
        write_figure(path, figure)  # the one writer: a special file is refused, the umask kept
    return paths


def figure_paths(out: Path, name: str, cyclic: bool) -> list[Path]:
    """The files :func:`write_plots` writes for a run of ``name`` in ``out`` (checked before the run)."""
    return [out / f"{safe_name(name)}_{kind}.png" for kind in (CYCLIC_FIGURES if cyclic else TRIAL_FIGURES)]
