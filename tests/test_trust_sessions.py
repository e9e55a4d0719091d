"""A session folder as a hostile person leaves it (issue 64): every case ends in one line, exit 2 (or
0), with the folder as it was, and a folder edited by hand is named for what was changed.

The robot is section 5's simulated MARIO (:class:`~ilc_steering.lab_robot.LabRobot`), answering
each request in this process; no program is started (a session runs none).
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
from pathlib import Path
from typing import Any

import pytest
import yaml

from ilc_steering.cli import main
from ilc_steering.config import load_config
from ilc_steering.lab_robot import LabRobot
from ilc_steering.session_folder import Session

CONFIGS = Path(__file__).resolve().parents[1] / "configs"
ROBOT = LabRobot(load_config("experiment_forward"))


def robot_config(folder: Path, **plant: Any) -> Path:
    """experiment_forward on a process plant, measured without simulated noise, ``plant`` keys changed."""
    data = yaml.safe_load((CONFIGS / "experiment_forward_process.yaml").read_text())
    data.pop("simulation", None)
    data["plant"].update(plant)
    path = folder / "robot.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


def files(folder: Path) -> dict[str, bytes]:
    """Every file under ``folder`` but the lock, with its bytes."""
    return {
        str(p.relative_to(folder)): p.read_bytes()
        for p in sorted(folder.rglob("*"))
        if p.is_file() and not p.is_symlink() and p.name != ".lock"
    }


def refused(argv: list[str], capsys: pytest.CaptureFixture[str], folder: Path | None = None) -> str:
    """Run ``argv``: exit 2, one line on stderr (returned), ``folder`` as it was."""
    before = files(folder) if folder is not None else None
    capsys.readouterr()
    code = main(argv)
    err = capsys.readouterr().err
    assert code == 2, (argv, code, err)
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    if folder is not None:
        assert files(folder) == before
    return err


def answer(folder: Path, k: int) -> list[float]:
    """Where MARIO stops after trial ``k``'s request."""
    request = json.loads((folder / "trials" / f"{k:04d}" / "request.json").read_text())
    return list(ROBOT.trial(request)["final"])


def record(folder: Path, trials: int) -> None:
    """``trials`` trials asked, run and recorded through the command line."""
    for _ in range(trials):
        assert main(["session", "next", str(folder)]) == 0
        k = len(list((folder / "trials").glob("*/result.json"))) + 1
        assert main(["session", "record", str(folder), "--final", *map(repr, answer(folder, k))]) == 0


@pytest.fixture
def session(tmp_path: Path) -> Path:
    folder = tmp_path / "s"
    assert main(["session", "new", str(folder), "--config", str(robot_config(tmp_path)), "--trials", "3"]) == 0
    return folder


# -- nothing an output names is an input ---------------------------------------------------------


@pytest.mark.parametrize("name", ["session.json", "config.yaml", ".lock", "trials/0001/request.json", "link"])
def test_status_json_onto_a_file_of_the_session_is_refused_and_the_session_kept(session, capsys, name):
    record(session, 1)
    (session / "link").symlink_to(session / "session.json")
    err = refused(["session", "status", str(session), "--json", str(session / name)], capsys, session)
    assert "which this command reads" in err
    assert main(["session", "status", str(session)]) == 1  # 1 of 3 trials: not converged yet


def test_run_json_onto_its_config_or_its_program_is_refused_and_both_kept(tmp_path, capsys):
    config = tmp_path / "fp.yaml"
    config.write_text((CONFIGS / "forward_parking.yaml").read_text())
    os.link(config, tmp_path / "hard.yaml")
    for target in (config, tmp_path / "hard.yaml"):
        err = refused(["run", str(config), "--json", str(target)], capsys, tmp_path)
        assert f"--json {target}: is {config}" in err
    program = tmp_path / "robot.py"
    program.write_text("print('a robot')\n")
    robot = robot_config(tmp_path, command=["python", "robot.py"])
    refused(["run", str(robot), "--json", str(program)], capsys, tmp_path)


