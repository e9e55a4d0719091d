"""Section 7's cost-optimal learning, before and after: the plain eqs. 33-34 against the same law
with ``learning.cost``, on tasks given spare ``v2`` coefficients (``v2_terms > n - 1``).

For each task and cost, both learners run on the true (perturbed) plant; the table gives the
trials to tolerance and the cost of the last trial's *true* motion for each, and a figure puts
the two last trials side by side. ``steering_margin`` on simulation 2 reports the peak ``|phi|``
against the 45-degree stop instead of a path.

    python benchmarks/costs.py [--quick] [--out DIR]

writes ``costs.{csv,json,md}`` and ``costs_<task>_<cost>.png`` (committed in ``results/costs``).
"""

from __future__ import annotations

import dataclasses
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

import ilc_steering  # noqa: F401  (registers the envs)
from ilc_steering.agents.costs import NullSpaceCost
from ilc_steering.arguments import Parser
from ilc_steering.config import SteeringConfig, TaskConfig, load_config
from ilc_steering.engine.provenance import record_made
from ilc_steering.envs.rendering import draw_trial, draw_waypoints, setup_workspace
from ilc_steering.envs.scenario import Scenario
from ilc_steering.output import check_output_dir
from ilc_steering.runner import RunResult, run_ilc
from ilc_steering.tables import markdown_table, write_results

__all__ = ["CASES", "Args", "main"]

CASES: tuple[tuple[str, int, str], ...] = (
    ("forward_parking", 5, "path_length"),
    ("forward_parking", 5, "curvature"),
    ("unicycle_parking", 4, "path_length"),
    ("unicycle_parking", 4, "curvature"),
    ("trailer_bay", 6, "path_length"),
    ("trailer_bay", 6, "curvature"),
    ("forward_parking_saturated", 5, "steering_margin"),
)
"""(task, v2_terms, cost) of every row."""


@dataclass(frozen=True)
class Args:
    quick: bool = False
    """The first case only, four trials: checks that the script runs (CI)."""
    out: Path = Path("results/costs")
    """Where the tables and figures go."""
    trials: int = 12
    """Budget of every run [trials]."""


def with_terms(name: str, terms: int, cost: str) -> SteeringConfig:
    """The packaged one-trial task ``name`` with ``terms`` coefficients of ``v2`` and ``learning.cost``."""
    config = load_config(name)
    assert isinstance(config.task, TaskConfig)
    task = dataclasses.replace(config.task, v2_terms=terms, action_bound=None)
    learning = dataclasses.replace(config.learning, cost=cost)  # type: ignore[arg-type]  # checked on loading
    return dataclasses.replace(config, task=task, learning=learning)


def summary(result: RunResult, term: NullSpaceCost) -> dict[str, Any]:
    last = result.trials[-1]
    assert last.trajectory is not None
    q, t = last.trajectory.q, last.trajectory.t
    peak = float(np.max(np.abs(q[:, 3]))) if q.shape[1] > 3 else float("nan")
    return {
        "trials": result.converged_at,
        "cost": float(term.of_motion(q[None], t)[0]),
        "error_m": float(last.cartesian_error or 0.0),
        "peak_phi_deg": float(np.degrees(peak)),
    }


def figure(name: str, cost: str, plain: RunResult, costly: RunResult, rows: dict[str, Any]) -> Any:
    from matplotlib.figure import Figure

    config = plain.config
    robot = config.plant.nominal_map()
    fig = Figure(figsize=(11.0, 4.8), dpi=100)
    axes = fig.subplots(1, 2)
    task: Any = config.task
    for ax, result, label in ((axes[0], plain, "plain eqs. 33-34"), (axes[1], costly, "with the cost")):
        last = result.trials[-1]
        assert last.trajectory is not None
        draw_waypoints(ax, np.array([task.start, task.goal]), robot, ["start", "goal"])
        draw_trial(ax, last.trajectory.q, robot, snapshots=8, label=f"trial {last.trial}")
        key = "plain" if result is plain else "cost"
        setup_workspace(ax, None, f"{label}: {cost} = {rows[key + '_cost']:.4g}")
        ax.legend(fontsize=8, loc="best")
    for ax in axes:  # one scale for both panels, each with equal axes
        ax.update_datalim(np.concatenate([a.dataLim.get_points() for a in axes]))
        ax.autoscale_view()
    fig.suptitle(f"{name}, v2_terms {task.v2_terms}: the last trial of each learner", fontsize=10)
    fig.tight_layout()
    return fig


def main(args: Args) -> list[dict[str, Any]]:
    out = check_output_dir(args.out, "--out")
    cases = CASES[:1] if args.quick else CASES
    trials = 4 if args.quick else args.trials
    rows = []
    for name, terms, cost in cases:
        costly_config = with_terms(name, terms, cost)
        plain_config = with_terms(name, terms, "none")
        term = NullSpaceCost(Scenario.from_config(costly_config).nominal, cost)
        plain = run_ilc(plain_config, trials=trials, trajectories=True)
        costly = run_ilc(costly_config, trials=trials, trajectories=True)
        before, after = summary(plain, term), summary(costly, term)
        row: dict[str, Any] = {"task": name, "v2_terms": terms, "cost": cost}
        row.update({f"plain_{k}": v for k, v in before.items()})
        row.update({f"cost_{k}": v for k, v in after.items()})
        rows.append(row)
        print(row, flush=True)
        if cost != "steering_margin":
            figure(name, cost, plain, costly, row).savefig(out / f"costs_{name}_{cost}.png")

    def count(value: Any) -> str:
        return f"> {trials}" if value is None else str(value)

    table = [
        [
            str(r["task"]),
            str(r["v2_terms"]),
            str(r["cost"]),
            count(r["plain_trials"]),
            count(r["cost_trials"]),
            f"{r['plain_cost']:.4g}",
            f"{r['cost_cost']:.4g}",
            f"{100 * (r['cost_cost'] / r['plain_cost'] - 1):+.1f} %" if r["plain_cost"] else "-",
            "-"
            if np.isnan(r["plain_peak_phi_deg"])
            else f"{r['plain_peak_phi_deg']:.1f} / {r['cost_peak_phi_deg']:.1f}",
        ]
        for r in rows
    ]
    header = [
        "task",
        "v2_terms",
        "cost",
        "trials, plain",
        "trials, with cost",
        "cost of the last trial, plain",
        "with cost",
        "change",
        "peak abs(phi) [deg], plain / with cost",
    ]
    markdown = (
        f"Trials to 0.5 mm / 0.5 mrad within {trials}, and the cost of the last trial's true motion (path_length "
        "[m], curvature: the integral of the squared curvature along the path [1/m], steering_margin [rad^2 s]).\n\n"
        + markdown_table(header, table, [False, True, False, True, True, True, True, True, True])
    )
    write_results(rows, out, "costs", markdown, {"args": {k: str(v) for k, v in dataclasses.asdict(args).items()}})
    print(markdown)
    return rows


def parse(argv: list[str] | None = None) -> Args:
    parser = Parser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="the first case only, four trials")
    parser.add_argument("--out", type=Path, default=Args.out)
    parser.add_argument("--trials", type=int, default=Args.trials)
    return Args(**vars(parser.parse_args(argv)))


if __name__ == "__main__":
    arguments = parse()
    main(arguments)
    record_made(arguments.out, __file__, sys.argv[1:])
