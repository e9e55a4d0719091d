"""The tuning sweep behind the RL hyperparameters of ``configs/rl/*.yaml`` (``prior=nominal``).

A small grid per algorithm around the packaged values, each candidate run on forward parking
under ``prior=nominal`` for a few seeds with the comparison's own counting
(:func:`ilc_steering.compare.cells.measure`: every trial counts, deterministic trials included). A
candidate is ranked by how many seeds reach 1 cm / 0.01 rad, then by its median trials to 1 cm, then
by its median best error. The
sweep's own cost in trials is reported beside its table: the RL rows of the comparison stand on
that many trials more than their budget shows.

    python benchmarks/tune_rl.py [--quick] [--out DIR] [--workers N] [--seeds S ...]

It writes each run to ``cells-<trials>/`` as it finishes (a rerun resumes), then
``tuning.{csv,json,md}``; the winners are copied by hand into ``configs/rl/*.yaml``.
"""

from __future__ import annotations

import itertools
import json
import math
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ilc_steering.arguments import Parser
from ilc_steering.engine.provenance import record_made
from ilc_steering.output import check_output_dir, write_json
from ilc_steering.tables import markdown_table, write_results

__all__ = ["GRID", "Args", "main"]

GRID: dict[str, dict[str, list[Any]]] = {
    # sweep 2 (results/tuning/sweep2): around the nominal values chosen by sweep 1 (results/compare/tuning.md)
    "td3": {"noise_std": [0.005, 0.01], "learning_rate": [3.0e-3, 1.0e-3, 3.0e-4]},
    "sac": {"gradient_steps": [1, 2], "target_entropy": [-12.0, -16.0]},
    "ppo": {"n_steps": [16, 64], "policy_kwargs.log_std_init": [-3.0, -4.0]},
    "crossq": {
        "gradient_steps": [1, 2],
        "policy_kwargs.net_arch": [{"pi": [64, 64], "qf": [256, 256]}, {"pi": [256, 256], "qf": [1024, 1024]}],
    },
    "tqc": {"gradient_steps": [1], "ent_coef": ["auto_0.01", 1.0e-4], "policy_kwargs.n_quantiles": [25, 10]},
}
"""Per algorithm, the values tried of each hyperparameter (``a.b``: key ``b`` of the dict ``a``)."""


@dataclass(frozen=True)
class Args:
    quick: bool = False
    """Two candidates per algorithm, one seed, 60 trials: checks that the sweep runs (CI)."""
    out: Path = Path("results/tuning")
    """Where the tables go."""
    scenario: str = "forward_parking"
    """The task tuned on."""
    seeds: tuple[int, ...] = (100, 101)
    """Seeds of the sweep, apart from the comparison's 0-9."""
    trials: int = 3000
    """Budget of each candidate run [trials]."""
    workers: int = 0
    """Worker processes; 0: one per core."""
    algorithms: tuple[str, ...] = tuple(GRID)
    """The algorithms swept."""


def candidates(algorithm: str) -> list[dict[str, Any]]:
    """Every combination of :data:`GRID`'s values for ``algorithm``, as overrides."""
    grid = GRID[algorithm]
    return [dict(zip(grid, values)) for values in itertools.product(*grid.values())]


def with_overrides(params: dict[str, Any], overrides: dict[str, Any]) -> dict[str, Any]:
    out = {k: (dict(v) if isinstance(v, dict) else v) for k, v in params.items()}
    for key, value in overrides.items():
        outer, _, inner = key.partition(".")
        if inner:
            out[outer] = {**out.get(outer, {}), inner: value}
        else:
            out[key] = value
    if "n_steps" in overrides:
        out["batch_size"] = overrides["n_steps"]
    return out


def run_candidate(algorithm: str, overrides: dict[str, Any], scenario: str, seed: int, trials: int) -> dict[str, Any]:
    """One sweep cell, counted as the comparison counts."""
    import gymnasium as gym
    import torch

    from ilc_steering.agents import rl, rl_settings
    from ilc_steering.agents.base import LearnerContext
    from ilc_steering.compare.cells import ENV_ID, measure

    torch.set_num_threads(1)
    env = gym.make(ENV_ID, config=scenario)
    unwrapped: Any = env.unwrapped
    context = LearnerContext.from_env(env, seed=seed)
    params = with_overrides(rl_settings.hyperparameters(algorithm, unwrapped.config.name, "nominal"), overrides)
    result = measure(env, rl.make_learner(algorithm, params, trials, False, context), trials, seed)
    return {k: v for k, v in result.items() if k != "curve"}


def option_text(overrides: dict[str, Any]) -> str:
    """A candidate's overrides as a file-name part every shell and OS takes as it is
    (``learning_rate-0.0003_noise_std-0.005``), injective: a name whose text had to be cleaned
    gets a hash of the overrides appended."""
    from ilc_steering.output import content_hash, safe_name

    text = "_".join(f"{key}-{value!r}" for key, value in sorted(overrides.items())) or "defaults"
    return text if safe_name(text) == text else f"{safe_name(text)[:80]}-{content_hash(overrides)[:8]}"


