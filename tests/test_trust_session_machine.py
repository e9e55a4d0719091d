"""A hostile person at a session folder, as issue 64 found one: any sequence of the session verbs and
of hand edits ends each command in one line with exit 2, the folder as it was, or in success.

Beyond issue 49's person (``tests/test_session_properties.py``) this one types poses as programs print
them (``repr``, ``%g``, ``%e``, small negatives, a heading a turn off), headings in degrees, and edits
the folder by hand the ways that were misread: a result edited or deleted under a later trial, the
config swapped, a pending trial's commands cut short, ``withdrawn`` made a file, a status written
onto the session's own files. After every step the recorded results are exactly the poses typed.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import pytest
import yaml
from hypothesis import HealthCheck, settings
from hypothesis import strategies as st
from hypothesis.stateful import RuleBasedStateMachine, initialize, invariant, rule

from ilc_steering import session
from ilc_steering.cli import main
from ilc_steering.config import load_config
from ilc_steering.lab_robot import LabRobot

CONFIGS = Path(__file__).resolve().parents[1] / "configs"
BUDGET = 3
FORMATS = {"repr": repr, "%g": "{:g}".format, "%.17g": "{:.17g}".format, "%e": "{:e}".format}


def _files(folder: Path) -> dict[str, bytes]:
    return {
        str(p.relative_to(folder)): p.read_bytes()
        for p in sorted(folder.rglob("*"))
        if p.is_file() and not p.is_symlink() and p.name != ".lock"
    }


def _cut_commands(folder: Path, pending: int) -> tuple[Path, set[str]]:
    path = folder / "trials" / f"{pending:04d}" / "commands.csv"
    path.write_bytes(path.read_bytes()[:2000])
    return path, {"record"}  # next writes it again (the person sees it said), status reads on


def _withdrawn_file(folder: Path, pending: int) -> tuple[Path, set[str]]:
    path = folder / "withdrawn"
    if path.exists():
        return path, set()
    path.write_text("notes")
    return path, {"withdraw"}


def _edit_result(folder: Path, pending: int) -> tuple[Path, set[str]]:
    path = folder / "trials" / "0001" / "result.json"
    data = json.loads(path.read_text())
    data["final"][1] += 0.001
    path.write_text(json.dumps(data))
    return path, {"next", "status", "record"}


def _swap_config(folder: Path, pending: int) -> tuple[Path, set[str]]:
    path = folder / "config.yaml"
    path.write_text(path.read_text().replace("speed: 2.0", "speed: 3.0"))
    return path, {"next", "status", "record", "withdraw"}


EDITS = {"cut_commands": _cut_commands, "withdrawn_file": _withdrawn_file, "edit_result": _edit_result}
EDITS["swap_config"] = _swap_config


class HostilePerson(RuleBasedStateMachine):
    """A person at the session's folder (see the module)."""

    _tmp: Any
    _capsys: Any

    def __init__(self) -> None:
        super().__init__()
        self.robot = LabRobot(load_config("experiment_forward"))

    @initialize()
    def start(self) -> None:
        root = Path(self._tmp.mktemp("person"))
        data = yaml.safe_load((CONFIGS / "experiment_forward_process.yaml").read_text())
        data.pop("simulation", None)
        (root / "robot.yaml").write_text(yaml.safe_dump(data))
        self.folder = root / "s"
        assert self._run(["session", "new", str(self.folder), "--config", str(root / "robot.yaml")], BUDGET) == 0
        self.typed: list[list[float]] = []  # what was recorded, trial by trial
        self.asked = False

    def _run(self, argv: list[str], trials: int | None = None) -> int:
        self._capsys.readouterr()
        try:
            code = main(argv + (["--trials", str(trials)] if trials else []))
        except SystemExit as stopped:
            code = stopped.code
        self.err = self._capsys.readouterr().err
        return int(code)

    def _refused(self, argv: list[str]) -> None:
        before = _files(self.folder)
        code = self._run(argv)
        assert code == 2 and len(self.err.splitlines()) == 1 and "Traceback" not in self.err, (argv, self.err)
        assert _files(self.folder) == before, argv

    def _accepted(self, argv: list[str]) -> None:
        assert self._run(argv) == 0, (argv, self.err)

    @rule()
    def ask(self) -> None:
        argv = ["session", "next", str(self.folder)]
        if len(self.typed) < BUDGET:
            self._accepted(argv)
            self.asked = True
        else:  # the budget spent: nothing to run, exit 1 in one line, nothing written
            before = _files(self.folder)
            assert self._run(argv) == 1 and len(self.err.splitlines()) == 1, (argv, self.err)
            assert _files(self.folder) == before
            self.asked = False

    @rule(show=st.sampled_from(sorted(FORMATS)), turns=st.sampled_from([0, 0, 1, -1]))
    def record_as_a_program_prints_it(self, show: str, turns: int) -> None:
        argv = ["session", "record", str(self.folder), "--final"]
        if not self.asked:
            self._refused([*argv, "0", "0", "-1e-05"])
            return
        request = json.loads((self.folder / "trials" / f"{len(self.typed) + 1:04d}" / "request.json").read_text())
        final = self.robot.trial(request)["final"]
        final[2] += 2 * math.pi * turns  # theta and phi end near 0: small negatives, in exponent form too
        printed = [FORMATS[show](v) for v in final]
        self._accepted([*argv, *printed])
        self.typed.append([float(v) for v in printed])
        self.asked = False

    @rule(show=st.sampled_from(sorted(FORMATS)), turns=st.sampled_from([0, 1, -1]))
    def run_a_trial(self, show: str, turns: int) -> None:
        """What the person should do: ask, let the robot run, record what its script prints."""
        self.ask()
        if self.asked:
            self.record_as_a_program_prints_it(show, turns)

    @rule(heading=st.sampled_from(["45", "1e9", "-180", "nan"]))
    def record_a_heading_that_is_no_radians(self, heading: str) -> None:
        self._refused(["session", "record", str(self.folder), "--final", "1.8", "0.8", heading])

    @rule()
    def withdraw(self) -> None:
        argv = ["session", "withdraw", str(self.folder)]
        if not self.typed:
            self._refused(argv)
            return
        self._accepted(argv)
        self.typed.pop()
        self.asked = True

    @rule(name=st.sampled_from(["session.json", "config.yaml", "trials/0001/request.json", "trials/0001/result.json"]))
    def status_onto_a_file_of_the_session(self, name: str) -> None:
        if (self.folder / name).exists():
            self._refused(["session", "status", str(self.folder), "--json", str(self.folder / name)])

    @rule(edit=st.sampled_from(sorted(EDITS)), command=st.sampled_from(["next", "status", "record", "withdraw"]))
    def edit_by_hand_then_a_command(self, edit: str, command: str) -> None:
        pending = len(self.typed) + 1
        if (edit == "cut_commands" and not self.asked) or (edit == "edit_result" and not self.typed):
            return
        kept = {path: path.read_bytes() for path in self.folder.rglob("*") if path.is_file()}
        path, refusing = EDITS[edit](self.folder, pending)
        argv = ["session", command, str(self.folder), *(["--final", "0", "0", "0"] if command == "record" else [])]
        try:
            if command in refusing or (command == "record" and not self.asked):
                self._refused(argv)
            elif command == "status":  # run's exit codes, by the session's state
                code = self._run(argv)
                assert code in (0, 1, 5) and "Traceback" not in self.err, (argv, code, self.err)
            elif command == "next":  # exit 1 once the budget is spent: nothing to run
                assert self._run(argv) == (0 if len(self.typed) < BUDGET else 1), (argv, self.err)
            # a withdrawal or a record that may: not made here, the edit taken back
        finally:
            for file in [p for p in self.folder.rglob("*") if p.is_file() and p not in kept]:
                file.unlink()
            if path.is_file() and path not in kept:
                path.unlink()
            for file, content in kept.items():
                file.parent.mkdir(parents=True, exist_ok=True)
                file.write_bytes(content)

    @invariant()
    def the_results_are_the_poses_typed(self) -> None:
        if not hasattr(self, "folder"):
            return
        results = sorted((self.folder / "trials").glob("*/result.json")) if (self.folder / "trials").exists() else []
        assert [json.loads(p.read_text())["final"] for p in results] == self.typed
        code = self._run(["session", "status", str(self.folder)])
        assert code in (0, 1, 5) and code == session.status(self.folder).exit_code, (code, self.err)  # run's codes


@pytest.mark.filterwarnings("ignore::DeprecationWarning")
@pytest.mark.parametrize(
    ("examples", "steps"), [(3, 8), pytest.param(40, 20, marks=pytest.mark.slow)], ids=["small", "large"]
)
def test_a_hostile_person_of_issue_64_leaves_the_session_consistent(examples, steps, tmp_path_factory, capsys):
    HostilePerson._tmp = tmp_path_factory
    HostilePerson._capsys = capsys
    runner = HostilePerson.TestCase
    runner.settings = settings(
        max_examples=examples, stateful_step_count=steps, deadline=None, suppress_health_check=list(HealthCheck)
    )
    runner().runTest()
