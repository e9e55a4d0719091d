"""A run on the console: its header, a row per trial (or cycle) as it finishes, the verdict (held,
relapses, the plant's floor), and the run's JSON and figures where asked. ``run`` and
``reproduce`` print through it. Before the run, :func:`check_counts` and :func:`check_outputs`
refuse what could not end well: a hold the trials could never reach, an output that cannot be
written or that names one of the run's inputs (its config, its robot program's files)."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from ilc_steering.config import MAX_TRIALS, SteeringConfig
from ilc_steering.config.loading import ConfigSource
from ilc_steering.core.robots.process import ProcessPlantConfig
from ilc_steering.core.robots.process_limits import WRAPPED
from ilc_steering.core.scatter import FLOOR, HOLD
from ilc_steering.errors import BadInput
from ilc_steering.output import check_output_dir, check_output_file, write_json
from ilc_steering.readers import check_apart
from ilc_steering.runner import (
    DEFAULT_LEARNER,
    CycleRecord,
    CyclicRunResult,
    RunResult,
    TrialRecord,
    learner_spec,
    run_cyclic_ilc,
    run_goals,
    run_ilc,
)

__all__ = ["check_counts", "check_outputs", "learn", "learn_goals", "print_header", "print_row", "save", "save_goals"]


def check_counts(trials: int | None, hold: int | None, configs: list[SteeringConfig]) -> int:
    """``--trials`` and ``--hold`` checked against each other and the configs; the hold to use. A run
    whose trials could never hold within the tolerance as long as its hold asks (the default's
    included: ``--trials 2`` against a hold of 3) is refused before it runs."""
    for option, value in (("--trials", trials), ("--hold", hold)):
        if value is not None and not 1 <= value <= MAX_TRIALS:
            raise BadInput(f"{option} must be a whole number in [1, {MAX_TRIALS}], got {value}")
    used = HOLD if hold is None else hold
    for config in configs:
        unit = "cycles" if config.is_cyclic else "trials"
        count = config.learning.trials if trials is None else trials
        budget = f"--trials {count}" if trials is not None else f"the {count} {unit} of {config.name} (learning.trials)"
        if used > count:
            given = f"--hold {hold}" if hold is not None else f"the default --hold {HOLD}"
            raise BadInput(
                f"{given} is more than {budget}: the run could never hold {used} {unit} within the tolerance; "
                f"give --hold at most {count}, or more --trials"
            )
    return used


def check_outputs(
    json_path: Path | None,
    plots: Path | None,
    configs: list[SteeringConfig],
    sources: list[ConfigSource],
    files: list[Path] | None = None,
) -> None:
    """Check, before the first trial, that the run's JSON and figures can be written and name none of
    its inputs: the config files, the files a robot program's command names, and ``files``."""
    outputs = [] if json_path is None else [("--json", json_path)]
    if plots is not None:
        from ilc_steering.plots import figure_paths

        outputs += [("--plots", path) for path in figure_paths(plots, configs[0].name, configs[0].is_cyclic)]
    inputs = [source.path for source in sources if source.path is not None] + (files or [])
    for config in configs:
        plant = config.plant
        if isinstance(plant, ProcessPlantConfig):
            named = [Path(str(plant.folder), word) for word in plant.command]
            inputs += [path for path in named if os.path.isfile(path)]
    check_apart(outputs, inputs)
    if json_path is not None:
        check_output_file(json_path, "--json")
    if plots is not None:
        check_output_dir(plots, "--plots")


def _columns(config: SteeringConfig) -> list[str]:
    names = ["cartesian [m]", "orientation [rad]"] if config.plant.kind.has_pose else ["error norm"]
    if not config.is_cyclic:
        return names
    return [
        f"wp{l} {name}"
        for l in range(1, len(config.task.waypoints) + 1)  # type: ignore[union-attr]
        for name in names
    ]


