"""``ilc-steering session``: a robot driven through a folder, the learner rebuilt from the measurements.

The robot here is section 5's simulated MARIO (:class:`~ilc_steering.lab_robot.LabRobot`) answering
each trial's request from the folder, as a person or a script would; the session's trials must be
the in-process run's, bit for bit. Every refused step leaves the folder as it was.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest
import yaml

from ilc_steering.cli import main
from ilc_steering.config import load_config
from ilc_steering.errors import ConfigError
from ilc_steering.lab_robot import LabRobot
from ilc_steering.runner import run_ilc
from ilc_steering.session_folder import Session

CONFIGS = Path(__file__).resolve().parents[1] / "configs"


def _robot_config(folder: Path) -> Path:
    """experiment_forward on a process plant, measured without simulated noise (a real measurement)."""
    data = yaml.safe_load((CONFIGS / "experiment_forward_process.yaml").read_text())
    data.pop("simulation", None)
    path = folder / "robot.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


def _files(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def _run_robot(session: Session, robot: LabRobot, trials: int) -> None:
    """Each pending trial's request answered by the robot and its final pose recorded."""
    for _ in range(trials):
        replay = session.replay()
        assert replay.pending_folder is not None
        request = json.loads((replay.pending_folder / "request.json").read_text())
        answer = robot.trial(request)
        session.record(answer["final"])


@pytest.fixture
def started(tmp_path: Path) -> Session:
    return Session.new(tmp_path / "s", _robot_config(tmp_path), "ilc_paper", 1, 3)


def test_a_session_gives_the_in_process_trials_bit_for_bit(started: Session) -> None:
    _run_robot(started, LabRobot(load_config("experiment_forward")), 3)
    replay = started.replay()
    assert replay.pending is None
    data = yaml.safe_load((CONFIGS / "experiment_forward.yaml").read_text())
    data.pop("simulation", None)
    reference = run_ilc(data, trials=3, learner="ilc_paper", seed=1)
    assert [t.cartesian_error for t in replay.result.trials] == [t.cartesian_error for t in reference.trials]
    assert [t.orientation_error for t in replay.result.trials] == [t.orientation_error for t in reference.trials]


def test_a_resumed_session_asks_the_same_commands(started: Session, tmp_path: Path) -> None:
    _run_robot(started, LabRobot(load_config("experiment_forward")), 1)
    pending = started.replay().pending_folder
    assert pending is not None
    request = (pending / "request.json").read_bytes()
    moved = tmp_path / "elsewhere"
    started.folder.rename(moved)
    again = Session(moved).replay()
    assert again.pending == 2
    assert again.pending_folder is not None and (again.pending_folder / "request.json").read_bytes() == request


@pytest.mark.parametrize(
    ("final", "needs"),
    [([float("nan"), 0.0, 0.0, 0.0], "finite"), ([0.0, 0.0], "needs 4"), ([50.0, 0.0, 0.0, 0.0], "workspace")],
)
def test_a_bad_pose_is_refused_and_the_session_is_unchanged(started: Session, final: list[float], needs: str) -> None:
    started.replay()  # trial 1's commands written
    before = _files(started.folder)
    with pytest.raises(ValueError, match=needs):
        started.record(final)
    assert _files(started.folder) == before


def test_a_record_without_commands_is_refused(started: Session) -> None:
    before = _files(started.folder)
    with pytest.raises(ValueError, match="session next"):
        started.record([0.0, 0.0, 0.0, 0.0])
    assert _files(started.folder) == before


def test_a_withdrawn_trial_is_asked_again_uncounted(started: Session) -> None:
    _run_robot(started, LabRobot(load_config("experiment_forward")), 1)
    assert len(started.replay().result.trials) == 1
    assert started.withdraw() == 1
    replay = started.replay()
    assert replay.pending == 1 and not replay.result.trials
    withdrawn = sorted(p.name for p in (started.folder / "withdrawn").iterdir())
    assert len(withdrawn) == 2 and withdrawn[0].startswith("0001-") and withdrawn[1].startswith("0002-")


