"""What made a result (issue 67): each cell and row records the hash of its import closure, a
change stales exactly the results whose closure holds it, a resume recomputes exactly those, and
``ilc-steering current`` says which and why."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from ilc_steering.cli import main
from ilc_steering.compare.args import Args
from ilc_steering.compare.cells import cell_roots, run_cell
from ilc_steering.compare.command import run_cells
from ilc_steering.current import check_folders
from ilc_steering.engine import closure as closure_module
from ilc_steering.engine import provenance as prov
from ilc_steering.errors import BadInput

ROOT = Path(__file__).resolve().parent.parent
CAR = "ilc_steering.core.robots.car"
TINY = {"priors": ("nominal",), "scenarios": ("forward_parking",), "seeds": (0, 1), "model_trials": 3, "workers": 1}


def files_of(method: str) -> dict[str, str]:
    return prov.code(cell_roots(method, CAR))[1]


def test_a_cell_s_code_is_the_closure_of_its_learner_its_env_and_its_robot() -> None:
    newton_ilc, ilc, ppo = files_of("newton_ilc"), files_of("ilc"), files_of("ppo")
    for files in (newton_ilc, ilc, ppo):  # every cell: the trial loop, the env, the integrator, the car
        for path in ("loop.py", "envs/steering_env.py", "core/integrate.py", "core/robots/car.py"):
            assert f"ilc_steering/{path}" in files, path
    assert "ilc_steering/agents/newton_ilc.py" in newton_ilc
    assert "ilc_steering/agents/newton_ilc.py" not in ilc and "ilc_steering/agents/newton_ilc.py" not in ppo
    assert "ilc_steering/configs/rl/ppo.yaml" in ppo and "ilc_steering/configs/rl/sac.yaml" not in ppo
    # what only arranges results is not in a cell's closure: a table drawn otherwise stales nothing
    assert not any(path.endswith(("compare/report.py", "cli.py", "plots.py", "current.py")) for path in ilc)
    assert "ilc_steering/core/robots/unicycle.py" not in ilc  # another robot's module


@pytest.fixture
def changed(monkeypatch: pytest.MonkeyPatch):
    """``changed(name)``: make the file whose key ends with ``name`` hash as if it had been edited."""
    edited: list[str] = []
    digest = closure_module._digest

    def fake(path: Path) -> str:
        real = digest(path)
        return "e" * 16 if any(path.as_posix().endswith(name) for name in edited) else real

    monkeypatch.setattr(closure_module, "_digest", fake)

    def change(name: str) -> None:
        edited.append(name)
        prov._closure.cache_clear()

    yield change
    prov._closure.cache_clear()


def _run(out: Path, methods: tuple[str, ...], ran: list[tuple[str, int]] | None = None) -> list[dict]:
    def runner(args, prior, method, scenario, seed):  # in this process: the test's patches hold
        if ran is not None:
            ran.append((method, seed))
        return run_cell(args, prior, method, scenario, seed)

    return run_cells(Args(out=out, methods=methods, **TINY), runner)


def test_a_change_to_one_learner_stales_its_cells_and_nothing_else(tmp_path: Path, changed, capsys) -> None:
    first = _run(tmp_path, ("ilc", "newton_ilc"))
    assert check_folders([tmp_path])[0]
    changed("agents/newton_ilc.py")
    current, lines = check_folders([tmp_path])
    assert not current
    assert lines[0] == f"{tmp_path}: STALE: 2 of 4 results stale"
    assert lines[1] == "  2 of newton_ilc: 1 file changed: ilc_steering/agents/newton_ilc.py"
    assert main(["current", str(tmp_path)]) == 1
    ran: list[tuple[str, int]] = []
    again = _run(tmp_path, ("ilc", "newton_ilc"), ran)
    assert ran == [("newton_ilc", 0), ("newton_ilc", 1)]  # exactly the stale cells, and each once
    kept = [cell for cell in again if cell["method"] == "ilc"]
    assert kept == [cell for cell in first if cell["method"] == "ilc"]  # the others as they were
    assert all(cell["code"] != old["code"] for cell, old in zip(again[2:], first[2:]))
    assert check_folders([tmp_path])[0]
    assert main(["current", str(tmp_path)]) == 0


def test_a_change_to_the_integrator_stales_every_cell_that_integrates(tmp_path: Path, changed) -> None:
    _run(tmp_path / "run", ("ilc", "newton_ilc"))
    changed("core/integrate.py")
    current, lines = check_folders([tmp_path])  # a folder of run folders
    assert not current and lines[0].endswith("STALE: 4 of 4 results stale")
    assert all("ilc_steering/core/integrate.py" in line for line in lines[1:3])


def test_a_stale_cell_is_never_reused(tmp_path: Path, changed) -> None:
    first = _run(tmp_path, ("ilc",))
    path = next((tmp_path / "cells").glob("*__0.json"))
    cell = json.loads(path.read_text())
    path.write_text(json.dumps({**cell, "best_error": 123.0}))  # a stale cell's result is not looked at again
    changed("agents/ilc.py")
    ran: list[tuple[str, int]] = []
    again = _run(tmp_path, ("ilc",), ran)
    assert ran == [("ilc", 0), ("ilc", 1)]
    assert again[0]["best_error"] == first[0]["best_error"] != 123.0
    assert json.loads(path.read_text())["code"] == again[0]["code"] != cell["code"]


def test_a_dry_run_says_what_a_resume_would_compute_and_writes_nothing(tmp_path: Path, changed, capsys) -> None:
    _run(tmp_path, ("ilc", "newton_ilc"))
    changed("agents/newton_ilc.py")
    before = {path: path.read_bytes() for path in tmp_path.rglob("*") if path.is_file()}
    capsys.readouterr()
    argv = ["compare", "--out", str(tmp_path), "--methods", "ilc", "newton_ilc", "robust_ilc", "--priors", "nominal"]
    argv += ["--scenarios", "forward_parking", "--seeds", "0", "1", "--model-trials", "3", "--workers", "1"]
    assert main([*argv, "--dry-run"]) == 0
    out = capsys.readouterr().out
    assert "4 to compute (2 missing, 2 stale)" in out
    assert "newton_ilc    seed 0: its code differs" in out and "missing: nominal forward_parking" in out
    assert {path: path.read_bytes() for path in tmp_path.rglob("*") if path.is_file()} == before


def test_a_sweep_s_rows_and_oracle_record_their_code(tmp_path: Path, changed, capsys) -> None:
    argv = ["sweep", "forward_parking", "--methods", "ilc", "newton_ilc", "--grid", "2", "--trials", "2"]
    argv += ["--workers", "1", "--oracle", "--out", str(tmp_path)]
    assert main(argv) == 0
    current, lines = check_folders([tmp_path])
    assert current and lines[1].startswith("  making them again costs about ")  # what a change would cost
    changed("agents/newton_ilc.py")
    current, lines = check_folders([tmp_path])
    assert not current and lines[1] == "  2 of newton_ilc: 1 file changed: ilc_steering/agents/newton_ilc.py"
    assert lines[2].startswith("  a resume recomputes them: about ") and len(lines) == 3
    changed("ilc_steering/oracle.py")
    assert "  1 of oracle: 1 file changed: ilc_steering/oracle.py" in check_folders([tmp_path])[1]


def test_a_report_made_from_other_results_is_stale(tmp_path: Path) -> None:
    from ilc_steering.compare.command import main as compare

    compare(Args(out=tmp_path, methods=("ilc",), **TINY))
    assert check_folders([tmp_path])[0]
    path = next((tmp_path / "cells").glob("*__1.json"))
    path.write_text(json.dumps({**json.loads(path.read_text()), "wall_s": 99.0}))  # the report holds the old
    current, lines = check_folders([tmp_path])
    assert not current and "report compare.json: made from other results" in lines[-1]


def test_current_refuses_a_folder_without_a_run_record(tmp_path: Path) -> None:
    assert main(["current", str(tmp_path)]) == 2


def _installed_layout(tmp_path: Path) -> Path:
    """A copy of the package as a wheel lays it out (agents, envs, configs under ilc_steering)."""
    site = tmp_path / "site"
    package = site / "ilc_steering"
    shutil.copytree(
        ROOT / "ilc_steering",
        package,
        ignore=shutil.ignore_patterns("__pycache__", "*.nb*", "agents", "envs", "configs"),
    )
    for name in ("agents", "envs", "configs"):
        shutil.copytree(ROOT / name, package / name, ignore=shutil.ignore_patterns("__pycache__", "*.nb*"))
    return site


@pytest.mark.slow
@pytest.mark.skipif(not (ROOT / "agents").is_dir(), reason="needs the source tree")
def test_the_current_command_reports_cells_stale_after_a_learner_or_the_simulator_changes(tmp_path: Path) -> None:
    site = _installed_layout(tmp_path)
    env = {**os.environ, "PYTHONPATH": str(site)}

    def ilc_steering(*args: str) -> subprocess.CompletedProcess[str]:
        return subprocess.run(
            [sys.executable, "-m", "ilc_steering", *args], capture_output=True, text=True, env=env, cwd=tmp_path,
            timeout=600,
        )  # fmt: skip

    run = tmp_path / "run"
    made = ilc_steering(
        "compare", "--out", str(run), "--methods", "ilc", "newton_ilc", "--priors", "nominal", "--scenarios",
        "forward_parking", "--seeds", "0", "--model-trials", "3", "--workers", "1",
    )  # fmt: skip
    assert made.returncode == 0, made.stdout + made.stderr
    assert ilc_steering("current", str(run)).returncode == 0
    path = site / "ilc_steering" / "agents" / "newton_ilc.py"
    path.write_text(path.read_text() + "\n# changed\n")
    stale = ilc_steering("current", str(run))
    assert stale.returncode == 1, stale.stdout + stale.stderr
    assert "1 of 2 results stale" in stale.stdout and "1 of newton_ilc: 1 file changed" in stale.stdout
    path = site / "ilc_steering" / "core" / "integrate.py"
    path.write_text(path.read_text() + "\n# changed\n")
    stale = ilc_steering("current", str(run))
    assert "2 of 2 results stale" in stale.stdout and "ilc_steering/core/integrate.py" in stale.stdout


def test_what_a_script_made_is_current_until_its_code_changes(tmp_path: Path, changed) -> None:
    import ilc_steering.agents.newton_ilc  # noqa: F401  (a learner the script ran, imported by name)

    prov.record_made(tmp_path / "made", str(ROOT / "benchmarks" / "newton_ilc.py"), ["--quick"])
    prov.record_made(tmp_path / "made", str(ROOT / "benchmarks" / "noisy.py"))  # another script, the same folder
    records = json.loads((tmp_path / "made" / "made.json").read_text())
    assert sorted(records) == ["benchmarks/newton_ilc.py", "benchmarks/noisy.py"]
    record = records["benchmarks/newton_ilc.py"]
    assert record["command"] == "python benchmarks/newton_ilc.py --quick"
    assert "ilc_steering/agents/newton_ilc.py" in record["files"] and "benchmarks/newton_ilc.py" in record["files"]
    current, lines = check_folders([tmp_path])
    said = f"({record['made']}; {record['cpu_s'] / 60:.1f} CPU minutes)"  # when, and what making it again costs
    assert current and lines[0] == f"{tmp_path / 'made'}: current: made by {record['command']} {said}"
    changed("benchmarks/noisy.py")  # only the second script's code
    current, lines = check_folders([tmp_path])
    assert not current and lines[0].startswith(f"{tmp_path / 'made'}: current: made by python benchmarks/newton_ilc.py")
    assert lines[1] == f"{tmp_path / 'made'}: STALE: 1 file changed: benchmarks/noisy.py"
    changed("agents/newton_ilc.py")  # in both closures: the learner was imported by the process that recorded
    assert sum("STALE" in line for line in check_folders([tmp_path])[1]) == 2
    (tmp_path / "made" / "made.json").write_text(json.dumps({**records, "x": {**record, "code": "0" * 16}}))
    assert main(["current", str(tmp_path)]) == 2  # a record that contradicts itself is refused


def test_results_with_no_record_of_what_made_them_are_never_called_current(tmp_path: Path) -> None:
    (tmp_path / "made").mkdir()
    prov.record_made(tmp_path / "made", str(ROOT / "benchmarks" / "newton_ilc.py"))
    (tmp_path / "made" / "deeper").mkdir()
    (tmp_path / "made" / "deeper" / "table.md").write_text("| a |\n")  # below a record: its artifact
    (tmp_path / "loose").mkdir()
    (tmp_path / "loose" / "table.md").write_text("| a |\n")
    current, lines = check_folders([tmp_path])
    assert not current
    no_record = "holds results with no record of what made them (no run.json, made.json or kept.json)"
    assert lines[0] == f"{tmp_path / 'loose'}: STALE: {no_record}"
    assert len(lines) == 2 and lines[1].startswith(f"{tmp_path / 'made'}: current")


def test_a_kept_record_is_reported_as_measured_and_never_stale_but_must_name_its_files(tmp_path: Path) -> None:
    """A measurement of the code before a fix, a CI machine's times: kept as measured (kept.json), named
    with its commit and when, never remade; a kept.json that names no file of its folder is refused."""
    (tmp_path / "before").mkdir()
    (tmp_path / "before" / "timing.txt").write_text("91.5 s\n")
    entry = {"what": "reproduce's CPU time before the fix", "commit": "eca4e05", "when": "2026-11-30"}
    (tmp_path / "before" / "kept.json").write_text(json.dumps({"timing.txt": entry}))
    current, lines = check_folders([tmp_path])
    assert current and lines == [
        f"{tmp_path / 'before'}: kept: timing.txt: reproduce's CPU time before the fix (recorded 2026-11-30 in "
        "eca4e05; kept as measured)"
    ]
    (tmp_path / "before" / "table.md").write_text("| a |\n")  # a file no record names: stale
    current, lines = check_folders([tmp_path])
    assert not current and lines[0].startswith(f"{tmp_path / 'before'}: STALE: holds results with no record")
    (tmp_path / "before" / "table.md").unlink()
    for bad in ({"gone.txt": entry}, {"timing.txt": {"what": "x"}}, {"../x": entry}, [], 5, {"timing.txt": 5}):
        (tmp_path / "before" / "kept.json").write_text(json.dumps(bad))
        with pytest.raises(BadInput, match="kept.json"):
            check_folders([tmp_path])
        assert main(["current", str(tmp_path)]) == 2
