"""``ilc-steering session``'s commands: ``new``, ``next``, ``record``, ``withdraw``, ``status`` on a
session folder, each printing what :mod:`ilc_steering.session`'s verb returns (docs/your_robot.md).
``status`` exits as ``run`` does (:data:`STATUS_EXIT_CODES`)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from ilc_steering import session
from ilc_steering.console import check_outputs, print_header, print_row, print_verdict, save
from ilc_steering.core.scatter import HOLD
from ilc_steering.output import output_file, output_folder
from ilc_steering.session_folder import Session

__all__ = ["STATUS_EXIT_CODES", "add_session_arguments"]

STATUS_EXIT_CODES = {
    0: f"converged: the last {HOLD} recorded trials within the tolerance (held)",
    1: "not converged: yet (a trial pending: run it), or within the session's budget (every trial run)",
    5: "converged to the robot's floor: the tolerance is below its repeatability, estimated from the trials, "
    "and the last trials are within that",
    2: "bad input (a folder that is no session, a file of it edited by hand, an argument), or the pending "
    "trial's commands refused for the robot's plant.limits (the line names the recorded pose it was learned from)",
    4: "the learner failed on the recorded trials (a learner of yours: module:attr)",
    3: "internal error: a bug of ilc-steering",
}
"""``session status``'s exit codes, with ``run``'s meanings (:data:`ilc_steering.session.EXIT_CODES` per state)."""


def _summary(request: dict[str, Any]) -> str:
    """A pending trial's commands in one line: its length, the nominal end, the largest inputs."""
    control, nominal = request["control"], request["nominal"]
    end = ", ".join(f"{v:.4g}" for v in nominal["q"][-1])
    peak = max(abs(v) for v in nominal["u1"]), max(abs(v) for v in nominal["u2"])
    return (
        f"{len(control['t'])} samples every {control['dt']:.4g} s; the nominal path ends at ({end}) "
        f"(world frame); largest |u1| {peak[0]:.4g}, |u2| {peak[1]:.4g}"
    )


def _new(args: argparse.Namespace) -> int:
    started = session.new(args.folder, args.config, args.learner, args.seed, args.trials)
    print(f"started a session of {started.learner} (seed {started.seed}, {started.trials} trials) in {started.folder}")
    print(f"next: ilc-steering session next {started.folder}")
    return 0


def _next(args: argparse.Namespace) -> int:
    trial = session.next(args.folder, dry_run=args.dry_run)
    if trial is None:  # exit 1: a script that runs what `next` wrote must not run the last trial again
        print(f"{args.folder}: nothing to run: the session has run its trials; see `session status`", file=sys.stderr)
        return 1
    print(f"trial {trial.trial}: {_summary(trial.request)}")
    if not trial.written:
        print("(a dry run: nothing written)")
        return 0
    if trial.restored:  # cut short, deleted or edited since `next` wrote them: the robot must not play those
        print(f"wrote {' and '.join(trial.restored)} again: they were not this trial's (cut short, deleted, edited)")
    print(f"the commands are in {trial.commands} and request.json")
    print(f"after the run: ilc-steering session record {args.folder} --final X Y THETA [PHI]")
    return 0


def _record(args: argparse.Namespace) -> int:
    state = session.record(args.folder, args.final, pose_file=args.pose_file, topic=args.topic)
    for record in state.trials:
        print_row(record)
    print(f"recorded trial {len(state.trials)}; {_then(state, args.folder)}")
    return 0


def _then(state: session.Status, folder: Path) -> str:
    """What a session's person does next, by its state."""
    if state.state is session.State.REFUSED:
        return f"the next trial is refused: {state.refusal}"
    if state.state in (session.State.CONVERGED, session.State.FLOOR):
        return f"{state.state.value}: see ilc-steering session status {folder}"
    if state.pending is None:
        return f"the session has run its {state.budget} trials without converging; see `session status`"
    return f"next: ilc-steering session next {folder}"


def _withdraw(args: argparse.Namespace) -> int:
    withdrawn = session.withdraw(args.folder)
    print(f"withdrew trial {withdrawn.trial}: it is asked again (ilc-steering session next {args.folder}), uncounted")
    return 0