def print_header(config: SteeringConfig, count: int) -> None:
    tol = config.learning.tolerance
    unit = "cycles" if config.is_cyclic else "trials"
    bound = (
        f"{tol.cartesian} m / {tol.orientation} rad" if config.plant.kind.has_pose else f"{tol.error} on ||z^d - z||"
    )
    print(f"{config.name}: {count} {unit}, tolerance {bound}{' at every waypoint' if config.is_cyclic else ''}")
    print(f"{unit[:-1]:>5}  " + "  ".join(f"{c:>17}" for c in _columns(config)))


def _values(record: TrialRecord) -> list[float]:
    if record.cartesian_error is not None and record.orientation_error is not None:
        return [record.cartesian_error, record.orientation_error]
    return [record.error_norm]


def print_row(record: TrialRecord | CycleRecord) -> None:
    if isinstance(record, CycleRecord):
        index, values = record.cycle, [v for w in record.waypoints for v in _values(w)]
        left = any(w.left_chart for w in record.waypoints)
        clipped = any(w.clipped for w in record.waypoints)
    else:
        index, values, left, clipped = record.trial, _values(record), record.left_chart, record.clipped
    note = "  left the chart (the robot halted where eqs. 4-5 break down)" if left else ""
    note += "  action clipped to the box (task.action_bound)" if clipped else ""
    wrapped = record.plant.get(WRAPPED) if isinstance(record, TrialRecord) and record.plant else None
    if isinstance(wrapped, dict):  # the robot reported a heading unwrapped (whole turns): read wrapped, said so
        note += "  " + ", ".join(f"{name} {v[0]:.6g} rad read as {v[1]:.6g}" for name, v in wrapped.items())
    print(f"{index:>5}  " + "  ".join(f"{v:>17.3e}" for v in values) + note, flush=True)


def _bounds(below: dict[str, list[float]], index: int) -> str:
    units = {"cartesian": " m", "orientation": " rad", "error": ""}
    return " / ".join(f"{values[index]:.2g}{units[name]}" for name, values in below.items())


def print_verdict(result: RunResult | CyclicRunResult, unit: str, done: int) -> None:
    """The lines that end a run: converged or not, its relapses, and a tolerance below the plant's scatter."""
    verdict = result.verdict
    spans = [f"{unit[:-1]} {first}" if first == last else f"{unit} {first}-{last}" for first, last in verdict.relapses]
    if spans:  # one line, however many: "...at trial 5, out again at trial 6; at trials 9-13, ... 14"
        print(
            "relapsed: within the tolerance "
            + "; ".join(
                f"at {span}, out again at {unit[:-1]} {last + 1}" for span, (_, last) in zip(spans, verdict.relapses)
            )
        )
    if verdict.below and verdict.scatter is not None:
        sigma = ", ".join(f"{k} {v:.2g}" for k, v in verdict.scatter.items() if k != "dof")
        print(
            f"tolerance {_bounds(verdict.below, 0)} is below this plant's repeatability, about "
            f"{_bounds(verdict.below, 1)} ({FLOOR:g} times its scatter per coordinate, estimated from the trials: "
            f"{sigma})" + (": converged to the plant's floor" if verdict.floor else "")
        )
    if verdict.converged_at is not None:
        print(f"converged at {unit[:-1]} {verdict.converged_at} (held for the last {verdict.held} {unit})")
    elif not verdict.floor:
        held = f" (the last {verdict.held} within the tolerance, {verdict.hold} needed)" if verdict.held else ""
        print(f"not converged within {done} {unit}{held}")


