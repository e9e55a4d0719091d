"""``compare --against``: a user's learner against a committed run, computing only its own cells; and
the docs' users'-learner commands (docs/learners.md), run as written from the folder that holds the module."""

import json
import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from ilc_steering.cli import main
from ilc_steering.compare.args import Args
from ilc_steering.compare.cells import run_cell
from ilc_steering.compare.command import run_cells

ROOT = Path(__file__).resolve().parents[1]
LEARNERS = (ROOT / "docs" / "learners.md").read_text()  # "Your own learner", its last section
SCRIPT = Path(sys.executable).with_name("ilc-steering")
pytestmark = pytest.mark.slow  # compare runs and fresh ilc-steering processes

MY_BAY = (ROOT / "configs" / "parallel_parking.yaml").read_text().replace("name: parallel_parking", "name: my_bay")
COMMITTED = ["--quick", "--methods", "ilc", "least_squares", "--priors", "nominal", "--workers", "1"]


def users_learner() -> str:
    """The docs' ``Broyden`` and the ``make`` it says to save beside it, as ``my_learners.py``."""
    section = LEARNERS[LEARNERS.index("## Your own learner") :]
    block = re.findall(r"```python\n(.*?)```", section, re.S)[0]
    return block[: block.index("\nenv = gym.make")] + "\n\ndef make(context):\n    return Broyden(context)\n"


def snapshot(folder: Path) -> dict[str, tuple[bytes, int]]:
    """Every file under ``folder``: its bytes and modification time [ns]."""
    return {
        str(p.relative_to(folder)): (p.read_bytes(), p.stat().st_mtime_ns) for p in folder.rglob("*") if p.is_file()
    }


def script(argv: list[str], cwd: Path) -> subprocess.CompletedProcess[str]:
    """The installed ``ilc-steering`` script, whose own folder (not ``cwd``) is on its path."""
    return subprocess.run([str(SCRIPT), *argv], capture_output=True, text=True, cwd=cwd, timeout=600)


@pytest.fixture(scope="module")
def committed(tmp_path_factory):
    """A tiny committed run: ilc and least_squares, quick budgets, two seeds, a packaged scenario and a YAML one."""
    home = tmp_path_factory.mktemp("committed")
    (home / "my_bay.yaml").write_text(MY_BAY)
    out = home / "base"
    assert (
        main(["compare", *COMMITTED, "--scenarios", "parallel_parking", str(home / "my_bay.yaml"), "--out", str(out)])
        == 0
    )
    return out


