"""``session status`` exits as ``run`` does, and :mod:`ilc_steering.session` is the API a lab's script drives.

Each session here reaches its state through poses the library's own simulated plant computes:
section 5's MARIO (:class:`~ilc_steering.lab_robot.LabRobot`) answers each trial's request, as the
robot and the person measuring it would. The exit codes are ``run``'s: 0 converged and held, 1 not
converged (yet, or within the budget), 5 the robot's floor, 2 bad input or commands beyond the
robot's limits, 4 the user's learner failed, 3 a bug.
"""

from __future__ import annotations

import doctest
import json
from pathlib import Path
from typing import Any

import pytest
import yaml

from ilc_steering import session
from ilc_steering.cli import main
from ilc_steering.config import load_config
from ilc_steering.errors import BadInput, LimitError
from ilc_steering.lab_robot import LabRobot

CONFIGS = Path(__file__).resolve().parents[1] / "configs"
ROBOT = LabRobot(load_config("experiment_forward"))
TYPED = [0.18, 0.08, 0.0]
"""Trial 1's end typed with a decimal point slipped (MARIO stops near the goal, (1.8, 0.8, 0)): the
paper's law's next step leaves the workspace, as robust_ilc's did after the docs' example's pose
(1.02, 0.43, 0.71) 0.86 m off."""


def robot_config(folder: Path, noise: float | None = None, tolerance: float | None = None) -> Path:
    """experiment_forward on a process plant: measured without noise, or with the library's ``noise``
    [m] (twice that [rad]) on each recorded pose; ``tolerance`` [m] (twice that [rad]) if given."""
    data = yaml.safe_load((CONFIGS / "experiment_forward_process.yaml").read_text())
    data.pop("simulation")
    if noise is not None:
        data["simulation"] = {"measurement_noise": [noise, noise, 2 * noise, 2 * noise]}
    if tolerance is not None:
        data["learning"]["tolerance"] = {"cartesian": tolerance, "orientation": 2 * tolerance}
    path = folder / "robot.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


def drive(folder: Path, trials: int | None = None) -> session.Status:
    """Run and record the pending trials (``trials`` of them, or until the session is not pending)."""
    state = session.status(folder)
    while state.state is session.State.PENDING and (trials is None or len(state.trials) < trials):
        trial = session.next(folder)
        assert trial is not None and trial.commands.is_file()
        state = session.record(folder, ROBOT.trial(trial.request)["final"])
    return state


