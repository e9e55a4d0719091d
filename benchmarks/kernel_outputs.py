"""The final states of every packaged config's trials, to compare two versions of the simulator.

For each config: the nominal solution with its coefficients perturbed by 5 % (seeded), a batch of
``size`` trials (a plant per trial, their true factors jittered by 2 %, so a block of lanes mixes
plants), run serially and shared among threads, and ten trials with every step recorded.

    python benchmarks/kernel_outputs.py --save before.npz       # on one version of the code
    python benchmarks/kernel_outputs.py --compare before.npz    # on another: exit 1 unless identical

``--compare`` prints, per config, the largest difference of the final states (``0`` bit for bit)
and exits 1 if any exceeds ``--tolerance`` (0: bit for bit).
"""

from __future__ import annotations

import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ilc_steering.arguments import Parser
from ilc_steering.config import load_config
from ilc_steering.core.simulate import simulate
from ilc_steering.envs.scenario import Scenario

__all__ = ["CONFIGS", "Args", "main", "outputs"]

CONFIGS = (
    "forward_parking",
    "forward_parking_saturated",
    "parallel_parking",
    "parallel_parking_servo",
    "parallel_parking_lag",
    "unicycle_parking",
    "trailer_bay",
    "trailer_hitch",
    "chained_perturbed",
    "experiment_forward",
    "experiment_parallel",
)


@dataclass(frozen=True)
class Args:
    save: Path | None = None
    """Write the outputs to this ``.npz``."""
    compare: Path | None = None
    """Compare the outputs with this ``.npz`` (written by ``--save``)."""
    size: int = 75
    """Trials per batch: a block of 64 lanes and a padded partial block (the lab robot: a third)."""
    tolerance: float = 0.0
    """The largest difference ``--compare`` accepts (0: bit for bit)."""
    configs: tuple[str, ...] = CONFIGS


def outputs(name: str, size: int, seed: int = 0) -> dict[str, Any]:
    """Final states and statuses of ``name``'s trials (serial, parallel) and the recorded states."""
    scenario = Scenario.from_config(load_config(name))
    rng = np.random.default_rng(seed)
    c0 = scenario.nominals[0].solve()
    c = c0 * (1 + 0.05 * rng.standard_normal((size, c0.size)))
    plants = [scenario.plant.with_true_factors(1 + 0.02 * rng.standard_normal(2)) for _ in range(size)]
    x0 = np.repeat(scenario.x_start[None], size, axis=0)
    profile = scenario.nominals[0].profile
    result: dict[str, Any] = {}
    for parallel in (False, True):
        trials = simulate(plants, profile, x0, c, scenario.max_step, parallel=parallel)
        result[f"{name}/final/{parallel}"] = trials.final
        result[f"{name}/status/{parallel}"] = trials.status
    recorded = simulate(plants[:10], profile, x0[:10], c[:10], scenario.max_step, record=True)
    assert recorded.states is not None
    result[f"{name}/states"] = recorded.states
    return result


def main(args: Args) -> int:
    result: dict[str, Any] = {}
    for name in args.configs:
        size = max(11, args.size // 3) if name.startswith("experiment") else args.size
        result.update(outputs(name, size))
    if args.save is not None:
        np.savez(args.save, **result)
    if args.compare is None:
        return 0
    before = np.load(args.compare)
    worst = 0.0
    for name in args.configs:
        keys = [key for key in result if key.startswith(f"{name}/")]
        diff = max(float(np.max(np.abs(result[key] - before[key]))) for key in keys)
        print(f"{name:28s} largest difference {diff:.3g}")
        worst = max(worst, diff)
    print(f"worst {worst:.3g} (tolerance {args.tolerance:g})")
    return int(worst > args.tolerance)


def parse(argv: list[str] | None = None) -> Args:
    parser = Parser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--save", type=Path)
    parser.add_argument("--compare", type=Path)
    parser.add_argument("--size", type=int, default=Args.size)
    parser.add_argument("--tolerance", type=float, default=0.0)
    parser.add_argument("--configs", nargs="+", default=list(CONFIGS))
    ns = parser.parse_args(argv)
    return Args(ns.save, ns.compare, ns.size, ns.tolerance, tuple(ns.configs))


if __name__ == "__main__":
    sys.exit(main(parse()))