def test_against_computes_only_the_new_cells_and_writes_the_joint_report(committed, tmp_path):
    (tmp_path / "my_learners.py").write_text(users_learner())
    (tmp_path / "my_bay.yaml").write_text(MY_BAY)
    before = snapshot(committed)
    argv = ["compare", "--methods", "my_learners:make", "--against", str(committed), "--out", "mine"]
    result = script([*argv, "--scenarios", "parallel_parking", "my_bay.yaml"], tmp_path)
    assert result.returncode == 0, result.stderr
    assert snapshot(committed) == before  # not a byte, not a time stamp, not a lock file more
    assert "8 committed cells taken as they are" in result.stdout and "4 cells to compute" in result.stdout
    assert "with its settings: --quick --seeds 0 1 --ablation-seeds 5 --model-trials 6 --blackbox-trials 40" in (
        result.stdout
    )
    progress = [line for line in result.stdout.splitlines() if re.search(r"left nominal +\S+ +\S+ +seed \d:", line)]
    assert len(progress) == 4 and all("my_learners:make" in line for line in progress)  # nothing else ran
    mine = tmp_path / "mine"
    for name in (committed / "cells").iterdir():  # the committed cells, copied as they are (wall times too)
        assert json.loads((mine / "cells" / name.name).read_text()) == json.loads(name.read_text())
    new = sorted(p.name for p in (mine / "cells").glob("*my_learners_make*"))
    assert new == [
        f"nominal__my_learners_make__{s}__{seed}.json" for s in ("my_bay", "parallel_parking") for seed in (0, 1)
    ]
    report = json.loads((mine / "compare.json").read_text())
    assert len(report["cells"]) == 12 and {c["method"] for c in report["cells"]} == {
        "ilc",
        "least_squares",
        "my_learners:make",
    }
    assert all(c["budget"] == 20 for c in report["cells"] if c["method"] == "my_learners:make")  # quick custom_trials
    table = (mine / "compare.md").read_text()
    for row in (
        "| parallel_parking | ilc | 6 |",
        "| parallel_parking | least_squares | 40 |",
        "| my_bay | my_learners:make | 20 |",
    ):
        assert row in table
    ours, theirs = (json.loads((folder / "run.json").read_text()) for folder in (mine, committed))
    assert ours.pop("sessions")[-1]["computed"] == 4  # the sessions of work differ; what made the cells does not
    theirs.pop("sessions")
    assert ours.pop("report") != theirs.pop("report")  # the joint report is of more cells
    mine_codes, their_codes = ours.pop("codes"), theirs.pop("codes")
    assert their_codes.items() <= mine_codes.items() and len(mine_codes) == len(their_codes) + 1  # yours: one code
    assert ours == theirs
    for scenario in ("parallel_parking", "my_bay"):
        assert (mine / f"compare_{scenario}.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    # run again: a resume, which recomputes nothing
    again = script([*argv, "--scenarios", "parallel_parking", "my_bay.yaml"], tmp_path)
    assert again.returncode == 0 and "0 cells to compute" in again.stdout, again.stderr


def test_a_library_method_against_a_committed_run_runs_its_cells_only_once(committed, tmp_path):
    args = Args(out=tmp_path / "mine", against=committed, methods=("newton",), scenarios=("parallel_parking",))
    calls = []

    def counted(a, prior, method, scenario, seed):
        calls.append((prior, method, scenario, seed))
        return run_cell(a, prior, method, scenario, seed)

    cells = run_cells(args, counted)
    assert calls == [("nominal", "newton", "parallel_parking", 0), ("nominal", "newton", "parallel_parking", 1)]
    assert [c["method"] for c in cells].count("newton") == 2 and len(cells) == 10  # all 8 committed ones too
    assert all(c["budget"] == 6 for c in cells if c["method"] == "newton")  # the committed run's quick budget
    assert run_cells(args, lambda *call: pytest.fail(f"recomputed {call[1:]}")) == cells


@pytest.mark.parametrize(
    ("edit", "argv", "message"),
    [
        (lambda r: {**r, "version": "0.0.1"}, [], r"made by ilc-steering 0\.0\.1, this is "),
        (None, ["--seeds", "0"], r"it was run with --seeds 0 1, not --seeds 0; leave the option out"),
        (None, ["--custom-trials", "25"], r"it was run with --custom-trials 20, not --custom-trials 25"),
        (lambda r: {**r, "quick": False}, ["--quick"], r"it was run with no --quick, not --quick"),
        (lambda r: {**r, "max_cells": 3}, [], r"a setting 'max_cells' that this version has no option for"),
        (lambda r: {k: v for k, v in r.items() if k != "version"}, [], r"records no package version"),
        # a record that does not match its own cells: the least_squares cells hold budget 40
        (
            lambda r: {**r, "blackbox_trials": 41},
            ["--scenarios", "parallel_parking"],
            r"budget 40, not 41; .* not consistent",
        ),
        (
            None,
            ["--scenarios", "parallel_parking", "other_bay.yaml"],
            r"its 'my_bay' cells were computed with another config",
        ),
        (None, ["--scenarios", "trailer_bay"], r"--scenarios trailer_bay: the committed run .* has no cells of it"),
        (None, [], r"its scenario 'my_bay' is not a packaged config; give its YAML file with --scenarios"),
        (
            None,
            ["--priors", "none", "--scenarios", "parallel_parking"],
            r"--priors: the committed run .* has cells of nominal only",
        ),
    ],
)
def test_a_committed_run_of_another_version_or_other_settings_is_refused(
    committed, tmp_path, monkeypatch, capsys, edit, argv, message
):
    folder = tmp_path / "base"
    shutil.copytree(committed, folder)
    if edit is not None:
        record = json.loads((folder / "run.json").read_text())
        (folder / "run.json").write_text(json.dumps(edit(record)))
    (tmp_path / "other_bay.yaml").write_text(
        MY_BAY.replace("true_wheelbase: 0.22", "true_wheelbase: 0.23")
    )  # my_bay too
    monkeypatch.chdir(tmp_path)
    before = snapshot(folder)
    assert main(["compare", "--methods", "newton", "--against", str(folder), "--out", "mine", *argv]) == 2
    err = capsys.readouterr().err
    assert re.search(message, err) and err.count("\n") == 1, err
    assert not (tmp_path / "mine").exists()  # refused before anything was written
    assert snapshot(folder) == before


def test_the_output_never_goes_into_the_committed_folder(committed, capsys):
    before = snapshot(committed)
    for out in (committed, committed / "cells", committed / "mine"):
        assert main(["compare", "--methods", "newton", "--against", str(committed), "--out", str(out)]) == 2
        assert "inside the committed run --against" in capsys.readouterr().err
    assert main(["compare", "--against", str(committed), "--out", "/tmp/never"]) == 2  # which methods to add?
    assert "name the methods to add with --methods" in capsys.readouterr().err
    assert snapshot(committed) == before


def test_a_folder_that_is_no_compare_run_is_refused(tmp_path, capsys):
    (tmp_path / "old").mkdir()
    (tmp_path / "old" / "run.json").write_text(json.dumps({"quick": True, "seeds": [0, 1]}))  # before version keys
    for folder, message in (
        (tmp_path / "nowhere", "not a folder"),
        (tmp_path, "no run.json, so this is not a compare run folder"),
        (tmp_path / "old", "records no package version"),
    ):
        assert main(["compare", "--methods", "newton", "--against", str(folder), "--out", str(tmp_path / "o")]) == 2
        assert message in capsys.readouterr().err


def test_the_readmes_users_learner_commands_run_as_written_from_the_modules_folder(tmp_path):
    section = LEARNERS[LEARNERS.index("## Your own learner") :]
    commands = [line for block in re.findall(r"```bash\n(.*?)```", section, re.S) for line in block.splitlines()]
    joins, against = commands
    (tmp_path / "my_learners.py").write_text(users_learner())
    (tmp_path / "my_task.yaml").write_text(MY_BAY.replace("name: my_bay", "name: my_task"))
    # as written, with --quick: the budgets do not change where the module is found
    result = script(
        [*shlex.split(joins)[1:], "--quick", "--priors", "nominal", "--seeds", "0", "--workers", "2"], tmp_path
    )
    assert result.returncode == 0, result.stderr
    table = (tmp_path / "runs" / "compare" / "compare.md").read_text()  # compare's default --out
    assert "| my_task | my_learners:make | 20 |" in table
    # the committed run the second command names: a quick one of the two baselines, then the command as written
    shutil.rmtree(tmp_path / "runs")
    base = script(["compare", *COMMITTED, "--scenarios", "parallel_parking", "--out", "runs/compare"], tmp_path)
    assert base.returncode == 0, base.stderr
    result = script(shlex.split(against)[1:], tmp_path)
    assert result.returncode == 0, result.stderr
    table = (tmp_path / "runs" / "mine" / "compare.md").read_text()
    assert all(f"| parallel_parking | {m} |" in table for m in ("ilc", "least_squares", "my_learners:make"))


@pytest.mark.parametrize(
    ("spec", "message"),
    [
        ("my_learners:Factory.make", None),  # a dotted attr
        ("my_learners:Broyden", None),  # a class is its own factory
        ("mypkg.mod:make", None),  # a package in the working directory
        ("my_learners.py:make", "give the module's import name, not its file: my_learners:make"),
        ("./my_learners.py:make", "give the module's import name, not its file: my_learners:make"),
        ("my_learners:", "give module:attr"),
        ("code:make", "it is an installed module, found before your code.py of the working directory: rename yours"),
        ("broken:make", "importing it raised ModuleNotFoundError: No module named 'not_installed'"),
        ("syntax:make", "importing it raised SyntaxError"),
        ("nowhere:make", "no module 'nowhere' in the working directory"),
    ],
)
def test_any_module_attr_is_found_in_the_working_directory_or_refused_in_one_line(tmp_path, spec, message):
    learner = users_learner() + "\n\nclass Factory:\n    make = staticmethod(make)\n"
    (tmp_path / "my_learners.py").write_text(learner)
    (tmp_path / "code.py").write_text(learner)  # the standard library's code module comes first
    (tmp_path / "mypkg").mkdir()
    (tmp_path / "mypkg" / "__init__.py").write_text("")
    (tmp_path / "mypkg" / "mod.py").write_text(learner)
    (tmp_path / "broken.py").write_text("import not_installed\n")
    (tmp_path / "syntax.py").write_text("def make(:\n")
    result = script(["run", "parallel_parking", "--trials", "5", "--learner", spec], tmp_path)
    if message is None:
        assert result.returncode == 0 and "converged at trial 3" in result.stdout, result.stderr
    else:
        assert result.returncode == 2 and message in result.stderr and result.stderr.count("\n") == 1, result.stderr


README = (ROOT / "README.md").read_text()


@pytest.mark.skipif(not (ROOT / "results" / "compare" / "run.json").is_file(), reason="needs the committed run")
def test_the_readmes_row_beside_the_committed_comparison_runs_as_written(tmp_path):
    section = README[README.index("Your learner as one more row") :]
    command = re.findall(r"```bash\n(.*?)```", section, re.S)[0].strip()
    words = shlex.split(command)
    assert words[0] == "PYTHONPATH=examples" and words[1] == "ilc-steering" and words[-2:] == ["--out", "runs/mine"]
    env = {**__import__("os").environ, "PYTHONPATH": str(ROOT / "examples")}
    out = tmp_path / "mine"
    result = subprocess.run(
        [str(SCRIPT), *words[2:-1], str(out)], capture_output=True, text=True, cwd=ROOT, env=env, timeout=1800
    )
    assert result.returncode == 0, result.stderr[-2000:]
    report = json.loads((out / "compare.json").read_text())
    committed = json.loads((ROOT / "results" / "compare" / "compare.json").read_text())
    mine = [c for c in report["cells"] if c["method"] == "my_learners:make"]
    assert len(report["cells"]) == len(committed["cells"]) + len(mine)
    assert {c["scenario"] for c in mine} == {c["scenario"] for c in committed["cells"]}
    seeds = {prior: {c["seed"] for c in committed["cells"] if c["prior"] == prior} for prior in ("nominal", "none")}
    assert {prior: {c["seed"] for c in mine if c["prior"] == prior} for prior in seeds} == seeds