def _status(args: argparse.Namespace) -> int:
    folder = Session(args.folder)
    check_outputs(args.json, args.plots, [folder.recorded], [], _inputs(folder.folder))
    trajectories = args.json is not None or args.plots is not None
    state = session.status(args.folder, trajectories=trajectories, tensorboard=args.tensorboard)
    print_header(state.result.config, state.budget)
    for record in state.trials:
        print_row(record)
    done = len(state.trials)
    print_verdict(state.result, "trials", done)
    scatter = state.verdict.scatter
    if scatter is not None:
        sigma = ", ".join(f"{k} {v:.2g}" for k, v in scatter.items() if k != "dof")
        print(
            f"the robot's scatter as the trials tell it, per coordinate ({scatter['dof']:g} degrees of freedom): "
            + sigma
        )
    pending = f"trial {state.pending} pending" if state.pending is not None else "every trial run"
    print(f"{state.learner}, seed {state.seed}: {done} of {state.budget} trials recorded, {pending}")
    save(state.result, args.json, args.plots)
    if state.refusal is not None:  # run's refusal for the limits, exit 2 (after the report, as run writes its trials)
        print(f"ilc-steering: error: {state.refusal}", file=sys.stderr, flush=True)
    return state.exit_code


def _inputs(folder: Path) -> list[Path]:
    """The files of the session at ``folder``: none of them is an output."""
    found = [folder / name for name in ("session.json", "config.yaml", ".lock")]
    for part in ("trials", "withdrawn"):
        found += [path for path in (folder / part).rglob("*") if not path.is_dir()]
    return found


def add_session_arguments(parser: argparse.ArgumentParser) -> None:
    """The ``session`` subcommands."""
    sub = parser.add_subparsers(dest="session_command", required=True, metavar="ACTION")
    new = sub.add_parser("new", help="start a session in a new folder from a process-plant config")
    new.add_argument("folder", type=output_folder, metavar="DIR")
    new.add_argument("--config", required=True, help="a config with plant.model: process (a path or a packaged name)")
    new.add_argument("--learner", default="ilc_paper", help="a learner id or module:attr (default: ilc_paper)")
    new.add_argument("--seed", type=int, default=1, help="the learner's seed (default: 1)")
    new.add_argument("--trials", type=int, default=None, help="the budget (default: the config's learning.trials)")
    new.set_defaults(handler=_new)
    step = sub.add_parser("next", help="write the next trial's commands and say where")
    step.add_argument("folder", type=Path, metavar="DIR")
    step.add_argument("--dry-run", action="store_true", help="show the next trial's commands, write nothing")
    step.set_defaults(handler=_next)
    record = sub.add_parser("record", help="record where the robot stopped after the pending trial")
    record.add_argument("folder", type=Path, metavar="DIR")
    where = record.add_mutually_exclusive_group(required=True)
    where.add_argument("--final", type=float, nargs="+", metavar="V", help="x y theta [phi], world frame")
    where.add_argument(
        "--pose-file", type=Path, metavar="PATH", help="its last pose: a CSV (x, y, theta[, phi]) or a ROS bag"
    )
    record.add_argument("--topic", default=None, help="the bag's pose topic (default: its only one)")
    record.set_defaults(handler=_record)
    withdraw = sub.add_parser("withdraw", help="withdraw the last recorded trial (the robot botched it)")
    withdraw.add_argument("folder", type=Path, metavar="DIR")
    withdraw.set_defaults(handler=_withdraw)
    status = sub.add_parser(
        "status",
        help="the trials so far, their errors, and whether it converged (exit 0 converged, 1 not yet, 5 floor)",
        epilog="Exit codes, as run's: " + "; ".join(f"{code} {text}" for code, text in STATUS_EXIT_CODES.items()) + ".",
    )
    status.add_argument("folder", type=Path, metavar="DIR")
    status.add_argument("--json", type=output_file, default=None, help="write the run's JSON here")
    status.add_argument("--plots", type=output_folder, default=None, metavar="DIR", help="write the run's figures here")
    status.add_argument(
        "--tensorboard",
        type=output_folder,
        default=None,
        metavar="DIR",
        help="write the recorded trials as TensorBoard events under DIR/<config>/<learner>_seed<seed> (as run "
        "does; the tensorboard extra)",
    )
    status.set_defaults(handler=_status)
