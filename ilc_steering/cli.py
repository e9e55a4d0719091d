"""The ``ilc-steering`` command (also ``python -m ilc_steering``).

Its commands, in the order ``--help`` lists them:

- ``list``: the packaged configs, one line each;
- ``run CONFIG``: learn on one scenario (several in turn, each from where the last left off), so it
  can gate a CI job;
- ``reproduce``: the paper's simulations, against its counts;
- ``plot RUN.json``: the paper's figures of a run written by ``run --json``;
- ``compare``: run (or resume) the benchmark of ILC against RL and black-box learners;
- ``sweep CONFIG``: a robustness map, a learner's trials over a grid of true plants;
- ``session``: a trial at a time on a robot nobody scripted (a person at the robot, a lab's script);
- ``current DIR``: whether every committed result is made by the code in this tree;
- ``tables``: rewrite the comparison tables of Markdown files from a compare run.

Exit codes (:data:`EXIT_CODES`): 0 converged (or done; ``run``: the last ``--hold`` trials within the
tolerance), 1 not converged, 5 converged to the plant's floor (``run``: the tolerance is below the
plant's repeatability, estimated from the trials, and the last trials are within that), 2 bad input (a config,
an argument, a run file, an unusable output path: all checked before any trial runs), 3 an
internal error (a bug of the library), 4 the user's code failed: in ``run``, a learner raised
(``sys.exit()`` included) or acted with an action the env refused, or a plant failed (it raised or
returned junk; ``plant.model: process``: the program hung, died or answered junk; the message names
it and the trial; the trials completed are written to ``--json`` / ``--plots``, as they are when a
trial's commands are refused for the robot's limits, exit 2); in ``compare`` and ``sweep``, some
cells or rows failed (or outlived ``--cell-timeout``): each is recorded with its error under
``failed/``, the others are finished and reported, and the last line says how many failed. 130:
interrupted (``run`` writes the trials completed, as for 4, and its line says so). Errors are one
line; ``--debug`` adds the traceback.
"""

from __future__ import annotations

import argparse
import os
import re
import signal
import sys
import threading
import traceback
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from ilc_steering.arguments import Parser
from ilc_steering.compare.command import add_arguments as add_compare_arguments
from ilc_steering.config import load_config, packaged_configs
from ilc_steering.config.loading import resolve_config
from ilc_steering.console import check_counts, check_outputs, learn, learn_goals, save, save_goals
from ilc_steering.core.scatter import HOLD
from ilc_steering.errors import ENDS_A_RUN, BadInput, ConfigError, LearnerError, PlantError
from ilc_steering.output import check_output_dir, output_file, output_folder
from ilc_steering.readers import check_apart
from ilc_steering.reproduce import PAPER
from ilc_steering.reproduce import reproduce as reproduce_paper
from ilc_steering.runner import (
    DEFAULT_LEARNER,
    CyclicRunResult,
    RunResult,
    step_warning,
)
from ilc_steering.session_cli import add_session_arguments
from ilc_steering.sweep.command import add_arguments as add_sweep_arguments
from ilc_steering.trial_board import check_tensorboard

__all__ = ["EXIT_CODES", "main"]

EXIT_CODES = {
    0: "converged (or done): run's last --hold trials within the tolerance",
    1: "not converged",
    2: "bad input: a config, an argument, a run file or an output path, refused before any trial",
    3: "internal error: a bug of ilc-steering (please report it; --debug prints the traceback)",
    4: "the user's code failed (a learner, or a plant: it raised, exited, hung, died or answered junk): run "
    "wrote the trials before it; compare and sweep recorded each failed cell or row (its error, or "
    "--cell-timeout) under failed/ and finished the others",
    5: "converged to the plant's floor: the tolerance is below the plant's repeatability (estimated from "
    "the trials) and run's last --hold trials are within the repeatability",
    130: "interrupted (run wrote the trials before it)",
}
"""The CLI's exit codes, as its ``--help`` prints them."""


NUMBER = re.compile(r"^-(?:(?:\d[\d_]*\.?[\d_]*|\.\d[\d_]*)(?:[eE][-+]?\d[\d_]*)?|inf(?:inity)?|nan)$", re.I)
"""A negative number as a program prints it (``repr``, ``%g``, ``%e``: ``-1e-05``, ``-.5``, ``-inf``): an
argument, never an option. argparse's own pattern knows ``-1`` and ``-0.5`` only, so ``--final 1.8 0.8
-1e-05`` was "unrecognized arguments: -1e-05"."""


