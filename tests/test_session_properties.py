"""A hostile person at a session folder: any sequence of commands, right or wrong, leaves the
session consistent (issue 49).

A state machine drives ``ilc-steering session`` as a person might: ``next`` at any time, a record
of the robot's true end, a record of garbage (not a number, infinite, too short, a kilometre
away), a record twice or before ``next``, a withdrawal, ``status``, a command while another holds
the folder, ``session.json`` or a result edited by hand. After every step:

- a command that is refused exits 2 with exactly one line on stderr, and the folder is as it was;
- a command that is accepted exits 0 and does what it says;
- the recorded trials are the in-process run's first trials, bit for bit (section 5's simulated
  MARIO answers every request, so a session that lost or garbled nothing replays the same run).
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import yaml
from hypothesis import HealthCheck, settings
from hypothesis import strategies as st
from hypothesis.stateful import RuleBasedStateMachine, initialize, invariant, rule

from ilc_steering import session
from ilc_steering.cli import main
from ilc_steering.config import load_config
from ilc_steering.lab_robot import LabRobot
from ilc_steering.runner import run_ilc
from ilc_steering.session_folder import Session

CONFIGS = Path(__file__).resolve().parents[1] / "configs"
BUDGET = 3

GARBAGE = [
    ["nan", "0", "0", "0"],
    ["inf", "0", "0"],
    ["1e400", "0", "0"],
    ["0", "0"],
    ["0", "0", "0", "0", "0"],
    ["1000", "0", "0"],
]
"""Poses a person may type that are not a pose of this robot in its workspace."""
EDITS = [
    ("session.json", "{"),
    ("session.json", "[]"),
    ("session.json", '{"learner": "ilc_paper"}'),
    ("config.yaml", "plant: [unclosed"),
    ("trials/0001/result.json", '{"type": "result", "trial": 1, "final": "here"}'),
    ("trials/0001/request.json", "{not json"),
]
"""Files edited by hand into something else (a result or request only where it exists)."""


def _config(folder: Path) -> Path:
    data = yaml.safe_load((CONFIGS / "experiment_forward_process.yaml").read_text())
    data.pop("simulation", None)  # a real measurement: no simulated noise
    path = folder / "robot.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


def _reference() -> list[tuple[float | None, float | None]]:
    data = yaml.safe_load((CONFIGS / "experiment_forward.yaml").read_text())
    data.pop("simulation", None)
    trials = run_ilc(data, trials=BUDGET, learner="ilc_paper", seed=1).trials
    return [(t.cartesian_error, t.orientation_error) for t in trials]


def _files(folder: Path) -> dict[str, bytes]:
    return {
        str(p.relative_to(folder)): p.read_bytes()
        for p in sorted(folder.rglob("*"))
        if p.is_file() and p.name != ".lock"
    }


class HostilePerson(RuleBasedStateMachine):
    """A person at the session's folder, and what the session should then be."""

    def __init__(self) -> None:
        super().__init__()
        self.robot = LabRobot(load_config("experiment_forward"))

    @initialize()
    def start(self) -> None:
        self.root = Path(self._tmp.mktemp("person"))
        self.folder = self.root / "s"
        assert (
            main(["session", "new", str(self.folder), "--config", str(_config(self.root)), "--trials", str(BUDGET)])
            == 0
        )
        self.recorded = 0  # trials with a result
        self.asked = False  # the pending trial's commands are written

    def _refused(self, argv: list[str]) -> None:
        before = _files(self.folder)
        self._capsys.readouterr()
        try:
            code = main(argv)
        except SystemExit as stopped:  # the argument parser's refusal
            code = stopped.code
        err = self._capsys.readouterr().err
        assert code == 2, (argv, code, err)
        assert len(err.splitlines()) == 1 and "Traceback" not in err, (argv, err)
        assert _files(self.folder) == before, argv

    def _accepted(self, argv: list[str]) -> str:
        self._capsys.readouterr()
        code = main(argv)
        out, err = self._capsys.readouterr()
        assert code == 0, (argv, code, err)
        return out

    @rule()
    def ask(self) -> None:
        argv = ["session", "next", str(self.folder)]
        if self.recorded < BUDGET:
            assert f"trial {self.recorded + 1}:" in self._accepted(argv)
            self.asked = True
        else:  # nothing to run: exit 1, one line, nothing written
            before = _files(self.folder)
            self._capsys.readouterr()
            assert main(argv) == 1
            (line,) = self._capsys.readouterr().err.splitlines()
            assert "nothing to run: the session has run its trials" in line and _files(self.folder) == before

    @rule()
    def record_the_robots_end(self) -> None:
        argv = ["session", "record", str(self.folder), "--final"]
        if not self.asked or self.recorded == BUDGET:  # before next, twice, or after the last trial
            self._refused([*argv, "0", "0", "0"])
            return
        request = json.loads((self.folder / "trials" / f"{self.recorded + 1:04d}" / "request.json").read_text())
        self._accepted([*argv, *map(repr, self.robot.trial(request)["final"])])
        self.recorded += 1
        self.asked = False  # the next trial's commands are not written until `next`

    @rule()
    def run_a_trial(self) -> None:
        """What the person should do: ask, let the robot run, record."""
        self.ask()
        if self.recorded < BUDGET:
            self.record_the_robots_end()

    @rule(pose=st.sampled_from(GARBAGE), asked_first=st.booleans())
    def record_garbage(self, pose: list[str], asked_first: bool) -> None:
        if asked_first:
            self.ask()
        self._refused(["session", "record", str(self.folder), "--final", *pose])

    @rule()
    def withdraw(self) -> None:
        if self.recorded == 0:
            self._refused(["session", "withdraw", str(self.folder)])
            return
        self._accepted(["session", "withdraw", str(self.folder)])
        self.recorded -= 1
        self.asked = True  # the withdrawn trial's commands are still there: it is asked again

    @rule()
    def status(self) -> None:
        self._capsys.readouterr()
        code = main(["session", "status", str(self.folder)])
        out, err = self._capsys.readouterr()
        assert code in (0, 1, 5) and code == session.status(self.folder).exit_code, (code, err)  # run's codes
        assert f"{self.recorded} of {BUDGET} trials recorded" in out

    @rule(command=st.sampled_from(["next", "status", "withdraw"]))
    def while_another_command_runs(self, command: str) -> None:
        with Session(self.folder).locked():
            self._refused(["session", command, str(self.folder)])

    @rule(edit=st.sampled_from(EDITS), command=st.sampled_from(["next", "status", "withdraw"]))
    def edit_a_file_by_hand(self, edit: tuple[str, str], command: str) -> None:
        path = self.folder / edit[0]
        if not path.exists():
            return
        kept = path.read_bytes()
        path.write_text(edit[1])
        try:
            if command == "withdraw" and edit[0].startswith("trials/"):
                return  # withdraw reads no trial's files: it moves the last result away, as asked
            self._refused(["session", command, str(self.folder)])
        finally:
            path.write_bytes(kept)

    @invariant()
    def the_recorded_trials_are_the_runs(self) -> None:
        if not hasattr(self, "folder"):
            return
        trials = Session(self.folder).replay(write=False).result.trials
        assert [(t.cartesian_error, t.orientation_error) for t in trials] == REFERENCE[: self.recorded]


REFERENCE = _reference()


@pytest.mark.filterwarnings("ignore::DeprecationWarning")
@pytest.mark.parametrize(
    ("examples", "steps"),
    [(3, 8), pytest.param(60, 20, marks=pytest.mark.slow)],  # the fast tier a few sequences, the slow tier many
    ids=["small", "large"],
)
def test_a_hostile_person_leaves_the_session_consistent(examples, steps, tmp_path_factory, capsys):
    HostilePerson._tmp = tmp_path_factory
    HostilePerson._capsys = capsys
    runner = HostilePerson.TestCase
    runner.settings = settings(
        max_examples=examples, stateful_step_count=steps, deadline=None, suppress_health_check=list(HealthCheck)
    )
    runner().runTest()
