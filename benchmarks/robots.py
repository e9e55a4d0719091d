"""Every robot's simulator against the car's, in one run: simulated seconds per wall-clock second.

For each packaged robot (the car of forward parking, the unicycle, the car towing a trailer and
section 5's lab robot), on the same kind of trials (the nominal solution with every coefficient
perturbed by 5 %, seeded):

- the vector env's ``step`` at ``N`` trials (a plant per trial: one compiled call), in trials per
  second times the task's duration ``T``: simulated seconds per second, and its ratio to the car's,
  the robots timed in alternation, repeat by repeat;
- ``env.step`` through ``gym.make`` (one trial per call), the median of ``repeats`` repeats, beside
  one ``solve_ivp`` trial (DOP853, rtol = atol = 1e-8, on the robot's own reference field) timed
  in the same run;
- with ``--first-run``, ``ilc-steering run CONFIG`` in a fresh process with an empty numba cache
  (the first run of a fresh install, compile included) for every packaged config.

    PYTHONPATH=. python benchmarks/robots.py [--quick] [--first-run] [--out DIR]

writes ``robots.json``, ``robots.csv`` and ``robots.md`` to ``DIR`` (committed in ``results/benchmarks``).
From a checkout, put it first on the path (``PYTHONPATH=.``): a script's own folder heads
``sys.path``, so without it the script times whichever ``ilc_steering`` the interpreter has installed.
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time
from dataclasses import asdict, dataclass
from pathlib import Path
from statistics import median
from typing import Any

import gymnasium as gym
import numpy as np
from scipy.integrate import solve_ivp

import ilc_steering  # noqa: F401  (registers the envs)
from ilc_steering.arguments import Parser
from ilc_steering.config import load_config, packaged_configs
from ilc_steering.engine.provenance import record_made
from ilc_steering.envs.scenario import Scenario
from ilc_steering.envs.steering_vector_env import ChainedSteeringVectorEnv
from ilc_steering.output import check_output_dir
from ilc_steering.tables import markdown_table, median_seconds, write_results

__all__ = ["Args", "main"]

ROBOTS = {
    "car": "forward_parking",
    "unicycle": "unicycle_parking",
    "car_trailer": "trailer_bay",
    "lab": "experiment_forward",
}
"""Robot -> the packaged task it is timed on."""
TARGETS = {"car": 1.0, "unicycle": 1.0, "car_trailer": 1 / 3, "lab": 0.1}
"""Issue 25's floor of each robot's simulated seconds per second, as a share of the car's."""
STEP_TARGETS_MS = {"car": 0.1, "unicycle": 0.1, "car_trailer": 0.2}
"""Issue 25's ceiling of ``env.step`` through ``gym.make`` [ms per trial]."""


@dataclass(frozen=True)
class Args:
    quick: bool = False
    """A small batch and few repeats: checks that the script runs (CI)."""
    size: int = 2048
    """Trials per vector-env step."""
    repeats: int = 5
    """Timing repeats; medians are reported."""
    steps: int = 200
    """``env.step`` calls per repeat (the lab robot: a tenth)."""
    first_run: bool = False
    """Also time the first run of every packaged config with an empty numba cache (minutes)."""
    seed: int = 0
    out: Path = Path("results/benchmarks")
    """Folder for the JSON, CSV and Markdown results."""


def actions(name: str, count: int, seed: int) -> np.ndarray:
    scenario = Scenario.from_config(load_config(name))
    c0 = scenario.nominals[0].solve()
    rng = np.random.default_rng(seed)
    return (c0 * (1 + 0.05 * rng.standard_normal((count, c0.size)))).astype(np.float32)


def vector_seconds(name: str, c: np.ndarray) -> Any:
    """A function that runs one vector-env step of ``len(c)`` trials."""
    env = ChainedSteeringVectorEnv(len(c), config=name)
    env.reset(seed=0)
    env.step(c)  # compiled, or loaded from the cache

    def step() -> None:
        env.step(c)

    return step


def step_ms(name: str, c: np.ndarray, steps: int, repeats: int) -> float:
    env = gym.make("ilc_steering/ChainedSteering-v0", config=name)
    env.reset(seed=0)
    env.step(c[0])
    return 1e3 * median_seconds(lambda: [env.step(c[i % len(c)]) for i in range(steps)], repeats) / steps


def solve_ivp_ms(name: str, c: np.ndarray, repeats: int) -> float:
    scenario = Scenario.from_config(load_config(name))
    profile, plant = scenario.profile, scenario.plant
    if plant.state_dim == 12:  # the lab robot's reference restarts at every event: not a per-trial solve
        return float("nan")

    def one() -> None:
        field, _, _ = plant.reference_field(profile, c[0].astype(np.float64))
        x = scenario.x_start
        for t0, t1 in zip(profile.breakpoints[:-1], profile.breakpoints[1:]):
            x = solve_ivp(field, (t0, t1), x, method="DOP853", rtol=1e-8, atol=1e-8).y[:, -1]

    return 1e3 * median_seconds(one, repeats)


