"""``newton_ilc`` against eqs. 33-34 and ``least_squares``: trials to 0.5 mm / 0.5 mrad, and its cost.

Three experiments, every learner counted by the same rule (the first trial whose *true* errors
meet the config's tolerance, every trial counted, the first one included):

- **in the family**: the packaged tasks as they are (wheelbase and wheel radius 10 % off, or the
  chained form's gains), measured exactly; with the ablations of the learner (identification
  alone, secant alone, neither: a Newton step on the nominal family with an offset);
- **outside it**: forward parking with and without the 45-degree limit, each unmodeled servo
  perturbation switched on (a 0.02 rad misaligned wheel, a 0.05 s steering servo, a 0.1 s drive);
- **measured with noise**: the car tasks with ``measurement_noise`` of 2e-4 per coordinate (the
  noisy config's), over seeds.

It also times the learner's update (its simulations included) and draws the error against the
trial on simulations 1-3.

    python benchmarks/newton_ilc.py [--quick] [--out DIR]

writes ``newton_ilc.{csv,json,md}`` and ``newton_ilc_errors.png`` (committed in ``results/newton_ilc``).
"""

from __future__ import annotations

import dataclasses
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from statistics import median
from typing import Any

import gymnasium as gym
import numpy as np

import ilc_steering  # noqa: F401  (registers the envs)
from ilc_steering.agents.base import Learner, LearnerContext, update_times
from ilc_steering.agents.newton_ilc import NewtonILC
from ilc_steering.agents.registry import lookup
from ilc_steering.arguments import Parser
from ilc_steering.config import SteeringConfig, load_config
from ilc_steering.core.score import within_tolerance
from ilc_steering.engine.provenance import record_made
from ilc_steering.loop import run_trials
from ilc_steering.output import check_output_dir
from ilc_steering.tables import markdown_table, write_results

__all__ = ["LEARNERS", "PERTURBATIONS", "Args", "main"]

TASKS = ("forward_parking", "forward_parking_saturated", "parallel_parking", "chained_perturbed")
PERTURBATIONS = {"steering_offset": 0.02, "steering_lag": 0.05, "speed_lag": 0.1}
"""The unmodeled perturbations switched on one at a time [rad, s, s]."""


def _variant(identify: bool, secant: bool) -> Callable[[LearnerContext], Learner]:
    def make(context: LearnerContext) -> Learner:
        space = context.action_space
        low, high = np.asarray(space.low, np.float64), np.asarray(space.high, np.float64)
        return NewtonILC(context.model, context.first_action(), low, high, context.nu_a, context.nu_b, identify, secant)

    return make


VARIANTS: dict[str, Callable[[LearnerContext], Learner]] = {
    "identify_only": _variant(True, False),
    "secant_only": _variant(False, True),
    "offset_only": _variant(False, False),
}
"""``newton_ilc`` without identification, secant or both: ablations of this benchmark only."""
LEARNERS = ("ilc_paper", "ilc", "least_squares", "newton_ilc", *VARIANTS)
"""``ilc_paper``: eqs. 33-34 from the fictitious zero iteration (``run``'s default); ``ilc``: from the
nominal solution; the library's ids are built by the registry (:mod:`ilc_steering.agents.registry`)."""


def build(learner: str, context: LearnerContext, trials: int) -> Learner:
    """The learner ``learner`` (a registry id or one of :data:`VARIANTS`) for a budget of ``trials``."""
    if learner in VARIANTS:
        return VARIANTS[learner](context)
    return lookup(learner).make(context, trials)


@dataclass(frozen=True)
class Args:
    quick: bool = False
    """Forward parking only, one seed, a few trials: checks that the script runs (CI)."""
    out: Path = Path("results/newton_ilc")
    """Where the tables and the figure go."""
    seeds: tuple[int, ...] = tuple(range(10))
    """Seeds of the measurement noise."""
    trials: int = 12
    """Budget of every model-based run [trials]."""
    least_squares_trials: int = 60
    """Budget of ``least_squares`` [trials]."""
    noise: float = 2e-4
    """Measurement noise sigma per coordinate [m, rad]."""


def perturbed(name: str, **plant: float) -> SteeringConfig:
    config = load_config(name)
    return dataclasses.replace(config, plant=dataclasses.replace(config.plant, **plant)) if plant else config  # type: ignore[type-var]