def test_plot_onto_its_own_run_file_is_refused(tmp_path, capsys):
    run = tmp_path / "forward_parking_errors.png"  # a run file named as one of its figures
    assert main(["run", "forward_parking", "--trials", "3", "--json", str(run)]) in (0, 1)
    refused(["plot", str(run), "--out", str(tmp_path)], capsys, tmp_path)


# -- every change to the folder, all or none -----------------------------------------------------


@pytest.mark.parametrize("kind", ["file", "fifo", "dangling link", "rename fails"])
def test_a_withdrawal_that_cannot_be_made_changes_nothing(session, capsys, monkeypatch, kind):
    record(session, 2)
    assert main(["session", "next", str(session)]) == 0  # trial 3's folder: it moves too
    withdrawn = session / "withdrawn"
    if kind == "file":
        withdrawn.write_text("notes")
    elif kind == "fifo":
        os.mkfifo(withdrawn)
    elif kind == "dangling link":
        withdrawn.symlink_to(session / "nowhere")
    else:  # the second move fails (another file system, a folder read-only): the first is undone
        real, calls = os.rename, []

        def rename(source: Any, target: Any) -> None:
            calls.append(source)
            if len(calls) == 2:
                raise OSError(18, "Invalid cross-device link", str(target))
            real(source, target)

        monkeypatch.setattr(os, "rename", rename)
    err = refused(["session", "withdraw", str(session)], capsys, session)
    assert "nothing was changed" in err or "withdrawn" in err
    monkeypatch.undo()
    assert (session / "trials" / "0002" / "result.json").is_file() and (session / "trials" / "0003").is_dir()
    assert "2 of 3 trials recorded" in _status(session, capsys)


def _status(folder: Path, capsys: pytest.CaptureFixture[str]) -> str:
    capsys.readouterr()
    assert main(["session", "status", str(folder)]) == 1  # these sessions stop before converging
    return capsys.readouterr().out


@pytest.mark.parametrize("seed", ["-1", "1.5", "x"])
def test_session_new_with_a_bad_seed_writes_nothing_and_a_retry_starts_it(tmp_path, capsys, seed):
    config, folder = robot_config(tmp_path), tmp_path / "s"
    capsys.readouterr()
    try:
        code = main(["session", "new", str(folder), "--config", str(config), "--seed", seed])
    except SystemExit as stopped:  # not a whole number: the parser's refusal
        code = stopped.code
    assert code == 2 and len(capsys.readouterr().err.splitlines()) == 1
    assert not folder.exists()
    assert main(["session", "new", str(folder), "--config", str(config), "--seed", "2"]) == 0


@pytest.mark.parametrize("kind", ["file", "loop", "not empty", "under a file"])
def test_session_new_where_no_session_can_start_is_refused_in_one_line(tmp_path, capsys, kind):
    folder = tmp_path / "s"
    if kind == "file":
        folder.write_text("a file")
    elif kind == "loop":
        folder.symlink_to(folder)
    elif kind == "not empty":
        folder.mkdir()
        (folder / "notes.txt").write_text("mine")
    else:
        (tmp_path / "f").write_text("a file")
        folder = tmp_path / "f" / "s"
    refused(["session", "new", str(folder), "--config", str(robot_config(tmp_path))], capsys, tmp_path)


def test_session_new_that_fails_halfway_leaves_no_folder(tmp_path, monkeypatch):
    import ilc_steering.output as output

    real, written = output.write_atomic, []

    def write_atomic(path: Path, content: Any) -> None:
        written.append(path)
        if len(written) == 2:
            raise OSError(28, "No space left on device", str(path))
        real(path, content)

    monkeypatch.setattr(output, "write_atomic", write_atomic)
    with pytest.raises(ValueError, match="No space left"):
        Session.new(tmp_path / "a" / "b" / "s", robot_config(tmp_path), "ilc_paper", 1, 3)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["robot.yaml"]


