"""Per-trial cost of the RL baselines: SB3 (torch's default threads and one thread) against SBX (JAX).

In one run, for each algorithm, each implementation runs the comparison's own learner
(:func:`ilc_steering.agents.rl.make_learner` through :func:`ilc_steering.compare.cells.measure`:
every trial counted, deterministic trials included) on forward parking under
``prior=nominal`` with its packaged hyperparameters, for ``short`` and for ``long`` trials:

- ``per_trial_ms``: the marginal cost of a trial, ``(t_long - t_short) / (long - short)``: what a
  cell's budget multiplies;
- ``fixed_s``: what a cell costs besides, ``t_short - short * per_trial``: building the model and,
  for SBX, compiling its update (from JAX's persistent cache after the first cell of a process);
- ``cell_s``: the whole cost of a cell of ``budget`` trials, ``fixed + budget * per_trial``.

A warm-up run of each implementation comes first (imports, numba's and JAX's first compiles), so
every timed run is a later cell of a worker process, as in ``compare``. Times are medians over
``repeats`` (seeds 0, 1, ...); speed-ups are against SB3 with one thread (what ``compare`` runs
today) and SB3 with torch's default threads (what a user gets), measured in the same run. A
backend that is not installed is left out and said so.

    python benchmarks/rl_speed.py [--quick] [--out DIR]

writes ``rl_speed.{json,csv,md}`` to ``DIR``.
"""

from __future__ import annotations

import os
import platform
import sys
import time
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ilc_steering.arguments import Parser
from ilc_steering.engine.provenance import record_made
from ilc_steering.output import check_output_dir
from ilc_steering.tables import markdown_table, write_results

__all__ = ["Args", "main"]

MODES = ("sb3, torch default threads", "sb3, 1 thread", "sbx")


@dataclass(frozen=True)
class Args:
    quick: bool = False
    """td3 and sac, 20 and 60 trials, one repeat: checks that the benchmark runs (CI)."""
    out: Path = Path("results/rl_speed")
    """Where the tables go."""
    algorithms: tuple[str, ...] = ("td3", "sac", "crossq", "tqc", "ppo")
    """The RL methods timed."""
    scenario: str = "forward_parking"
    """The task."""
    short: int = 100
    """Trials of the short run."""
    long: int = 600
    """Trials of the long run."""
    repeats: int = 3
    """Timed pairs of runs per (algorithm, implementation); the median is reported."""
    budget: int = 10_000
    """The cell budget ``cell_s`` is given for [trials]."""
    modes: tuple[str, ...] = MODES
    """The implementations timed, of :data:`MODES`."""


def _cell_seconds(algorithm: str, mode: str, scenario: str, trials: int, seed: int) -> float:
    import gymnasium as gym
    import torch

    from ilc_steering.agents import rl, rl_settings
    from ilc_steering.agents.base import LearnerContext
    from ilc_steering.compare.cells import ENV_ID, measure

    backend = "sbx" if mode == "sbx" else "sb3"
    rl.TORCH_THREADS = 1 if mode == "sb3, 1 thread" else DEFAULT_THREADS
    env = gym.make(ENV_ID, config=scenario)
    unwrapped: Any = env.unwrapped
    context = LearnerContext.from_env(env, seed=seed)
    params = rl_settings.hyperparameters(algorithm, unwrapped.config.name, "nominal")
    start = time.perf_counter()
    learner = rl.make_learner(algorithm, params, trials, False, context, backend)
    result = measure(env, learner, trials, seed)
    seconds = time.perf_counter() - start
    if result["trials"] != trials:
        raise RuntimeError(f"{algorithm} on {mode}: ran {result['trials']} of {trials} trials")
    torch.set_num_threads(DEFAULT_THREADS)
    return seconds


DEFAULT_THREADS = 0
"""torch's default thread count, read before anything sets it (in :func:`main`)."""


