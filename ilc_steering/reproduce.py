"""``ilc-steering reproduce``: the paper's simulations 1-4 and experiments 1-2, each run to the
config's tolerance, a table beside the paper's counts with the known causes of a difference, and
the lab experiments over :data:`SEEDS` of their localization noise for :data:`SEEDED_LEARNERS`."""

from __future__ import annotations

import argparse
import statistics

from ilc_steering.agents.registry import REGISTRY
from ilc_steering.config import load_config
from ilc_steering.console import learn, save
from ilc_steering.output import check_output_dir
from ilc_steering.runner import (
    RunResult,
    run_ilc,
)

__all__ = ["PAPER", "SEEDED_LEARNERS", "SEEDS", "WHY_DIFFERENT", "reproduce"]

PAPER: dict[str, tuple[int | None, str]] = {
    "forward_parking": (4, "Figs. 3-6"),
    "forward_parking_saturated": (7, "Figs. 7-10"),
    "parallel_parking": (5, "Figs. 11-14"),
    "cyclic_home_goal": (None, "Figs. 23-25"),  # no count stated; the figures show five cycles
    "experiment_forward": (5, "Figs. 16-18"),  # section 5, on the lab robot
    "experiment_parallel": (5, "Figs. 19-21"),
}
WHY_DIFFERENT = {
    "forward_parking_saturated": (
        "the paper does not say how its 45-degree saturation is modelled (ours: a steering servo whose "
        "command winds past the stop, ilc_steering/core/robots/car_fields.py), and it judged 'exact steering' "
        "from its plots where we count trials to a 0.5 mm tolerance"
    ),
    "experiment_forward": (
        "the simulated MARIO's unnamed imperfections (its wheels' rolling radius, the drive's lag, the steering's "
        "trim and play) are calibrated on both experiments at once (benchmarks/calibrate_mario.py, docs/paper.md): "
        "no candidate of the search that takes five on experiment 2 takes more than four here"
    ),
    "experiment_parallel": (
        "the simulated MARIO's unnamed imperfections are calibrated on both experiments at once "
        "(benchmarks/calibrate_mario.py, docs/paper.md)"
    ),
}


def reproduce(args: argparse.Namespace) -> int:
    for folder, option in ((args.json_dir, "--json-dir"), (args.plots, "--plots")):
        if folder is not None:
            check_output_dir(folder, option)
    rows = []
    for name, (paper, figures) in PAPER.items():
        result = learn(load_config(name), None, trajectories=args.json_dir is not None or args.plots is not None)
        save(result, None if args.json_dir is None else args.json_dir / f"{name}.json", args.plots)
        print()
        rows.append((name, figures, paper, result))
    print("| scenario | paper figures | paper iterations | trials (cycles) to tolerance |")
    print("| --- | --- | ---: | ---: |")
    for name, figures, paper, result in rows:
        ours = result.converged_at if result.converged_at is not None else "not converged"
        print(f"| {name} | {figures} | {paper if paper is not None else 'not stated'} | {ours} |")
    for name, _, paper, result in rows:
        if paper is None:
            print(f"\n{name}: the paper states no count; its figures show errors shrinking over five cycles.")
        elif result.converged_at != paper and isinstance(result, RunResult):
            errors = [t.error_norm if t.cartesian_error is None else t.cartesian_error for t in result.trials]
            ratio = errors[-1] / errors[-2] if len(errors) > 1 else float("nan")
            at_paper = f"{errors[paper - 1]:.2e} m at trial {paper}, " if paper <= len(errors) else ""
            print(
                f"\n{name}: {result.converged_at} trials against the paper's {paper}: "
                f"{WHY_DIFFERENT.get(name, 'no known cause')}. "
                f"Measured: {at_paper}error ratio {ratio:.2f} per trial at the end."
            )
    noisy = [name for name, *_ in rows if load_config(name).simulation.measurement_noise is not None]
    if noisy:
        _seeds_table(noisy)
    return 0 if all(result.converged_at is not None for *_, result in rows) else 1


SEEDS = range(10)
"""Seeds of the measurement noise over which ``reproduce`` reports the lab experiments."""
SEEDED_LEARNERS = tuple(i for i, spec in REGISTRY.items() if spec.reproduce)
"""The learners of that table: a view of the registry (``LearnerSpec.reproduce``)."""


def _seeds_table(names: list[str]) -> None:
    """Trials to tolerance over :data:`SEEDS` of the noise: median [range] and how many converged."""
    print(f"\nOver {len(SEEDS)} seeds of the localization noise (trials to the config's tolerance, median [range]):")
    print("| scenario | paper iterations | " + " | ".join(SEEDED_LEARNERS) + " |")
    print("| --- | ---: | " + " | ".join("---:" for _ in SEEDED_LEARNERS) + " |")
    for name in names:
        cells = []
        for learner in SEEDED_LEARNERS:
            counts = [run_ilc(name, learner=learner, seed=seed).converged_at for seed in SEEDS]
            got = sorted(c for c in counts if c is not None)
            summary = f"{statistics.median(got):g} [{got[0]}, {got[-1]}]" if got else "-"
            cells.append(f"{summary}, {len(got)}/{len(counts)} converged")
        print(f"| {name} | {PAPER[name][0]} | " + " | ".join(cells) + " |", flush=True)