def test_a_session_runs_no_program_a_relative_or_a_missing_one(tmp_path, capsys):
    (tmp_path / "robot.sh").write_text("#!/bin/sh\n")
    (tmp_path / "robot.sh").chmod(0o755)
    config = robot_config(tmp_path, command=["./robot.sh"])  # as the docs show: beside the config
    assert main(["session", "new", str(tmp_path / "s"), "--config", str(config), "--trials", "3"]) == 0
    record(tmp_path / "s", 1)
    (tmp_path / "robot.sh").unlink()  # the session copied to a machine without the robot program
    record(tmp_path / "s", 1)
    assert "2 of 3 trials recorded" in _status(tmp_path / "s", capsys)


def test_a_record_the_learner_fails_on_leaves_no_result(session, monkeypatch):
    from ilc_steering import session_folder as module
    from ilc_steering.errors import LearnerError

    assert main(["session", "next", str(session)]) == 0
    final = answer(session, 1)
    real = module.run_ilc

    def failing(config: Any, **kwargs: Any) -> Any:
        if config.plant.candidate is not None:
            raise LearnerError("learner ilc_paper failed in learn() on trial 1")
        return real(config, **kwargs)

    monkeypatch.setattr(module, "run_ilc", failing)
    with pytest.raises(LearnerError):
        Session(session).record(final)
    assert not (session / "trials" / "0001" / "result.json").exists()


# -- a folder edited by hand is named for what changed ------------------------------------------


def _edit_result(folder: Path) -> str:
    path = folder / "trials" / "0001" / "result.json"
    data = json.loads(path.read_text())
    data["final"][0] += 0.01
    path.write_text(json.dumps(data))
    return "edited by hand after `session record` wrote it"


def _swap_config(folder: Path) -> str:
    path = folder / "config.yaml"
    path.write_text(path.read_text().replace("cartesian: 0.005", "cartesian: 0.006"))
    return "not the config this session was started with"


def _delete_result(folder: Path) -> str:
    (folder / "trials" / "0001" / "result.json").unlink()
    return "a result deleted by hand"


def _edit_request(folder: Path) -> str:
    path = folder / "trials" / "0001" / "request.json"
    data = json.loads(path.read_text())
    data["c"][1] *= 1.01
    path.write_text(json.dumps(data))
    return "deleted or edited by hand"


def _lose_a_key(folder: Path) -> str:
    path = folder / "trials" / "0001" / "request.json"
    data = json.loads(path.read_text())
    del data["c"]
    path.write_text(json.dumps(data))
    return "deleted or edited by hand"


def _bad_learner(folder: Path) -> str:
    path = folder / "session.json"
    path.write_text(path.read_text().replace('"ilc_paper"', '"no_such_learner"'))
    return "session.json: learner: unknown learner 'no_such_learner'"


def _fifo(folder: Path) -> str:
    (folder / "session.json").unlink()
    os.mkfifo(folder / "session.json")
    return "session.json: is a FIFO, not a regular file"


def _loop(folder: Path) -> str:
    path = folder / "trials" / "0002" / "result.json"
    path.unlink()
    path.symlink_to(path)
    return "result.json: cannot read it: Too many levels of symbolic links"


EDITS = [_edit_result, _swap_config, _delete_result, _edit_request, _lose_a_key, _bad_learner, _fifo, _loop]


@pytest.mark.parametrize("edit", EDITS, ids=[edit.__name__.strip("_") for edit in EDITS])
@pytest.mark.parametrize("command", ["next", "status", "record"])
def test_a_folder_edited_by_hand_is_named_for_what_changed(session, capsys, edit, command):
    record(session, 2)
    says = edit(session)
    argv = ["session", command, str(session), *(["--final", "0", "0", "0"] if command == "record" else [])]
    err = refused(argv, capsys, session)
    assert says in err and "another version" not in err and "--learner" not in err