def learn(
    config: SteeringConfig,
    count: int | None,
    trajectories: bool,
    learner: str = DEFAULT_LEARNER,
    hold: int = HOLD,
    tensorboard: Path | None = None,
) -> RunResult | CyclicRunResult:
    """Run ``learner`` on the config with a table row per trial (or cycle) as it finishes (and its
    TensorBoard event files under ``tensorboard``, where given)."""
    if config.is_cyclic and learner != DEFAULT_LEARNER:
        raise BadInput(
            f"--learner {learner}: a cyclic config runs the paper's cyclic law of eqs. 39-40 "
            f"(the default, --learner {DEFAULT_LEARNER})"
        )
    if not config.is_cyclic:
        learner_spec(learner)  # an unknown or unimportable learner is refused before the header
    print_header(config, config.learning.trials if count is None else count)
    if config.is_cyclic:
        result: RunResult | CyclicRunResult = run_cyclic_ilc(
            config, count, on_cycle=print_row, trajectories=trajectories, hold=hold, tensorboard=tensorboard
        )
    else:
        result = run_ilc(
            config,
            count,
            on_trial=print_row,
            trajectories=trajectories,
            learner=learner,
            hold=hold,
            tensorboard=tensorboard,
        )
    unit = "cycles" if config.is_cyclic else "trials"
    done = len(result.cycles) if isinstance(result, CyclicRunResult) else len(result.trials)
    records = result.trials if isinstance(result, RunResult) else [w for c in result.cycles for w in c.waypoints]
    clipped = sum(r.clipped for r in records)
    if clipped:
        print(f"{clipped} of {len(records)} actions were clipped to the action box (task.action_bound)")
    print_verdict(result, unit, done)
    return result


def learn_goals(
    configs: list[SteeringConfig],
    count: int | None,
    learner: str,
    hold: int,
    carry: bool,
    tensorboard: Path | None = None,
) -> list[RunResult]:
    """Run ``learner`` on each goal in turn (as :func:`learn`, a table each), carrying what it learned
    of the robot from goal to goal with ``carry``; then one line of trials to the tolerance: the
    first goal's, and the later goals' median."""
    cyclic = [config.name for config in configs if config.is_cyclic]
    if cyclic:
        raise BadInput(f"a list of goals takes one-trial configs; {cyclic[0]} is cyclic")
    learner_spec(learner)

    def started(k: int) -> None:
        config = configs[k]
        print(f"goal {k + 1} of {len(configs)}:", end=" ")
        print_header(config, config.learning.trials if count is None else count)

    def ended(k: int, result: RunResult) -> None:
        print_verdict(result, "trials", len(result.trials))
        if k + 1 < len(configs):
            started(k + 1)

    started(0)
    results = run_goals(
        configs, count, learner, hold=hold, carry=carry, on_goal=ended, on_trial=print_row, tensorboard=tensorboard
    )
    print(goals_line(results, carry))
    return results


def goals_line(results: list[RunResult], carry: bool) -> str:
    """``goals: 3 of 3 converged; trials to the tolerance: first goal 4, goals 2-3 median 2 (carried)``."""
    reached = [_first_within(r) for r in results]
    converged = sum(r.converged_at is not None for r in results)
    first = "not reached" if reached[0] is None else str(reached[0])
    line = f"goals: {converged} of {len(results)} converged; trials to the tolerance: first goal {first}"
    later = sorted(k for k in reached[1:] if k is not None)
    if len(results) > 1:
        missed = len(results) - 1 - len(later)
        if len(results) == 2:
            line += f", goal 2 {later[0] if later else 'not reached'}"
        else:
            median = "none reached" if not later else f"median {float(np.median(later)):g}"
            line += f", goals 2-{len(results)} {median}" + (f" ({missed} not reached)" if missed else "")
    return line + (" (learning carried from goal to goal)" if carry else " (each goal from scratch)")


def _first_within(result: RunResult) -> int | None:
    """The first trial within the tolerance, if any (``goals_line``'s trials to the tolerance)."""
    verdict = result.verdict
    if verdict.relapses:
        return verdict.relapses[0][0]
    return len(result.trials) - verdict.held + 1 if verdict.held else None


def save_goals(results: list[RunResult], json_path: Path | None) -> None:
    """Write the goals' runs as one JSON (``{"kind": "goals", "goals": [run, ...]}``), where asked."""
    if json_path is not None:
        write_json(json_path, {"kind": "goals", "goals": [r.to_json() for r in results]})
        print(f"wrote {json_path}")


def save(result: RunResult | CyclicRunResult, json_path: Path | None, plots: Path | None) -> None:
    """Write the run's JSON and its figures, where asked (the paths were checked before the run)."""
    data = result.to_json()
    if json_path is not None:
        write_json(json_path, data)
        print(f"wrote {json_path}")
    if plots is not None:
        from ilc_steering.plots import write_plots

        for path in write_plots(data, plots):
            print(f"wrote {path}")