def run(config: SteeringConfig, learner: str, trials: int, seed: int = 0, noise: float | None = None) -> dict[str, Any]:
    """One run: trials to tolerance, the true error after each trial and the update times."""
    env = gym.make("ilc_steering/ChainedSteering-v0", config=config, measurement_noise=noise)
    learning = config.learning
    agent = build(learner, LearnerContext.from_env(env, seed=seed), trials)
    rollout = run_trials(env, agent, trials, seed=seed)
    hits = [k for k, info in enumerate(rollout.infos, 1) if within_tolerance(learning.tolerance, info)]
    key = "true_cartesian_error" if "true_cartesian_error" in rollout.infos[0] else "true_error_norm"
    seconds = update_times(agent)
    return {
        "trials_to_tolerance": hits[0] if hits else None,
        "errors": [float(info[key]) for info in rollout.infos],
        "median_update_s": median(seconds) if seconds else None,
        "max_update_s": max(seconds) if seconds else None,
    }


def _count(value: int | None) -> str:
    return "-" if value is None else str(value)


def main(args: Args) -> list[dict[str, Any]]:
    out = check_output_dir(args.out, "--out")
    tasks = TASKS[:1] if args.quick else TASKS
    seeds = args.seeds[:1] if args.quick else args.seeds
    trials = 4 if args.quick else args.trials
    budget = {"least_squares": 8 if args.quick else args.least_squares_trials}
    run(load_config(tasks[0]), "newton_ilc", 2)  # compile outside the timing
    rows: list[dict[str, Any]] = []

    def record(experiment: str, task: str, perturbation: str, learner: str, seed: int, result: dict[str, Any]) -> None:
        rows.append(
            {
                "experiment": experiment,
                "task": task,
                "perturbation": perturbation,
                "learner": learner,
                "seed": seed,
                **result,
            }
        )
        print(
            f"{experiment:8s} {task:26s} {perturbation:16s} {learner:14s} seed {seed}: "
            f"{_count(result['trials_to_tolerance'])}",
            flush=True,
        )

    for task in tasks:
        for learner in LEARNERS:
            record("family", task, "none", learner, 0, run(load_config(task), learner, budget.get(learner, trials)))
    car_tasks = [t for t in tasks if t.startswith("forward")]
    for task in car_tasks:
        for key, value in list(PERTURBATIONS.items())[: 1 if args.quick else None]:
            config = perturbed(task, **{key: value})
            for learner in LEARNERS:
                result = run(config, learner, budget.get(learner, trials))
                record("unmodeled", task, f"{key}={value:g}", learner, 0, result)
    for task in [t for t in tasks if t != "chained_perturbed"]:
        for seed in seeds:
            for learner in ("ilc_paper", "ilc", "newton_ilc"):
                record(
                    "noise",
                    task,
                    f"sigma={args.noise:g}",
                    learner,
                    seed,
                    run(load_config(task), learner, trials, seed, args.noise),
                )
    markdown = report(rows, seeds)
    write_results(
        [{k: v for k, v in r.items() if k != "errors"} for r in rows],
        out,
        "newton_ilc",
        markdown,
        {"curves": rows, "args": {k: str(v) for k, v in dataclasses.asdict(args).items()}},
    )
    figure(rows, out / "newton_ilc_errors.png")
    print(markdown)
    return rows