def first_run_s(name: str) -> float:
    with tempfile.TemporaryDirectory() as cache:
        env = {**os.environ, "NUMBA_CACHE_DIR": cache}
        start = time.perf_counter()
        subprocess.run([sys.executable, "-m", "ilc_steering", "run", name], env=env, capture_output=True, check=False)
        return time.perf_counter() - start


def main(args: Args) -> list[dict[str, Any]]:
    if args.quick:
        args = Args(**{**asdict(args), "quick": True, "size": 128, "repeats": 2, "steps": 20})
    out = check_output_dir(args.out, "--out")
    durations = {
        robot: float(Scenario.from_config(load_config(name)).profile.breakpoints[-1]) for robot, name in ROBOTS.items()
    }
    batches = {robot: actions(name, args.size, args.seed) for robot, name in ROBOTS.items()}
    steppers = {robot: vector_seconds(name, batches[robot]) for robot, name in ROBOTS.items()}
    samples: dict[str, list[float]] = {robot: [] for robot in ROBOTS}
    for _ in range(args.repeats):  # in alternation: a slow spell of the machine hits every robot
        for robot, step in steppers.items():
            start = time.perf_counter()
            step()
            samples[robot].append(time.perf_counter() - start)
    simulated = {robot: args.size * durations[robot] / median(samples[robot]) for robot in ROBOTS}
    rows = []
    for robot, name in ROBOTS.items():
        steps = max(2, args.steps // 10) if robot == "lab" else args.steps
        ms = step_ms(name, batches[robot], steps, args.repeats)
        reference = solve_ivp_ms(name, batches[robot], args.repeats)
        rows.append(
            {
                "robot": robot,
                "task": name,
                "T_s": durations[robot],
                "N": args.size,
                "trials_per_s": args.size / median(samples[robot]),
                "simulated_s_per_s": simulated[robot],
                "share_of_car": simulated[robot] / simulated["car"],
                "target_share": TARGETS[robot],
                "step_ms": ms,
                "target_step_ms": STEP_TARGETS_MS.get(robot, float("nan")),
                "solve_ivp_ms": reference,
                "step_speedup_over_solve_ivp": reference / ms,
            }
        )
    extra: dict[str, Any] = {"args": {k: str(v) for k, v in asdict(args).items()}}
    if args.first_run:
        extra["first_run_s"] = {name: first_run_s(name) for name in packaged_configs()}
    text = report(rows, extra)
    write_results(rows, out, "robots", text, extra)
    print(text)
    return rows


def report(rows: list[dict[str, Any]], extra: dict[str, Any]) -> str:
    def met(ok: bool) -> str:
        return "yes" if ok else "**no**"

    table = [
        [
            r["robot"],
            r["task"],
            f"{r['simulated_s_per_s']:,.0f}",
            f"{r['share_of_car']:.2f}",
            f"{r['target_share']:.2f} ({met(r['share_of_car'] >= r['target_share'])})",
            f"{r['step_ms']:.3f}",
            "-"
            if r["target_step_ms"] != r["target_step_ms"]
            else f"{r['target_step_ms']} ({met(r['step_ms'] <= r['target_step_ms'])})",
            "-" if r["solve_ivp_ms"] != r["solve_ivp_ms"] else f"{r['step_speedup_over_solve_ivp']:.0f}x",
        ]
        for r in rows
    ]
    header = [
        "robot",
        "task",
        f"simulated s / s (N = {rows[0]['N']})",
        "share of the car's",
        "floor (met)",
        "env.step via gym.make [ms]",
        "ceiling (met)",
        "env.step over solve_ivp",
    ]
    text = markdown_table(header, table, [False, False, True, True, True, True, True, True])
    text += "\nMedians of the repeats; the vector env's steps timed in alternation across the robots.\n"
    if "first_run_s" in extra:
        firsts = extra["first_run_s"]
        text += "\nFirst run with an empty numba cache (`ilc-steering run CONFIG`, the whole command) [s]: "
        text += ", ".join(f"{name} {seconds:.1f}" for name, seconds in firsts.items()) + ".\n"
    return text


def parse(argv: list[str] | None = None) -> Args:
    parser = Parser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="a small batch and few repeats (CI)")
    parser.add_argument("--size", type=int, default=Args.size, help="trials per vector-env step")
    parser.add_argument("--repeats", type=int, default=Args.repeats, help="timing repeats; medians are reported")
    parser.add_argument("--first-run", action="store_true", help="time every packaged config's first run (minutes)")
    parser.add_argument("--out", type=Path, default=Args.out, help="folder for the results")
    ns = parser.parse_args(argv)
    return Args(quick=ns.quick, size=ns.size, repeats=ns.repeats, first_run=ns.first_run, out=ns.out)


if __name__ == "__main__":
    arguments = parse()
    main(arguments)
    record_made(arguments.out, __file__, sys.argv[1:])
