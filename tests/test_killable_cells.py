"""A user's learner that calls sys.exit() inside a trial is its failure, not success (issue 44); one
that ends its process or never returns from compiled code is its cell's failure under compare, one
worker included (issue 51)."""

import json
import os

import pytest

from ilc_steering import cli

# A user's learner that breaks on one trial's update (``broken()``): one that calls sys.exit() under
# run, and under compare, even with one worker, one that ends its process and one that never
# returns from nogil compiled code, each its cell's failure.
WRAPPER = """
from ilc_steering.agents.base import BaseLearner
from ilc_steering.agents.ilc import ILCAgent


class Wrapped(BaseLearner):
    def __init__(self, context):
        super().__init__()
        self.inner = ILCAgent(context.model, context.nu_a, context.nu_b, start=context.first_action())

    def act(self, observation=None):
        return self.inner.act(observation)

    def learn(self, info):
        broken()

    def reset(self):
        self.inner.reset()


def make(context):
    return Wrapped(context)
"""
EXITING = "import sys\n\n\ndef broken():\n    sys.exit(0)\n" + WRAPPER


def test_a_learner_that_raises_system_exit_in_run_is_its_failure(tmp_path, monkeypatch, capsys):
    (tmp_path / "exiting_learners.py").write_text(EXITING)
    monkeypatch.chdir(tmp_path)
    monkeypatch.syspath_prepend(str(tmp_path))
    code = cli.main(["run", "forward_parking", "--learner", "exiting_learners:make", "--trials", "4"])
    err = capsys.readouterr().err
    assert code == 4
    assert "SystemExit" in err and "exiting_learners:make" in err


OS_EXIT = "import os\n\n\ndef broken():\n    os._exit(3)\n" + WRAPPER
NOGIL_LOOP = (
    """
import numba


@numba.njit(nogil=True)
def spin(x):
    while x >= 0.0:  # x tends to 2 and never leaves: no Python runs again in this thread
        x = 0.5 * x + 1.0
    return x


def broken():
    spin(1.0)
"""
    + WRAPPER
)
LIMIT = 15.0
"""[s] the time limit of the cells here: far above an ILC cell of three trials, so only the loop meets it."""
BROKEN = {"os_exit": (OS_EXIT, "WorkerDied: its worker process ended (exit code 3)"), "nogil_loop": (NOGIL_LOOP, "")}


@pytest.mark.timeout(240, method="thread")  # a cell left in this process would hang the suite: end it, saying where
@pytest.mark.parametrize("cell_timeout", [None, LIMIT])
@pytest.mark.parametrize("kind", ["os_exit", pytest.param("nogil_loop", marks=pytest.mark.slow)])  # runs out LIMIT
@pytest.mark.slow  # over 2.5 s: the README's test command stays under 5 min
def test_a_learner_that_exits_or_hangs_in_compiled_code_is_its_cells_failure_under_one_worker(
    kind, cell_timeout, tmp_path, monkeypatch, capsys
):
    """``compare --workers 1`` runs each cell in a killable worker, with or without ``--cell-timeout``:
    the learner's ``os._exit(3)`` or its endless ``nogil`` loop is named as its cell's failure, the
    other cell is written and so is the report. Without the option the engine's default bound ends
    the loop; it is shortened here to :data:`LIMIT`, as ``--cell-timeout`` shortens it on the command line.
    The other cell is computed first, without the short limit, and held when the run resumes: no
    machine is slow enough to fail it (a loaded one ran a three-trial cell past 15 s)."""
    from ilc_steering.compare.cells import cell_name
    from ilc_steering.engine import options as engine

    source, expected = BROKEN[kind]
    module = f"{kind}_learners"
    (tmp_path / f"{module}.py").write_text(source)
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join([str(tmp_path), os.environ.get("PYTHONPATH", "")]))
    monkeypatch.syspath_prepend(str(tmp_path))
    out = tmp_path / "run"
    settings = ["--priors", "nominal", "--seeds", "0", "--scenarios", "forward_parking", "--model-trials", "3"]
    settings += ["--custom-trials", "3", "--workers", "1", "--out", str(out)]
    assert cli.main(["compare", "--methods", "ilc", *settings]) == 0  # the other cell, under the default bound
    capsys.readouterr()
    monkeypatch.setattr(engine, "DEFAULT_CELL_TIMEOUT", LIMIT)  # read when the engine starts the cells
    argv = ["compare", "--methods", "ilc", f"{module}:make", *settings]
    argv += [] if cell_timeout is None else ["--cell-timeout", str(cell_timeout)]
    assert cli.main(argv) == 4
    err = capsys.readouterr().err
    expected = (
        expected or f"CallTimeout: took longer than the time limit of {LIMIT:g} s (--cell-timeout); its worker process"
    )
    failure = [line for line in err.splitlines() if f"{module}:make seed 0: FAILED" in line]
    assert len(failure) == 1 and expected in failure[0], err
    assert "1 of 2 cells failed" in err
    assert [p.name for p in (out / "cells").iterdir()] == [f"{cell_name('nominal', 'ilc', 'forward_parking', 0)}.json"]
    failed = cell_name("nominal", f"{module}:make", "forward_parking", 0)
    assert [p.name for p in (out / "failed").iterdir()] == [f"{failed}.json"]
    report = json.loads((out / "compare.json").read_text())
    assert [cell["method"] for cell in report["cells"]] == ["ilc"]