def report(rows: list[dict[str, Any]], seeds: tuple[int, ...]) -> str:
    """The three tables and the learner's compute per update."""

    def cell(experiment: str, task: str, perturbation: str, learner: str) -> list[dict[str, Any]]:
        return [
            r
            for r in rows
            if (r["experiment"], r["task"], r["perturbation"], r["learner"])
            == (experiment, task, perturbation, learner)
        ]

    parts = ["## Inside the family (the packaged tasks), trials to 0.5 mm / 0.5 mrad\n"]
    tasks = list(dict.fromkeys(r["task"] for r in rows if r["experiment"] == "family"))
    table = [[t, *(_count(cell("family", t, "none", m)[0]["trials_to_tolerance"]) for m in LEARNERS)] for t in tasks]
    parts.append(markdown_table(["task", *LEARNERS], table, [False] + [True] * len(LEARNERS)))
    parts.append("\n## Outside the family (unmodeled servo perturbations), trials to 0.5 mm / 0.5 mrad\n")
    cases = list(dict.fromkeys((r["task"], r["perturbation"]) for r in rows if r["experiment"] == "unmodeled"))
    table = [
        [t, p, *(_count(cell("unmodeled", t, p, m)[0]["trials_to_tolerance"]) for m in LEARNERS)] for t, p in cases
    ]
    parts.append(markdown_table(["task", "perturbation", *LEARNERS], table, [False, False] + [True] * len(LEARNERS)))
    parts.append(
        f"\n## Measured with noise, {len(seeds)} seeds: median [min, max] trials; seeds where newton_ilc "
        "needs no more trials than each law\n"
    )
    table = []
    for task, noise in dict.fromkeys((r["task"], r["perturbation"]) for r in rows if r["experiment"] == "noise"):
        laws = ("ilc_paper", "ilc", "newton_ilc")
        counts = {m: [r["trials_to_tolerance"] for r in cell("noise", task, noise, m)] for m in laws}
        shown = []
        for values in counts.values():
            got = [v for v in values if v is not None]
            shown.append(
                f"{median(got):g} [{min(got)}, {max(got)}]"
                if len(got) == len(values)
                else f"{len(got)}/{len(values)} converged"
            )
        inf = float("inf")
        wins = [
            sum(
                (n if n is not None else inf) <= (o if o is not None else inf)
                for n, o in zip(counts["newton_ilc"], counts[law])
            )
            for law in ("ilc_paper", "ilc")
        ]
        table.append([task, noise, *shown, f"{wins[0]}/{len(seeds)}", f"{wins[1]}/{len(seeds)}"])
    header = ["task", "noise", "ilc_paper", "ilc", "newton_ilc", "newton_ilc <= ilc_paper", "newton_ilc <= ilc"]
    parts.append(markdown_table(header, table, [False, False, True, True, True, True, True]))
    updates = [r for r in rows if r["learner"] == "newton_ilc" and r["median_update_s"] is not None]
    parts.append(
        f"\n`newton_ilc` update (identification and Newton solve, simulations included), over its {len(updates)} runs: "
        f"median {1e3 * median(r['median_update_s'] for r in updates):.0f} ms, "
        f"largest {1e3 * max(r['max_update_s'] for r in updates):.0f} ms.\n"
    )
    return "\n".join(parts)


def figure(rows: list[dict[str, Any]], path: Path) -> None:
    """Error against trial for eqs. 33-34, ``least_squares`` and ``newton_ilc`` on simulations 1-3."""
    from matplotlib.figure import Figure
    from matplotlib.ticker import MaxNLocator

    tasks = [t for t in TASKS[:3] if any(r["task"] == t and r["experiment"] == "family" for r in rows)]
    fig = Figure(figsize=(4.2 * len(tasks), 3.8), dpi=100)
    axes = fig.subplots(1, len(tasks), squeeze=False)[0]
    for ax, task in zip(axes, tasks):
        for learner, style in (("ilc_paper", "o-"), ("least_squares", "s-"), ("newton_ilc", "^-")):
            (found,) = [r for r in rows if (r["experiment"], r["task"], r["learner"]) == ("family", task, learner)]
            errors = np.maximum(found["errors"][:16], 1e-16)
            label = "eqs. 33-34" if learner == "ilc_paper" else learner
            ax.semilogy(np.arange(1, errors.size + 1), errors, style, markersize=4, label=label)
        ax.axhline(load_config(task).learning.tolerance.cartesian or 0, color="k", linestyle="--", linewidth=0.8)
        ax.set_title(task.replace("_", " ").capitalize())
        ax.set_xlabel("trial")
        ax.xaxis.set_major_locator(MaxNLocator(integer=True))
        ax.grid(True, linewidth=0.4, alpha=0.5)
    axes[0].set_ylabel("Cartesian error [m] (true)")
    axes[0].legend()
    fig.tight_layout()
    fig.savefig(path)


def parse(argv: list[str] | None = None) -> Args:
    parser = Parser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="forward parking, one seed, a few trials")
    parser.add_argument("--out", type=Path, default=Args.out)
    return Args(**vars(parser.parse_args(argv)))


if __name__ == "__main__":
    arguments = parse()
    main(arguments)
    record_made(arguments.out, __file__, sys.argv[1:])