def main(args: Args) -> list[dict[str, Any]]:

    from ilc_steering.agents import rl_settings
    from ilc_steering.engine.backends import run_calls

    unknown = [a for a in args.algorithms if a not in GRID]
    if unknown:
        raise ValueError(f"--algorithms: no grid for {unknown[0]!r}; choose from {list(GRID)}")
    grid = {a: candidates(a)[:2] if args.quick else candidates(a) for a in args.algorithms}
    seeds = args.seeds[:1] if args.quick else args.seeds
    trials = 60 if args.quick else args.trials
    calls = {
        (a, i, seed): (a, overrides, args.scenario, seed, trials)
        for a, options in grid.items()
        for i, overrides in enumerate(options)
        for seed in seeds
    }
    cells = check_output_dir(args.out, "--out") / f"cells-{trials}"
    cells.mkdir(exist_ok=True)

    def path(key: tuple[str, int, int]) -> Path:
        return cells / f"{key[0]}__{option_text(grid[key[0]][key[1]])}__{key[2]}.json"

    results = {key: json.loads(path(key).read_text()) for key in calls if path(key).exists()}  # resume

    def finish(key: tuple[str, int, int], result: dict[str, Any]) -> None:
        write_json(path(key), result)  # as it comes: an interrupted sweep resumes
        results[key] = result
        print(f"{key[0]} {grid[key[0]][key[1]]} seed {key[2]}: 1 cm at {result['trials_to']['1cm']}", flush=True)

    todo = {key: call for key, call in calls.items() if key not in results}
    if todo:
        run_calls(run_candidate, todo, finish, workers=args.workers)
    rows = []
    for algorithm, options in grid.items():
        for i, overrides in enumerate(options):
            runs = [results[(algorithm, i, seed)] for seed in seeds]
            to_cm = [math.inf if r["trials_to"]["1cm"] is None else r["trials_to"]["1cm"] for r in runs]
            rows.append(
                {
                    "algorithm": algorithm,
                    "overrides": overrides,
                    "median_trials_to_1cm": float(np.median(to_cm)),
                    "reached_1cm": int(np.isfinite(to_cm).sum()),
                    "median_best_error": float(np.median([r["best_error"] for r in runs])),
                    "median_wall_s": float(np.median([r["wall_s"] for r in runs])),
                    "trials": sum(r["trials"] for r in runs),
                    "chosen": False,
                }
            )
    for algorithm in grid:
        mine = [r for r in rows if r["algorithm"] == algorithm]
        best = min(mine, key=lambda r: (-r["reached_1cm"], r["median_trials_to_1cm"], r["median_best_error"]))
        best["chosen"] = True
    spent = sum(r["trials"] for r in rows)
    lines = [
        [
            r["algorithm"],
            ", ".join(f"{k}={v}" for k, v in r["overrides"].items()),
            "-" if math.isinf(r["median_trials_to_1cm"]) else f"{r['median_trials_to_1cm']:.0f}",
            f"{r['reached_1cm']}/{len(seeds)}",
            f"{r['median_best_error']:.2e}",
            f"{r['median_wall_s']:.0f}",
            "chosen" if r["chosen"] else "",
        ]
        for r in rows
    ]
    header = ["algorithm", "candidate", "median trials to 1 cm", "reached", "median best error", "median wall [s]", ""]
    text = (
        f"Tuning sweep on {args.scenario}, prior=nominal, seeds {list(seeds)}, {trials} trials per run "
        f"(python benchmarks/tune_rl.py, {rl_settings.rl_backend()}, {args.workers or 'one per core'} workers). "
        f"The sweep itself cost {spent} trials. Ranked by seeds reaching 1 cm, then median trials to it.\n\n"
        + markdown_table(header, lines, [False, False, True, True, True, True, False])
    )
    flat = [{**r, "overrides": str(r["overrides"])} for r in rows]
    write_results(flat, args.out, "tuning", text, {"spent_trials": spent, "seeds": list(seeds), "trials": trials})
    print(text)
    return rows


def parse(argv: list[str] | None = None) -> Args:
    parser = Parser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="two candidates, one seed, 60 trials (CI)")
    parser.add_argument("--out", type=Path, default=Args.out, help="folder for tuning.{csv,json,md}")
    parser.add_argument("--trials", type=int, default=Args.trials, help="budget of each candidate run [trials]")
    parser.add_argument("--workers", type=int, default=0, help="worker processes (0: one per core)")
    parser.add_argument("--algorithms", nargs="+", default=list(GRID), help="algorithms to sweep")
    parser.add_argument("--seeds", nargs="+", type=int, default=list(Args.seeds), help="seeds (apart from 0-9)")
    ns = parser.parse_args(argv)
    return Args(
        quick=ns.quick,
        out=ns.out,
        trials=ns.trials,
        workers=ns.workers,
        algorithms=tuple(ns.algorithms),
        seeds=tuple(ns.seeds),
    )


if __name__ == "__main__":
    arguments = parse()
    main(arguments)
    record_made(arguments.out, __file__, sys.argv[1:])
