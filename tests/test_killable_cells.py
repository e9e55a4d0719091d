"""A user's learner that calls sys.exit() inside a trial is its failure, not success (issue 44)."""

from ilc_steering import cli

EXITING = """
import sys

from ilc_steering.agents.base import BaseLearner
from ilc_steering.agents.ilc import ILCAgent


class Exiting(BaseLearner):
    def __init__(self, context):
        super().__init__()
        self.inner = ILCAgent(context.model, context.nu_a, context.nu_b, start=context.first_action())

    def act(self, observation=None):
        return self.inner.act(observation)

    def learn(self, info):
        sys.exit(0)

    def reset(self):
        self.inner.reset()


def make(context):
    return Exiting(context)
"""


def test_a_learner_that_raises_system_exit_in_run_is_its_failure(tmp_path, monkeypatch, capsys):
    (tmp_path / "exiting_learners.py").write_text(EXITING)
    monkeypatch.chdir(tmp_path)
    monkeypatch.syspath_prepend(str(tmp_path))
    code = cli.main(["run", "forward_parking", "--learner", "exiting_learners:make", "--trials", "4"])
    err = capsys.readouterr().err
    assert code == 4
    assert "SystemExit" in err and "exiting_learners:make" in err