def test_a_replay_that_differs_only_by_the_library_names_the_versions(session, capsys):
    """A request and its result as ``record`` wrote them, by another version asking other coefficients."""
    from ilc_steering.output import content_hash

    record(session, 1)
    request, result = session / "trials" / "0001" / "request.json", session / "trials" / "0001" / "result.json"
    asked, answered = json.loads(request.read_text()), json.loads(result.read_text())
    asked["c"][1] *= 1.01
    answered["recorded"].update(request=content_hash(asked["c"]), version="0.0.1")
    request.write_text(json.dumps(asked))
    result.write_text(json.dumps(answered))
    err = refused(["session", "status", str(session)], capsys, session)
    assert "recorded by ilc-steering 0.0.1, this is" in err


# -- the pending trial's files ------------------------------------------------------------------


@pytest.mark.parametrize("damage", ["cut short", "deleted", "a key lost"])
def test_a_pending_trials_damaged_files_are_written_again_by_next_and_refused_by_record(session, capsys, damage):
    assert main(["session", "next", str(session)]) == 0
    trial = session / "trials" / "0001"
    whole = {name: (trial / name).read_bytes() for name in ("commands.csv", "request.json")}
    if damage == "cut short":
        (trial / "commands.csv").write_bytes(whole["commands.csv"][:5000])
    elif damage == "deleted":
        (trial / "commands.csv").unlink()
    else:
        data = json.loads(whole["request.json"])
        del data["nominal"]
        (trial / "request.json").write_text(json.dumps(data))
    err = refused(
        [
            "session",
            "record",
            str(session),
            "--final",
            *map(repr, ROBOT.trial(json.loads(whole["request.json"]))["final"]),
        ],
        capsys,
        session,
    )
    assert "run `session next` to write them again" in err
    capsys.readouterr()
    assert main(["session", "next", str(session)]) == 0
    assert "again: they were not this trial's" in capsys.readouterr().out
    assert {name: (trial / name).read_bytes() for name in whole} == whole


# -- status writes what plot reads; an archived session is read ----------------------------------


@pytest.mark.slow  # over 2.5 s: the README's test command stays under 5 min
def test_status_json_and_plots_are_a_run_record_that_plot_reads(session, tmp_path, capsys):
    record(session, 3)
    assert (
        main(["session", "status", str(session), "--json", str(tmp_path / "run.json"), "--plots", str(tmp_path / "f")])
        == 1  # every trial of 3 run, not converged: written all the same, as run writes its trials
    )
    assert len(list((tmp_path / "f").glob("*.png"))) == 4
    shutil.rmtree(tmp_path / "f")
    assert main(["plot", str(tmp_path / "run.json"), "--out", str(tmp_path / "f")]) == 0


def test_a_read_only_session_is_read(session, tmp_path, capsys):
    record(session, 1)
    archive = tmp_path / "archive"
    archive.mkdir()
    if os.geteuid() != 0:
        shutil.copytree(session, archive / "s")
        for path in [archive / "s", *(archive / "s").rglob("*")]:
            path.chmod(path.stat().st_mode & ~0o222)
    else:  # root writes through permissions: a read-only mount, where mounts can be made
        mounted = subprocess.run(
            ["mount", "--bind", "-o", "ro", str(session.parent), str(archive)], capture_output=True
        )
        if mounted.returncode != 0:
            pytest.skip("root, and no read-only mount can be made here")
    try:
        assert "1 of 3 trials recorded" in _status(archive / "s", capsys)
        assert main(["session", "next", str(archive / "s"), "--dry-run"]) == 0
        refused(["session", "withdraw", str(archive / "s")], capsys)
    finally:
        if os.geteuid() == 0:
            subprocess.run(["umount", str(archive)], check=True)