def test_a_trial_recorded_again_after_a_withdrawal_asks_new_commands(
    started: Session, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The next trial's commands were learned from the withdrawn result: they go with it, so a
    different pose recorded in its place asks commands learned from that pose."""
    robot = LabRobot(load_config("experiment_forward"))
    _run_robot(started, robot, 1)
    assert started.replay().pending == 2  # trial 2's commands written, from trial 1's result
    asked = json.loads((started.folder / "trials" / "0002" / "request.json").read_text())["c"]
    started.withdraw()
    assert not (started.folder / "trials" / "0002").exists()
    request = json.loads((started.folder / "trials" / "0001" / "request.json").read_text())
    final = robot.trial(request)["final"]
    started.record([final[0] + 0.01, *final[1:]])  # measured again, a centimetre further
    replay = started.replay()
    assert replay.pending == 2 and replay.pending_folder is not None
    assert json.loads((replay.pending_folder / "request.json").read_text())["c"] != asked
    monkeypatch.setattr("ilc_steering.session_folder._now", lambda: "2026-12-03T00:00:00Z")
    started.withdraw()
    started.record(final)
    started.withdraw()  # twice within one second: both withdrawn results are kept
    assert len(list((started.folder / "withdrawn").glob("0001-*.json"))) == 3


def test_a_replay_that_differs_from_the_record_is_refused(started: Session) -> None:
    _run_robot(started, LabRobot(load_config("experiment_forward")), 1)
    path = started.folder / "trials" / "0001" / "request.json"
    request = json.loads(path.read_text())
    request["c"][0] += 1e-9
    path.write_text(json.dumps(request))
    with pytest.raises(ValueError, match="other coefficients"):
        started.replay()


def test_a_session_needs_a_process_plant(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="plant.model: process"):
        Session.new(tmp_path / "a", CONFIGS / "experiment_forward.yaml", "ilc_paper", 1, None)
    assert not (tmp_path / "a").exists()


@pytest.mark.parametrize(
    ("key", "value"), [("seed", "1"), ("seed", -1), ("trials", 0), ("trials", True), ("learner", 3), ("extra", 1)]
)
def test_a_session_record_edited_by_hand_is_refused_in_one_line(started: Session, key: str, value: object) -> None:
    path = started.folder / "session.json"
    data = json.loads(path.read_text())
    data[key] = value
    path.write_text(json.dumps(data))
    with pytest.raises(ValueError, match="session.json"):
        Session(started.folder)


def test_two_commands_at_once_are_refused(started: Session, capsys: pytest.CaptureFixture[str]) -> None:
    with started.locked():
        assert main(["session", "next", str(started.folder)]) == 2
    assert "another session command" in capsys.readouterr().err
    assert main(["session", "next", str(started.folder)]) == 0


def test_a_dry_run_writes_nothing(started: Session, capsys: pytest.CaptureFixture[str]) -> None:
    before = _files(started.folder)
    assert main(["session", "next", str(started.folder), "--dry-run"]) == 0
    assert "trial 1:" in capsys.readouterr().out
    assert {k: v for k, v in _files(started.folder).items() if k != ".lock"} == before


def test_the_command_line_drives_a_session(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    folder = tmp_path / "s"
    assert main(["session", "new", str(folder), "--config", str(_robot_config(tmp_path)), "--trials", "2"]) == 0
    assert main(["session", "next", str(folder)]) == 0
    assert "trial 1" in capsys.readouterr().out
    assert main(["session", "record", str(folder), "--final", "nan", "0", "0", "0"]) == 2
    assert "finite" in capsys.readouterr().err
    request = json.loads((folder / "trials" / "0001" / "request.json").read_text())
    final = LabRobot(load_config("experiment_forward")).trial(request)["final"]
    assert main(["session", "record", str(folder), "--final", *map(repr, final[:3])]) == 0  # phi: the commanded
    assert main(["session", "status", str(folder), "--json", str(tmp_path / "run.json")]) == 1  # not yet
    assert "1 of 2 trials recorded, trial 2 pending" in capsys.readouterr().out
    assert len(json.loads((tmp_path / "run.json").read_text())["trials"]) == 1
    assert main(["session", "next", "/nonexistent/folder"]) == 2


@pytest.mark.slow
@pytest.mark.parametrize(
    ("experiment", "learner"), [("experiment_forward", "ilc_paper"), ("experiment_parallel", "ilc_paper")]
)
def test_the_experiments_through_a_session_with_mario_as_a_program(
    tmp_path: Path, experiment: str, learner: str
) -> None:
    """Issue 49's proof: a script plays the person, section 5's MARIO runs as a program
    (``python -m ilc_steering.lab_robot``), the library's noise on the recorded poses from its seed;
    the trials are the in-process run's, bit for bit."""
    from ilc_steering.core.cable import Cable

    session = Session.new(tmp_path / "s", CONFIGS / f"{experiment}_process.yaml", learner, 1, None)
    robot = Cable([sys.executable, "-m", "ilc_steering.lab_robot", experiment], str(tmp_path))
    try:
        robot.send({"type": "hello", "protocol": 1, "robot": "car", "dimension": 4}, "the hello")
        robot.receive(600.0, "the hello")
        for _ in range(session.trials):
            replay = session.replay()
            if replay.request is None:
                break
            robot.send(replay.request, "a trial")
            session.record(robot.receive(600.0, "a trial")["final"])
    finally:
        robot.close()
    ours = session.replay(write=False).result
    reference = run_ilc(experiment, learner=learner, seed=1)
    assert [t.cartesian_error for t in ours.trials] == [t.cartesian_error for t in reference.trials]
    assert ours.converged_at == reference.converged_at


def test_a_pose_file_records_the_end_of_a_measured_trajectory(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    folder = tmp_path / "s"
    assert main(["session", "new", str(folder), "--config", str(_robot_config(tmp_path)), "--trials", "2"]) == 0
    assert main(["session", "next", str(folder)]) == 0
    request = json.loads((folder / "trials" / "0001" / "request.json").read_text())
    x, y, theta, phi = LabRobot(load_config("experiment_forward")).trial(request)["final"]
    odometry = tmp_path / "odometry.csv"
    odometry.write_text(f"t,x,y,theta,phi\n0,0,0,0,0\n10,{x!r},{y!r},{theta!r},{phi!r}\n")
    assert main(["session", "record", str(folder), "--pose-file", str(odometry), "--topic", "/odom"]) == 2
    assert "--topic is for a ROS bag" in capsys.readouterr().err
    assert main(["session", "record", str(folder), "--pose-file", str(odometry)]) == 0
    result = json.loads((folder / "trials" / "0001" / "result.json").read_text())
    assert result["final"] == [x, y, theta, phi]


@pytest.mark.parametrize("text", ["{not json", "[1, 2]", '{"type": "result", "trial": 1, "final": "here"}'])
def test_a_result_edited_by_hand_is_refused_naming_the_file(
    started: Session, capsys: pytest.CaptureFixture[str], text: str
) -> None:
    """Bad input in the session's folder: exit 2 naming it, not the learner's fault nor the robot's."""
    _run_robot(started, LabRobot(load_config("experiment_forward")), 1)
    (started.folder / "trials" / "0001" / "result.json").write_text(text)
    assert main(["session", "status", str(started.folder)]) == 2
    err = capsys.readouterr().err
    assert "result.json" in err or "the session's robot" in err, err
    assert "learner" not in err