class _Parser(Parser):
    """The command line's parser (and, through ``add_subparsers``, each subcommand's): an argument
    that reads as a negative number (:data:`NUMBER`) is a value, whatever its notation."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._negative_number_matcher = NUMBER


class Terminated(KeyboardInterrupt):
    """A ``SIGTERM`` (a supervisor, ``kill``, a CI job's end), taken as Ctrl-C is: the run stops, its
    robot program is stopped, the trials run so far are kept (exit 130)."""


def _terminate(signum: int, frame: Any) -> None:
    raise Terminated("by SIGTERM")


def _interrupted(done: int, unit: str, args: argparse.Namespace, error: KeyboardInterrupt) -> KeyboardInterrupt:
    """The interrupt ``error`` of a run whose ``done`` trials (cycles, goals) were kept: its one line says so."""
    where = [str(path) for path in (args.json, getattr(args, "plots", None)) if path is not None]
    note = f"; what ran is kept in {' and '.join(where)}" if done and where else ""
    cause = f"{error} " if isinstance(error, Terminated) else ""
    return type(error)(f"{cause}after {done} {unit[:-1] if done == 1 else unit}{note}")


def _run(args: argparse.Namespace) -> int:
    if len(args.config) > 1:
        return _run_goals(args)
    if args.carry:
        raise BadInput("--carry needs two or more configs (goals of one robot, in order)")
    source = resolve_config(args.config[0])
    config = load_config(source)
    hold = check_counts(args.trials, args.hold, [config])
    check_outputs(args.json, args.plots, [config], [source])
    check_tensorboard(args.tensorboard)
    warning = step_warning(config)
    if warning is not None:
        print(f"ilc-steering: {warning}", file=sys.stderr)
    try:
        trajectories = args.json is not None or args.plots is not None
        result = learn(config, args.trials, trajectories, args.learner, hold, args.tensorboard)
    except ENDS_A_RUN as error:
        partial = getattr(error, "partial", None)
        done = 0
        if isinstance(partial, (RunResult, CyclicRunResult)):
            done = len(partial.trials if isinstance(partial, RunResult) else partial.cycles)
            if done:
                save(partial, args.json, args.plots)  # the trials it completed are kept
        if isinstance(error, KeyboardInterrupt):  # still an interrupt (exit 130), saying what was kept
            raise _interrupted(done, "cycles" if config.is_cyclic else "trials", args, error) from error
        raise
    save(result, args.json, args.plots)
    if result.converged_at is not None:
        return 0
    return 5 if result.verdict.floor else 1


def _run_goals(args: argparse.Namespace) -> int:
    """``run A B C [--carry]``: one run per goal, in order, the learner carrying what it learned."""
    sources = [resolve_config(name) for name in args.config]
    configs = [load_config(source) for source in sources]
    hold = check_counts(args.trials, args.hold, configs)
    if args.plots is not None:
        raise BadInput("--plots draws one run: give one config (or plot a goal's run from --json)")
    check_outputs(args.json, None, configs, sources)
    check_tensorboard(args.tensorboard)
    try:
        results = learn_goals(configs, args.trials, args.learner, hold, args.carry, args.tensorboard)
    except ENDS_A_RUN as error:
        partial = getattr(error, "partial", None)
        done = len(partial) if isinstance(partial, list) else 0
        if isinstance(partial, list) and partial:
            save_goals(partial, args.json)  # the goals it completed are kept
        if isinstance(error, KeyboardInterrupt):
            raise _interrupted(done, "goals", args, error) from error
        raise
    save_goals(results, args.json)
    if all(r.converged_at is not None for r in results):
        return 0
    return 5 if all(r.converged_at is not None or r.verdict.floor for r in results) else 1


def _plot(args: argparse.Namespace) -> int:
    from ilc_steering.plots import figure_paths, load_run, write_plots

    run = load_run(args.run)
    check_apart([("--out", path) for path in figure_paths(args.out, run.name, run.cyclic)], [args.run])
    check_output_dir(args.out, "--out")
    for path in write_plots(run, args.out):
        print(f"wrote {path}")
    return 0


def _parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="ilc-steering",
        description="Iterative learning control of nonholonomic robots (Oriolo, Panzieri, Ulivi 1998).",
        epilog="Exit codes: " + "; ".join(f"{code} {meaning}" for code, meaning in EXIT_CODES.items()) + ".",
    )
    parser.add_argument("--debug", action="store_true", help="print the traceback of an error")
    sub = parser.add_subparsers(dest="command", required=True)
    listing = sub.add_parser("list", help="the packaged configs, one line each")
    listing.set_defaults(handler=_list)
    run = sub.add_parser(
        "run",
        help="learn on one scenario (one-trial or cyclic); exit 0 if it converged and held, 5 at the plant's floor",
    )
    run.add_argument(
        "config",
        nargs="+",
        help="a YAML file or a packaged config name, e.g. forward_parking; several: goals of one robot, "
        "run in order (see --carry)",
    )
    run.add_argument(
        "--carry",
        action="store_true",
        help="with several configs: each goal's learner starts from what the last one learned of the robot "
        "(its transfer(); a learner that carries nothing starts afresh)",
    )
    run.add_argument(
        "--trials",
        type=int,
        default=None,
        help="number of trials, or cycles for a cyclic config (default: the config's)",
    )
    run.add_argument(
        "--json",
        type=output_file,
        default=None,
        help="write the per-trial results and trajectories here (the input of plot)",
    )
    run.add_argument(
        "--plots",
        type=output_folder,
        default=None,
        metavar="DIR",
        help="write the paper's figures of this run here as PNGs",
    )
    run.add_argument(
        "--learner",
        default=DEFAULT_LEARNER,
        metavar="NAME",
        help="ilc_paper (the paper's eqs. 33-34), newton_ilc (re-identify, then Newton on the refit model), "
        "robust_ilc (global identification, continuation, a trust region), any other id of compare --methods, "
        "or module:attr, a factory make(LearnerContext) -> Learner",
    )
    run.add_argument(
        "--hold",
        type=int,
        default=None,
        metavar="N",
        help=f"converged means the last N trials (cycles) are all within the tolerance (default {HOLD}: one "
        "trial within it may be the scatter's luck); at most the trials run",
    )
    run.add_argument(
        "--tensorboard",
        type=output_folder,
        default=None,
        metavar="DIR",
        help="write TensorBoard event files here, in <config>/<learner>_seed<seed>: one point per trial of the "
        "errors, cost, reward and converged, the same tags as compare's cells (the tensorboard extra)",
    )
    run.set_defaults(handler=_run)
    reproduce = sub.add_parser("reproduce", help="run the paper's simulations and compare with its counts")
    reproduce.add_argument("--json-dir", type=output_folder, default=None, help="write one JSON per scenario here")
    reproduce.add_argument(
        "--plots",
        type=output_folder,
        default=None,
        metavar="DIR",
        help="write the paper's figures (Figs. 3-14, 16-21, 23-25) here as PNGs",
    )
    reproduce.set_defaults(handler=reproduce_paper)
    plot = sub.add_parser("plot", help="draw the paper's figures of a run written by run --json")
    plot.add_argument("run", type=Path, help="the run's JSON file")
    plot.add_argument("--out", type=output_folder, required=True, metavar="DIR", help="write the PNGs here")
    plot.set_defaults(handler=_plot)
    compare = sub.add_parser(
        "compare", help="trials to tolerance: ILC against RL and black-box optimizers, across seeds"
    )
    add_compare_arguments(compare)
    compare.set_defaults(handler=_compare)
    sweep = sub.add_parser(
        "sweep", help="robustness map: trials to tolerance over a grid of true plants, a learner per plant"
    )
    add_sweep_arguments(sweep)
    sweep.set_defaults(handler=_sweep)
    session = sub.add_parser(
        "session", help="learn with a robot driven through a folder: new, next, record, withdraw, status"
    )
    add_session_arguments(session)
    current = sub.add_parser(
        "current", help="is a run folder current for the code in this tree? exit 0 if it is, 1 if it is stale"
    )
    current.add_argument(
        "folders", type=Path, nargs="+", metavar="DIR", help="compare or sweep run folders, or folders that hold them"
    )
    current.set_defaults(handler=_current)
    tables = sub.add_parser("tables", help="rewrite the comparison tables of Markdown files from a compare run")
    tables.add_argument("folder", type=Path, metavar="DIR", help="the compare run folder, e.g. results/compare")
    tables.add_argument("--into", type=Path, nargs="+", required=True, metavar="FILE", help="the Markdown files")
    tables.add_argument("--check", action="store_true", help="rewrite nothing; exit 1 if a table differs")
    tables.set_defaults(handler=_tables)
    return parser


def _current(args: argparse.Namespace) -> int:
    from ilc_steering.current import check_folders

    current, lines = check_folders(args.folders)
    print("\n".join(lines), flush=True)
    return 0 if current else 1


def _tables(args: argparse.Namespace) -> int:
    from ilc_steering.compare import tables as compare_tables

    if args.check:
        stale = compare_tables.check(args.folder, args.into)
        for block in stale:
            print(f"{block}: differs from {args.folder}", flush=True)
        if not stale:
            print(f"every comparison table of {' '.join(map(str, args.into))} is {args.folder}'s", flush=True)
        return 1 if stale else 0
    changed = compare_tables.write(args.folder, args.into)
    print(f"rewrote {' '.join(map(str, changed)) or 'nothing'} from {args.folder}", flush=True)
    return 0


def _compare(args: argparse.Namespace) -> int:
    from ilc_steering.compare import command

    return _cells(command, args)


def _sweep(args: argparse.Namespace) -> int:
    from ilc_steering.sweep import command

    return _cells(command, args)


def _cells(command: Any, args: argparse.Namespace) -> int:
    """A run of cells (``compare``'s, or ``sweep``'s rows) by its ``command`` module: 4 if any failed, else 0."""
    _, failed = command.main_with_failures(command.from_namespace(args))
    return 4 if failed else 0


def _list(args: argparse.Namespace) -> int:
    rows = []
    for name in packaged_configs():
        config = load_config(name)
        unit = "cycles" if config.is_cyclic else "trials"
        figures = PAPER.get(name, (None, ""))[1]
        kind = f"{config.plant.model}, {'cyclic, ' if config.is_cyclic else ''}{config.learning.trials} {unit}"
        rows.append((name, kind, figures))
    widths = [max(len(row[i]) for row in rows) for i in (0, 1)]  # columns as wide as their longest entry
    for name, kind, figures in rows:
        print(f"{name:{widths[0]}s}  {kind:{widths[1]}s}  {figures}".rstrip())
    return 0


def _one_line(error: BaseException) -> str:
    text = " ".join(str(error).split())
    return text if len(text) <= 2000 else text[:2000] + " ..."


def main(argv: Sequence[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    handled = threading.current_thread() is threading.main_thread()
    previous = signal.signal(signal.SIGTERM, _terminate) if handled else None
    try:
        return _main(args)
    finally:
        if handled:
            signal.signal(signal.SIGTERM, signal.SIG_DFL if previous is None else previous)


def _main(args: argparse.Namespace) -> int:
    try:
        return int(args.handler(args))
    except KeyboardInterrupt as error:  # run keeps the trials before it, and says where (SIGTERM as Ctrl-C)
        word = "terminated" if isinstance(error, Terminated) else "interrupted"
        print(f"ilc-steering: {word} {_one_line(error)}".rstrip(), file=sys.stderr)
        return 130
    except BrokenPipeError:  # stdout closed early (ilc-steering list | head -1): nothing left to say
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())  # so that the interpreter's final flush does not fail again
        return 0
    except (LearnerError, PlantError) as error:  # the user's learner or plant, named: neither bad input nor a bug
        if args.debug:
            traceback.print_exc()
        print(f"ilc-steering: {_one_line(error)}", file=sys.stderr)
        return 4
    except BadInput as error:  # ConfigError, ParameterError and LimitError included
        if args.debug:
            traceback.print_exc()
        kind = "config error" if isinstance(error, ConfigError) else "error"
        print(f"ilc-steering: {kind}: {_one_line(error)}", file=sys.stderr)
        return 2
    except Exception as error:
        if args.debug:
            traceback.print_exc()
        print(
            f"ilc-steering: internal error: {type(error).__name__}: {_one_line(error)}. This is a bug: please report "
            "it with the command that caused it (--debug prints the traceback).",
            file=sys.stderr,
        )
        return 3


if __name__ == "__main__":
    sys.exit(main())