def status_code(folder: Path, capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    capsys.readouterr()
    code = main(["session", "status", str(folder)])
    out, err = capsys.readouterr()
    return code, out, err


def test_converged_and_held_is_exit_0(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    session.new(tmp_path / "s", robot_config(tmp_path), trials=10)
    state = drive(tmp_path / "s")
    assert state.state is session.State.CONVERGED and state.converged_at == 4 and len(state.trials) == 6
    assert all(t.cartesian_error is not None and t.cartesian_error < 5e-3 for t in state.trials[3:])
    code, out, err = status_code(tmp_path / "s", capsys)
    assert code == 0 and "converged at trial 4 (held for the last 3 trials)" in out and not err


def test_not_yet_converged_is_exit_1_with_a_trial_pending(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    session.new(tmp_path / "s", robot_config(tmp_path), trials=10)
    state = drive(tmp_path / "s", trials=2)
    assert state.state is session.State.PENDING and state.pending == 3 and state.exit_code == 1
    code, out, _ = status_code(tmp_path / "s", capsys)
    assert code == 1 and "2 of 10 trials recorded, trial 3 pending" in out


def test_the_budget_spent_without_converging_is_exit_1(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    session.new(tmp_path / "s", robot_config(tmp_path), trials=3)
    state = drive(tmp_path / "s")
    assert state.state is session.State.SPENT and state.pending is None and state.converged_at is None
    assert session.next(tmp_path / "s") is None
    capsys.readouterr()
    assert main(["session", "next", str(tmp_path / "s")]) == 1  # nothing to run: a loop on `next` stops
    assert "nothing to run: the session has run its trials" in capsys.readouterr().err
    code, out, _ = status_code(tmp_path / "s", capsys)
    assert code == 1 and "not converged within 3 trials" in out and "every trial run" in out


def test_the_robots_floor_is_exit_5(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A tolerance of 0.1 mm on a robot measured with 1 mm of scatter: converged to its floor."""
    session.new(tmp_path / "s", robot_config(tmp_path, noise=1e-3, tolerance=1e-4), trials=12)
    state = drive(tmp_path / "s")
    assert state.state is session.State.FLOOR and state.converged_at is None and state.verdict.floor
    assert state.verdict.scatter is not None and state.verdict.scatter["cartesian"] > 1e-4
    code, out, _ = status_code(tmp_path / "s", capsys)
    assert code == 5 and "converged to the plant's floor" in out


def test_a_pose_typed_wrong_refuses_the_next_trial_naming_the_session_and_the_pose(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Issue 68: the docs once recorded a pose 0.86 m off; the next trial left the workspace and the
    refusal named a robot process that a session never runs. Exit 2, as run's refusal; then withdraw."""
    folder = tmp_path / "mario"
    session.new(folder, robot_config(tmp_path), trials=10)
    assert session.next(folder) is not None
    state = session.record(folder, TYPED)
    assert state.state is session.State.REFUSED and state.exit_code == 2 and state.pending == 2
    with pytest.raises(LimitError, match="plant.limits.workspace: trial 2"):
        session.next(folder)
    code, out, err = status_code(folder, capsys)
    assert code == 2 and "1 of 10 trials recorded, trial 2 pending" in out
    (line,) = err.splitlines()
    assert "plant process" not in line and "lab_robot" not in line
    assert f"the robot of the session {folder}" in line
    assert "trial 1's recorded pose (x, y, θ) = (0.18, 0.08, 0) (world frame), 1.77 m and 0 rad from the goal" in line
    assert f"ilc-steering session withdraw {folder}" in line
    assert session.withdraw(folder) == session.Withdrawn(folder, 1)
    assert drive(folder).state is session.State.CONVERGED  # recorded again as the robot stopped


def test_a_learner_of_yours_that_fails_is_exit_4(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    (tmp_path / "broken_learner.py").write_text(
        "class Broken:\n    def act(self, observation):\n        raise RuntimeError('no commands today')\n\n"
        "    def learn(self, observation, info):\n        pass\n\n    def reset(self):\n        pass\n\n\n"
        "def make(context):\n    return Broken()\n"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    session.new(tmp_path / "s", robot_config(tmp_path), "broken_learner:make", trials=3)
    code, _, err = status_code(tmp_path / "s", capsys)
    assert code == 4 and "broken_learner:make" in err and "no commands today" in err and len(err.splitlines()) == 1


def test_bad_input_is_exit_2_and_a_bug_exit_3(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    code, _, err = status_code(tmp_path, capsys)
    assert code == 2 and "not a session folder" in err
    with pytest.raises(BadInput, match="not a session folder"):
        session.status(tmp_path)
    session.new(tmp_path / "s", robot_config(tmp_path), trials=3)

    def bug(*args: Any, **kwargs: Any) -> Any:
        raise ZeroDivisionError("a bug")

    monkeypatch.setattr("ilc_steering.session_folder.Session.replay", bug)
    code, _, err = status_code(tmp_path / "s", capsys)
    assert code == 3 and "internal error: ZeroDivisionError" in err


def test_status_json_keeps_working_whatever_the_exit(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    session.new(tmp_path / "s", robot_config(tmp_path), trials=10)
    drive(tmp_path / "s", trials=1)
    assert main(["session", "status", str(tmp_path / "s"), "--json", str(tmp_path / "one.json")]) == 1
    drive(tmp_path / "s")
    assert main(["session", "status", str(tmp_path / "s"), "--json", str(tmp_path / "all.json")]) == 0
    ran = json.loads((tmp_path / "all.json").read_text())
    assert len(json.loads((tmp_path / "one.json").read_text())["trials"]) == 1 and len(ran["trials"]) == 6
    assert ran["converged_at"] == 4 and ran["held"] == 3
    assert (tmp_path / "all.json").read_bytes().endswith(b"}\n")  # a file, as every JSON the library writes


def test_every_file_a_session_writes_ends_with_a_newline(tmp_path: Path) -> None:
    text = robot_config(tmp_path).read_text().rstrip("\n")
    (tmp_path / "bare.yaml").write_text(text)  # a config without its last newline
    session.new(tmp_path / "s", tmp_path / "bare.yaml", trials=3)
    drive(tmp_path / "s", trials=1)
    session.next(tmp_path / "s")
    session.withdraw(tmp_path / "s")
    written = [p for p in (tmp_path / "s").rglob("*") if p.is_file() and p.name != ".lock"]
    names = {p.name for p in written}
    assert {"session.json", "config.yaml", "request.json", "commands.csv"} <= names
    assert any(p.parent.name == "withdrawn" for p in written)
    assert [p for p in written if not p.read_bytes().endswith(b"\n")] == []
    assert json.loads((tmp_path / "s" / "trials" / "0001" / "request.json").read_text())["trial"] == 1


def test_a_request_written_before_the_newline_is_still_the_trials(tmp_path: Path) -> None:
    """A session asked before issue 68 wrote request.json without its newline: still intact, not rewritten."""
    session.new(tmp_path / "s", robot_config(tmp_path), trials=3)
    trial = session.next(tmp_path / "s")
    assert trial is not None
    path = trial.folder / "request.json"
    path.write_text(path.read_text().rstrip("\n"))
    again = session.next(tmp_path / "s")
    assert again is not None and again.restored == () and not path.read_text().endswith("\n")
    assert session.record(tmp_path / "s", ROBOT.trial(trial.request)["final"]).pending == 2


def test_record_takes_one_pose_and_a_topic_only_with_a_pose_file(tmp_path: Path) -> None:
    session.new(tmp_path / "s", robot_config(tmp_path), trials=3)
    for kwargs in ({}, {"final": [1.8, 0.8, 0.0], "pose_file": tmp_path / "p.csv"}, {"final": [1.8], "topic": "/x"}):
        with pytest.raises(BadInput):
            session.record(tmp_path / "s", **kwargs)


def test_the_api_example_runs() -> None:
    results = doctest.testmod(session, raise_on_error=False)
    assert results.attempted >= 8 and results.failed == 0
