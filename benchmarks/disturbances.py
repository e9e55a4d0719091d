"""Robustness to non-repetitive disturbances: imperfect homing (``start_error``) and a plant that
changes from trial to trial (``parameter_jitter``), for eqs. 33-34 and ``newton_ilc``.

Every trial draws its own start and true geometry (seeded), the learner sees only the measured
final error, and the true errors are scored. With disturbances a trial may meet the tolerance by
chance, so a run counts as converged at trial ``k`` when trial ``k`` and every later trial of its
budget meet 0.5 mm / 0.5 mrad.

    python benchmarks/disturbances.py [--quick] [--out DIR]

writes ``disturbances.{csv,json,md}`` (committed in ``results/disturbances``).
"""

from __future__ import annotations

import dataclasses
import sys
from dataclasses import dataclass
from pathlib import Path
from statistics import median
from typing import Any

import gymnasium as gym

import ilc_steering  # noqa: F401  (registers the envs)
from ilc_steering.agents.base import LearnerContext
from ilc_steering.agents.registry import lookup
from ilc_steering.arguments import Parser
from ilc_steering.config import load_config
from ilc_steering.core.score import within_tolerance
from ilc_steering.engine.provenance import record_made
from ilc_steering.loop import run_trials
from ilc_steering.output import check_output_dir
from ilc_steering.tables import markdown_table, write_results

__all__ = ["LEVELS", "Args", "main"]

LEVELS = {"start_error": (1e-5, 1e-4, 1e-3), "parameter_jitter": (1e-3, 1e-2, 5e-2)}
"""The sigmas tried: of the start configuration [m, rad per coordinate], and relative of the geometry."""
LEARNERS = ("ilc_paper", "newton_ilc")
"""Ids of the learner registry (:mod:`ilc_steering.agents.registry`)."""


@dataclass(frozen=True)
class Args:
    quick: bool = False
    """One level of each, two seeds: checks that the script runs (CI)."""
    out: Path = Path("results/disturbances")
    """Where the tables go."""
    task: str = "forward_parking"
    """The task (a packaged name or a YAML path)."""
    seeds: tuple[int, ...] = tuple(range(10))
    """Seeds of the disturbances."""
    trials: int = 15
    """Budget of every run [trials]."""


def settled(infos: list[dict[str, Any]], tolerance: Any) -> int | None:
    """The first trial from which every trial meets the tolerance, or ``None``."""
    ok = [within_tolerance(tolerance, info) for info in infos]
    for k in range(len(ok)):
        if all(ok[k:]):
            return k + 1
    return None


def run(task: str, learner: str, kind: str, sigma: float, seed: int, trials: int) -> tuple[int | None, float]:
    """Trials until the run settles within tolerance, and the median true Cartesian error [m] of its
    last five trials."""
    config = load_config(task)
    disturbance: dict[str, Any] = {kind: sigma}
    env = gym.make("ilc_steering/ChainedSteering-v0", config=config, **disturbance)
    learning = config.learning
    context = LearnerContext.from_env(env, seed=seed)
    rollout = run_trials(env, lookup(learner).make(context, trials), trials, seed=seed)
    late = median(float(info["true_cartesian_error"]) for info in rollout.infos[-5:])
    return settled(rollout.infos, learning.tolerance), late


def main(args: Args) -> list[dict[str, Any]]:
    out = check_output_dir(args.out, "--out")
    seeds = args.seeds[:2] if args.quick else args.seeds
    trials = 6 if args.quick else args.trials
    rows = []
    for kind, levels in LEVELS.items():
        for sigma in levels[1:2] if args.quick else levels:
            for learner in LEARNERS:
                results = [run(args.task, learner, kind, sigma, seed, trials) for seed in seeds]
                counts = [count for count, _ in results]
                got = [c for c in counts if c is not None]
                rows.append(
                    {
                        "disturbance": kind,
                        "sigma": sigma,
                        "learner": learner,
                        "converged": len(got),
                        "seeds": len(seeds),
                        "median_trials": median(got) if got else None,
                        "late_error_m": median(late for _, late in results),
                        "counts": counts,
                    }
                )
                print(f"{kind} {sigma:g} {learner}: {counts}", flush=True)
    table: list[list[str]] = [
        [
            str(r["disturbance"]),
            f"{r['sigma']:g}",
            str(r["learner"]),
            f"{r['converged']}/{r['seeds']}",
            "-" if r["median_trials"] is None else f"{r['median_trials']:g}",
            f"{r['late_error_m']:.1e}",
        ]
        for r in rows
    ]
    header = ["disturbance", "sigma", "learner", "settled within 0.5 mm / 0.5 mrad", "median trials", "late error [m]"]
    markdown = (
        f"{args.task}, {len(seeds)} seeds, {trials} trials; converged: from some trial on, every trial within "
        "0.5 mm / 0.5 mrad (true errors); late error: the median over seeds of the median true Cartesian error "
        "of the last five trials.\n\n" + markdown_table(header, table, [False, True, False, True, True, True])
    )
    write_results(
        rows, out, "disturbances", markdown, {"args": {k: str(v) for k, v in dataclasses.asdict(args).items()}}
    )
    print(markdown)
    return rows


def parse(argv: list[str] | None = None) -> Args:
    parser = Parser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="one level of each, two seeds")
    parser.add_argument("--out", type=Path, default=Args.out)
    parser.add_argument("--task", default=Args.task)
    return Args(**vars(parser.parse_args(argv)))


if __name__ == "__main__":
    arguments = parse()
    main(arguments)
    record_made(arguments.out, __file__, sys.argv[1:])
