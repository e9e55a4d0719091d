"""Trials to tolerance: ILC against RL (SB3), black-box and users' learners, across seeds and priors.

Every method is a :class:`~ilc_steering.agents.base.Learner` built from the same
:class:`~ilc_steering.agents.base.LearnerContext` (the nominal model, the env's spaces, a seed and
the prior), run on ``ilc_steering/ChainedSteering-v0`` by the one trial loop,
:func:`~ilc_steering.loop.run_trials`, which runs and counts every trial it asks for (probes,
random exploration and RL's deterministic trials included) up to the budget; a
:class:`TrialLog` records the *true* errors (the env may measure with noise).

Two conditions, ``--priors``: ``nominal`` (every method's first trial is the nominal open-loop
solution, and black-box and RL methods search a residual box around it) and ``none`` (no prior:
a seeded start near ``c = 0`` in the env's whole action box). ``ilc_paper`` is the paper's
learner exactly, whose fictitious zero iteration is its own first trial under both.

A run folder holds ``run.json`` (the settings, the package version and the content hash of each
scenario's resolved config), ``cells/<prior>__<method>__<scenario>__<seed>.json`` (one per
finished cell, written the moment it finishes; the method's part of the name is injective,
:func:`~ilc_steering.output.injective_name`), ``failed/`` (one file per cell that raised or
outlived ``--cell-timeout``, with its error) and, at the end, ``compare.{csv,json,md}`` and
``compare_<scenario>.png``. Running again on the same folder skips the finished cells and
retries the failed ones: an interrupted run resumes and never recomputes or loses a finished
cell. A resume with other settings, another version, or another config under a scenario's name
is refused, saying which; every resumed cell is checked value by value (:func:`read_cell`).
Cells run in ``--workers`` processes (one per core by default, at most
:data:`~ilc_steering.engine.backends.MAX_WORKERS`), with the same results as one process.

``--against DIR`` puts new methods beside a committed run without rerunning it: the run takes
the committed run's settings (budgets, seeds, ``quick``; another version or other settings are
refused, :mod:`~ilc_steering.compare.against`), its scenarios and priors, copies its cells, each checked,
into ``--out`` (``DIR`` is only read), computes only the cells it lacks, and reports them all.

A tolerance level is met when the error is at most the level; a count that a relative change
of 1e-6 in the error would move (:data:`FRAGILE`) is listed in the cell's ``fragile`` and
marked in the report.

    ilc-steering compare [--quick] [--out DIR] [--methods ilc least_squares mypkg.mod:make ...]
    ilc-steering compare --methods mypkg.mod:make --against results/compare --out DIR
    python benchmarks/compare.py [--quick] [--out DIR]
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Iterable
from dataclasses import replace
from pathlib import Path
from typing import Any

from ilc_steering.agents import registry
from ilc_steering.agents.base import PRIORS
from ilc_steering.arguments import Parser
from ilc_steering.compare.args import MAX_SEED, QUICK, QUICK_SEEDS, SCENARIOS, Args
from ilc_steering.compare.cells import run_cell
from ilc_steering.compare.execute import Runner, execute
from ilc_steering.compare.plan import plan
from ilc_steering.compare.report import write_report
from ilc_steering.engine.options import add_cell_options
from ilc_steering.engine.provenance import record_report
from ilc_steering.output import output_folder

__all__ = ["main", "main_with_failures", "method_families", "parse", "run_all", "run_cells", "validate"]

MODEL_METHODS = registry.ids("model-based")
BLACKBOX = registry.ids("black-box")
RL = registry.ids("RL")
METHODS = registry.METHODS
DEFAULT_METHODS = registry.DEFAULT_METHODS
"""Views of the one table of method ids, :data:`ilc_steering.agents.registry.REGISTRY`."""


def method_families(methods: Iterable[str] = ()) -> dict[str, tuple[str, ...]]:
    """The families the comparison's figures colour by (:mod:`~ilc_steering.figure_styles`):
    :func:`ilc_steering.agents.registry.families`."""
    return registry.families(methods)


def validate(args: Args) -> dict[str, str]:
    """Check every argument and scenario before the first cell (:func:`~ilc_steering.compare.plan.plan`);
    returns scenario -> config name."""
    return plan(args).names


def run_cells(args: Args, runner: Runner = run_cell) -> list[dict[str, Any]]:
    """Every finished cell of the run (:func:`run_all`), in order; the failed ones are in ``failed/``."""
    return run_all(args, runner)[0]


def run_all(args: Args, runner: Runner = run_cell) -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
    """Every cell of the run, computing only those not yet in the run folder, on the engine
    (:func:`~ilc_steering.engine.runs.compute_cells`; with a custom ``runner``, in this process, called as
    it is: a test's hook); returns the finished cells and the failed ones, each in the run's order."""
    return execute(plan(args), runner)


def main(args: Args) -> list[dict[str, Any]]:
    """Run (or resume) the comparison and write its report; returns the finished cells."""
    return main_with_failures(args)[0]


def main_with_failures(args: Args) -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
    """:func:`main`, returning the failed cells too; the last line printed says how many failed."""
    the_plan = plan(args)
    args, committed = the_plan.args, the_plan.committed
    cells, failed = execute(the_plan)
    if args.dry_run:
        return cells, failed
    names = list(the_plan.names.values())
    if committed is not None:
        names = list(dict.fromkeys([*(c["scenario"] for c in cells), *names]))
    if cells:
        groups = method_families(c["method"] for c in cells)
        text = write_report(cells, names, args.out, {"black-box": BLACKBOX, "RL": RL}, failed, groups)
        record_report(args.out, cells)
        print(text)
        where = f"{args.out}/compare.{{csv,json,md}}, compare_<scenario>.png"
        print(f"wrote {where} and one file per cell in {args.out}/cells")
    if committed is not None:
        print(
            f"the report holds the {len(committed.cells)} cells of the committed run --against {committed.folder} "
            f"and {len(cells) - len(committed.cells)} of {' '.join(args.methods)}"
            + (f"; its {committed.failed} failed cells are not taken" if committed.failed else ""),
            flush=True,
        )
    total = len(cells) + len(failed)
    if failed:
        line = f"{len(failed)} of {total} cells failed, each recorded with its error in {args.out}/failed"
        print(f"{line} (a resume computes them again)", flush=True)
        print(f"ilc-steering: {line}", file=sys.stderr, flush=True)
    else:
        print(f"all {total} cells finished", flush=True)
    return cells, failed


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.formatter_class = argparse.ArgumentDefaultsHelpFormatter
    parser.add_argument(
        "--quick",
        action="store_true",
        help=f"tiny budgets ({QUICK['model_trials']} model-based, {QUICK['blackbox_trials']} black-box, "
        f"{QUICK['rl_trials']} RL, {QUICK['custom_trials']} custom trials) and, unless --seeds is given, seeds "
        f"{' '.join(map(str, QUICK_SEEDS))}: checks that everything runs",
    )
    parser.add_argument("--out", type=output_folder, default=Args.out, help="run folder; an existing one is resumed")
    parser.add_argument(
        "--against",
        type=Path,
        default=None,
        metavar="DIR",
        help="a committed run folder (e.g. results/compare), only read: run the cells of --methods it lacks, with its "
        "scenarios, seeds, priors and budgets (its run.json; another version or other settings are refused), and "
        "write the joint report to --out",
    )
    parser.add_argument(
        "--priors", nargs="+", default=list(PRIORS), help="nominal: start from the nominal solution; none: no prior"
    )
    parser.add_argument(
        "--methods",
        nargs="+",
        default=list(DEFAULT_METHODS),
        help=f"any of {' '.join(METHODS)}, or module:attr, a factory make(LearnerContext) -> Learner",
    )
    parser.add_argument(
        "--scenarios", nargs="+", default=list(SCENARIOS), help="packaged config names or YAML paths (one-trial tasks)"
    )
    parser.add_argument(
        "--seeds",
        type=int,
        nargs="+",
        default=None,
        help=f"whole numbers in [0, {MAX_SEED}] (default: 0 to 9; with --quick: 0 1)",
    )
    for option, what in (
        ("model_trials", "ilc, ilc_paper and newton"),
        ("blackbox_trials", "each black-box optimizer"),
        ("rl_trials", "each RL algorithm (default: n_timesteps of configs/rl/*.yaml)"),
        ("custom_trials", "a user's learner (module:attr)"),
    ):
        parser.add_argument(
            f"--{option.replace('_', '-')}",
            type=int,
            default=argparse.SUPPRESS,
            help=f"budget of {what} [trials] (default: {getattr(Args, option)}; with --quick: {QUICK[option]})",
        )
    parser.add_argument(
        "--ablation-seeds",
        type=int,
        default=argparse.SUPPRESS,
        metavar="K",
        help=f"prior=none, the ablation, runs the first K seeds (default: {Args.ablation_seeds})",
    )
    add_cell_options(parser, "cell")
    parser.add_argument(
        "--tensorboard",
        type=output_folder,
        default=None,
        metavar="DIR",
        help="write TensorBoard event files of every cell computed, in <scenario>/<method>_seed<seed> (a prior "
        "other than nominal: _prior-<prior> after it): one point per trial, the same tags for every method, an RL "
        "method's own SB3 logs beside them (the tensorboard extra); not part of the results",
    )
    bar = parser.add_mutually_exclusive_group()
    bar.add_argument("--progress-bar", action="store_true", help="SB3's progress bar on RL cells (one worker)")
    bar.add_argument("--no-progress-bar", action="store_true", help="no progress bar (the default)")


def from_namespace(ns: argparse.Namespace) -> Args:
    budgets = {k: getattr(ns, k) for k in (*QUICK, "ablation_seeds") if hasattr(ns, k)}
    args = Args(
        quick=ns.quick,
        out=ns.out,
        against=ns.against,
        priors=tuple(ns.priors),
        methods=tuple(ns.methods),
        scenarios=tuple(ns.scenarios),
        seeds=None if ns.seeds is None else tuple(ns.seeds),
        workers=ns.workers,
        progress_bar=ns.progress_bar,
        backend=ns.backend,
        cell_timeout=getattr(ns, "cell_timeout", None),  # suppressed when not given: the plan applies the default
        dry_run=ns.dry_run,
        tensorboard=ns.tensorboard,
    )
    return replace(args, **budgets)


def parse(argv: list[str] | None = None) -> Args:
    parser = Parser(description=(__doc__ or "").splitlines()[0])
    add_arguments(parser)
    return from_namespace(parser.parse_args(argv))
