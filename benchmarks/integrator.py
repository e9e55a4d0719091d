"""Accuracy and speed of the compiled integrator against scipy's solve_ivp, in one run.

For each paper task, the first ILC trials are simulated with the compiled fixed-step integrator
at several step sizes and with ``solve_ivp(method="DOP853", rtol=1e-8)`` per trial, the
reference speed; both are compared with ``solve_ivp`` at rtol = atol = 1e-12 (restarted at every
steering-limit crossing). Times are medians over repeats; speed is reported as a ratio to the
reference measured in the same run.

    python benchmarks/integrator.py [--quick] [--out DIR]

writes ``integrator.json``, ``integrator.csv`` and ``integrator.md`` to ``DIR``.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

import ilc_steering  # noqa: F401  (registers the envs)
from ilc_steering.agents import ILCAgent
from ilc_steering.arguments import Parser
from ilc_steering.config import SteeringConfig, load_config
from ilc_steering.core.reference import trial as car_trial
from ilc_steering.engine.provenance import record_made
from ilc_steering.envs.scenario import Scenario
from ilc_steering.loop import run_trials
from ilc_steering.tables import markdown_table, median_seconds, write_results


@dataclass(frozen=True)
class Args:
    quick: bool = False
    """Fewer step sizes, trials and repeats: checks that the script runs (CI)."""
    repeats: int = 5
    """Timing repeats; the median is reported."""
    out: Path = Path("results/benchmarks")
    """Folder for the JSON, CSV and Markdown results."""


def ilc_actions(config: SteeringConfig, count: int) -> list[np.ndarray]:
    """The actions of the first ``count`` trials of eqs. 33-34 on ``config``."""
    env = gym.make("ilc_steering/ChainedSteering-v0", config=config)
    rollout = run_trials(env, ILCAgent(env.unwrapped.nominal_model), count)  # type: ignore[attr-defined]
    return [info["action"] for info in rollout.infos]


def main(args: Args) -> list[dict[str, object]]:
    tasks = (
        ["forward_parking", "parallel_parking"]
        if args.quick
        else ["forward_parking", "forward_parking_saturated", "parallel_parking"]
    )
    steps = [1 / 32] if args.quick else [1 / 8, 1 / 16, 1 / 32, 1 / 64]
    trials = 2 if args.quick else 4
    repeats = 1 if args.quick else args.repeats
    rows: list[dict[str, object]] = []
    for name in tasks:
        base = load_config(name)
        actions = ilc_actions(base, trials)
        scenario = Scenario.from_config(base)

        def reference(c: np.ndarray, rtol: float) -> np.ndarray:
            return car_trial(scenario.plant, scenario.profile, scenario.x_start, c, rtol)  # noqa: B023

        truth = [reference(c, 1e-12) for c in actions]
        ref_time = median_seconds(lambda: [reference(c, 1e-8) for c in actions], repeats) / trials  # noqa: B023
        ref_error = max(np.abs(reference(c, 1e-8) - x).max() for c, x in zip(actions, truth))
        rows.append(
            {
                "task": name,
                "method": "solve_ivp DOP853 rtol=1e-8",
                "max_step": None,
                "ms_per_trial": 1e3 * ref_time,
                "speedup": 1.0,
                "max_error": ref_error,
            }
        )
        for h in steps:
            config = type(base)(base.name, base.plant, base.task, base.learning, type(base.simulation)(h))
            sim = Scenario.from_config(config)
            sim.run(actions[0][None])  # compile outside the timing
            t = median_seconds(lambda: [sim.run(c[None]) for c in actions], repeats) / trials  # noqa: B023
            error = max(np.abs(sim.run(c[None]).final[0] - x).max() for c, x in zip(actions, truth))
            rows.append(
                {
                    "task": name,
                    "method": "compiled RK8 fixed step",
                    "max_step": h,
                    "ms_per_trial": 1e3 * t,
                    "speedup": ref_time / t,
                    "max_error": error,
                }
            )
    write(rows, args.out)
    return rows


def write(rows: list[dict[str, Any]], out: Path) -> None:
    table = [
        [
            str(r["task"]),
            str(r["method"]),
            "adaptive" if r["max_step"] is None else f"1/{round(1 / float(r['max_step']))}",
            f"{r['ms_per_trial']:.3f}",
            f"{r['speedup']:.1f}x",
            f"{r['max_error']:.1e}",
        ]
        for r in rows
    ]
    header = ["task", "method", "max step [s]", "ms / trial", "speed-up vs solve_ivp", "max final-state error"]
    markdown = markdown_table(header, table, [False, False, True, True, True, True])
    write_results(rows, out, "integrator", markdown)
    print(markdown)


def parse(argv: list[str] | None = None) -> Args:
    parser = Parser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer step sizes, trials and repeats (CI)")
    parser.add_argument("--repeats", type=int, default=Args.repeats)
    parser.add_argument("--out", type=Path, default=Args.out)
    ns = parser.parse_args(argv)
    return Args(quick=ns.quick, repeats=ns.repeats, out=ns.out)


if __name__ == "__main__":
    arguments = parse()
    main(arguments)
    record_made(arguments.out, __file__, sys.argv[1:])