def main(args: Args) -> list[dict[str, Any]]:
    global DEFAULT_THREADS
    import torch

    from ilc_steering.agents import rl_settings

    if not 0 < args.short < args.long or args.repeats < 1:
        raise ValueError(f"need 0 < short < long and repeats >= 1, got {args.short}, {args.long}, {args.repeats}")
    DEFAULT_THREADS = torch.get_num_threads()
    check_output_dir(args.out, "--out")
    algorithms = args.algorithms[:2] if args.quick else args.algorithms
    short, long, repeats = (20, 60, 1) if args.quick else (args.short, args.long, args.repeats)
    unknown = [m for m in args.modes if m not in MODES]
    if unknown:
        raise ValueError(f"--modes: unknown {unknown[0]!r}; choose from {list(MODES)}")
    installed = [m for m in args.modes if m != "sbx" or "sbx" in rl_settings.installed_backends()]
    rows: list[dict[str, Any]] = []
    for algorithm in algorithms:
        for mode in installed:
            _cell_seconds(algorithm, mode, args.scenario, short, 1000)  # warm-up: first imports and compiles
            pairs = [
                (
                    _cell_seconds(algorithm, mode, args.scenario, short, seed),
                    _cell_seconds(algorithm, mode, args.scenario, long, seed),
                )
                for seed in range(repeats)
            ]
            per_trial = float(np.median([(b - a) / (long - short) for a, b in pairs]))
            fixed = float(np.median([a - short * (b - a) / (long - short) for a, b in pairs]))
            rows.append(
                {
                    "algorithm": algorithm,
                    "implementation": mode,
                    "package": rl_settings.implementation(algorithm, "sbx" if mode == "sbx" else "sb3"),
                    "per_trial_ms": 1000 * per_trial,
                    "fixed_s": fixed,
                    "cell_s": fixed + args.budget * per_trial,
                }
            )
            print(f"{algorithm} {mode}: {1000 * per_trial:.2f} ms per trial, {fixed:.2f} s fixed", flush=True)
    for row in rows:
        mine = {r["implementation"]: r for r in rows if r["algorithm"] == row["algorithm"]}
        for mode, key in (
            ("sb3, 1 thread", "speedup_vs_sb3_1_thread"),
            ("sb3, torch default threads", "speedup_vs_sb3_default"),
        ):
            row[key] = mine[mode]["cell_s"] / row["cell_s"] if mode in mine else float("nan")
    lines = [
        [
            r["algorithm"],
            r["implementation"],
            r["package"],
            f"{r['per_trial_ms']:.2f}",
            f"{r['fixed_s']:.1f}",
            f"{r['cell_s']:.0f}",
            f"{r['speedup_vs_sb3_1_thread']:.1f}x",
            f"{r['speedup_vs_sb3_default']:.1f}x",
        ]
        for r in rows
    ]
    header = [
        "algorithm",
        "implementation",
        "package",
        "per trial [ms]",
        "fixed per cell [s]",
        f"cell of {args.budget} trials [s]",
        "vs sb3, 1 thread",
        "vs sb3, default threads",
    ]
    missing = [] if "sbx" in installed else ["SBX is not installed (pip install 'ilc-steering[rl-jax]'): no sbx rows."]
    text = "\n".join(
        [
            f"RL cost per trial on {args.scenario}, prior=nominal, the packaged hyperparameters "
            f"(python benchmarks/rl_speed.py{' --quick' if args.quick else ''}): runs of {short} and {long} trials, "
            f"medians of {repeats}, torch's default threads {DEFAULT_THREADS}, {os.cpu_count()} cores, "
            f"{platform.machine()}, Python {platform.python_version()}.",
            *missing,
            "",
            markdown_table(header, lines, [False, False, False, True, True, True, True, True]),
        ]
    )
    write_results(rows, args.out, "rl_speed", text, {"settings": {**asdict(args), "out": str(args.out)}})
    print(text)
    return rows


def parse(argv: list[str] | None = None) -> Args:
    parser = Parser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="td3 and sac, 20 and 60 trials, one repeat (CI)")
    parser.add_argument("--out", type=Path, default=Args.out, help="folder for rl_speed.{json,csv,md}")
    parser.add_argument("--algorithms", nargs="+", default=list(Args.algorithms), help="RL methods to time")
    parser.add_argument("--repeats", type=int, default=Args.repeats, help="timed pairs of runs (median)")
    parser.add_argument("--modes", nargs="+", default=list(MODES), help=f"implementations to time, of {list(MODES)}")
    ns = parser.parse_args(argv)
    return Args(quick=ns.quick, out=ns.out, algorithms=tuple(ns.algorithms), repeats=ns.repeats, modes=tuple(ns.modes))


if __name__ == "__main__":
    arguments = parse()
    main(arguments)
    record_made(arguments.out, __file__, sys.argv[1:])
