"""``ilc-steering session``'s commands: ``new``, ``next``, ``record``, ``withdraw``, ``status`` on a
session folder (:mod:`ilc_steering.session`; docs/your_robot.md)."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from ilc_steering.console import check_outputs, print_header, print_row, print_verdict, save
from ilc_steering.errors import BadInput
from ilc_steering.output import output_file, output_folder
from ilc_steering.pose_files import final_pose
from ilc_steering.session import Session

__all__ = ["add_session_arguments"]


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
    session = Session.new(args.folder, args.config, args.learner, args.seed, args.trials)
    print(f"started a session of {session.learner} (seed {session.seed}, {session.trials} trials) in {session.folder}")
    print(f"next: ilc-steering session next {session.folder}")
    return 0


def _next(args: argparse.Namespace) -> int:
    session = Session(args.folder)
    with session.locked(write=not args.dry_run):
        replay = session.replay(write=not args.dry_run)
    if replay.refused is not None:
        raise replay.refused
    if replay.pending_folder is None or replay.request is None:
        print(f"{args.folder}: the session has run its {session.trials} trials; see `session status`")
        return 0
    print(f"trial {replay.pending}: {_summary(replay.request)}")
    if args.dry_run:
        print("(a dry run: nothing written)")
        return 0
    if replay.restored:  # cut short, deleted or edited since `next` wrote them: the robot must not play those
        print(f"wrote {' and '.join(replay.restored)} again: they were not this trial's (cut short, deleted, edited)")
    print(f"the commands are in {replay.pending_folder}/commands.csv and request.json")
    print(f"after the run: ilc-steering session record {args.folder} --final X Y THETA [PHI]")
    return 0


def _record(args: argparse.Namespace) -> int:
    session = Session(args.folder)
    if args.topic is not None and args.pose_file is None:
        raise BadInput("--topic: names a topic of --pose-file's bag; give --pose-file")
    kind = session.config.plant.kind
    final = args.final if args.pose_file is None else final_pose(args.pose_file, args.topic, kind)
    with session.locked():
        replay = session.record(final)
    for record in replay.result.trials:
        print_row(record)
    print(f"recorded trial {len(replay.result.trials)}; next: ilc-steering session next {args.folder}")
    return 0


def _withdraw(args: argparse.Namespace) -> int:
    session = Session(args.folder)
    with session.locked():
        k = session.withdraw()
    print(f"withdrew trial {k}: it is asked again (ilc-steering session next {args.folder}), uncounted")
    return 0


def _status(args: argparse.Namespace) -> int:
    session = Session(args.folder)
    with session.locked(write=False):
        check_outputs(args.json, args.plots, [session.recorded], [], _inputs(session.folder))
        replay = session.replay(write=False, paths=args.json is not None or args.plots is not None)
    print_header(session.config, session.trials)
    for record in replay.result.trials:
        print_row(record)
    done = len(replay.result.trials)
    print_verdict(replay.result, "trials", done)
    scatter = replay.result.verdict.scatter
    if scatter is not None:
        sigma = ", ".join(f"{k} {v:.2g}" for k, v in scatter.items() if k != "dof")
        print(
            f"the robot's scatter as the trials tell it, per coordinate ({scatter['dof']:g} degrees of freedom): "
            + sigma
        )
    pending = f"trial {replay.pending} pending" if replay.pending is not None else "every trial run"
    print(f"{session.learner}, seed {session.seed}: {done} of {session.trials} trials recorded, {pending}")
    save(replay.result, args.json, args.plots)
    return 0


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
    status = sub.add_parser("status", help="the trials so far, their errors, and whether it converged")
    status.add_argument("folder", type=Path, metavar="DIR")
    status.add_argument("--json", type=output_file, default=None, help="write the run's JSON here")
    status.add_argument("--plots", type=output_folder, default=None, metavar="DIR", help="write the run's figures here")
    status.set_defaults(handler=_status)
