"""What made a run (issue 35): the code hash in run.json, resume refused across codes, and
``ilc-steering current`` saying a run is stale when a learner or the simulator changes."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

import ilc_steering
from ilc_steering.engine import provenance as prov
from ilc_steering.engine.runs import RunFolder
from ilc_steering.output import write_json

ROOT = Path(__file__).resolve().parent.parent


def test_the_code_hash_covers_the_simulator_the_envs_the_learners_and_the_rl_settings() -> None:
    files = prov.code_files()
    for path in ("core/plants.py", "core/simulate.py", "envs/steering_env.py", "agents/ilc.py", "agents/rl.py"):
        assert path in files
    assert "configs/rl/td3.yaml" in files
    assert "ilc_steering/loop.py" in files and "ilc_steering/compare/cells.py" in files
    # what only arranges results is not hashed: a table drawn otherwise does not make a run stale
    assert not any(path.endswith(("compare/report.py", "cli.py", "plots.py", "engine.py")) for path in files)


def test_changing_one_file_changes_its_hash_and_the_code_hash(tmp_path: Path) -> None:
    agents = Path(prov.util.find_spec("ilc_steering.agents").submodule_search_locations[0])  # type: ignore[union-attr]
    copy = tmp_path / "agents"
    shutil.copytree(agents, copy, ignore=shutil.ignore_patterns("__pycache__"))
    before = prov.code_files({"ilc_steering.agents": copy})
    assert before == prov.code_files()  # the copy hashes as the installed package does
    (copy / "ilc.py").write_text((copy / "ilc.py").read_text() + "\n# a change\n")
    after = prov.code_files({"ilc_steering.agents": copy})
    assert prov.changed(before, after) == ["agents/ilc.py"]
    assert prov.code_hash(before) != prov.code_hash(after)


def _fake_run(folder: Path, record: dict[str, object]) -> None:
    folder.mkdir()
    write_json(folder / "run.json", {"quick": True, "version": ilc_steering.__version__, "configs": {}, **record})


def test_current_and_stale_are_told_apart(tmp_path: Path) -> None:
    made = prov.provenance()
    _fake_run(tmp_path / "now", {"provenance": made})
    current, lines = prov.freshness(tmp_path / "now")
    assert current and "current" in lines[0]
    files = {**made["files"], "core/plants.py": "0" * 16}
    _fake_run(tmp_path / "then", {"provenance": {**made, "code": prov.code_hash(files), "files": files}})
    current, lines = prov.freshness(tmp_path / "then")
    assert not current and "STALE" in lines[0]
    assert any("core/plants.py" in line for line in lines)
    _fake_run(tmp_path / "old", {})
    assert not prov.freshness(tmp_path / "old")[0]


def test_a_resume_by_other_code_is_refused(tmp_path: Path) -> None:
    folder = RunFolder(tmp_path / "run", "cells", "compare")
    settings = {"quick": True, "version": ilc_steering.__version__}
    assert not folder.prepare(settings, {})
    write_json(folder.path("a_cell"), {"x": 1})
    assert folder.prepare(settings, {})  # the same code resumes
    record = json.loads((tmp_path / "run" / "run.json").read_text())
    record["provenance"] = {**record["provenance"], "code": "0" * 16, "files": {"agents/ilc.py": "0" * 16}}
    write_json(tmp_path / "run" / "run.json", record)
    with pytest.raises(ValueError, match="made by other code"):
        folder.prepare(settings, {})
    del record["provenance"]
    write_json(tmp_path / "run" / "run.json", record)
    with pytest.raises(ValueError, match="records no hash of the code"):
        folder.prepare(settings, {})


def test_a_resume_by_the_same_code_keeps_the_provenance_of_the_first_results(tmp_path: Path) -> None:
    # a folder resumed from an install without git (commit None) still names the commit that made it
    folder = RunFolder(tmp_path / "run", "cells", "compare")
    settings = {"quick": True, "version": ilc_steering.__version__}
    folder.prepare(settings, {})
    write_json(folder.path("a_cell"), {"x": 1})
    record = json.loads((tmp_path / "run" / "run.json").read_text())
    record["provenance"] = {**record["provenance"], "commit": "a" * 40, "dirty": False}
    write_json(tmp_path / "run" / "run.json", record)
    assert folder.prepare(settings, {})
    assert json.loads((tmp_path / "run" / "run.json").read_text())["provenance"]["commit"] == "a" * 40
    assert prov.read_run(tmp_path / "run")[1].provenance.commit == "a" * 40  # and it reads back
    (folder.path("a_cell")).unlink()  # no results held: the folder is taken over by this process's code
    folder.prepare(settings, {})
    assert json.loads((tmp_path / "run" / "run.json").read_text())["provenance"] == prov.provenance()


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
def test_the_current_command_reports_a_run_stale_after_a_learner_or_the_simulator_changes(tmp_path: Path) -> None:
    site = _installed_layout(tmp_path)
    env = {**os.environ, "PYTHONPATH": str(site)}

    def python(*args: str) -> subprocess.CompletedProcess[str]:
        return subprocess.run(
            [sys.executable, *args], capture_output=True, text=True, env=env, cwd=tmp_path, timeout=300
        )

    run = tmp_path / "run"
    made = python(
        "-c",
        "import ilc_steering, json, sys; from ilc_steering.engine.provenance import provenance; "
        "assert ilc_steering.__file__.startswith(sys.argv[1]), ilc_steering.__file__; "
        "print(json.dumps({'quick': True, 'version': ilc_steering.__version__, 'configs': {}, "
        "'provenance': provenance()}))",
        str(site),
    )
    assert made.returncode == 0, made.stderr
    run.mkdir()
    (run / "run.json").write_text(made.stdout)
    current = python("-m", "ilc_steering", "current", str(run))
    assert current.returncode == 0, current.stdout + current.stderr
    assert "current" in current.stdout
    for edited in ("agents/ilc.py", "core/plants.py"):
        path = site / "ilc_steering" / edited
        path.write_text(path.read_text() + "\n# changed\n")
    stale = python("-m", "ilc_steering", "current", str(run))
    assert stale.returncode == 1, stale.stdout + stale.stderr
    assert "STALE" in stale.stdout and "agents/ilc.py" in stale.stdout and "core/plants.py" in stale.stdout


def test_current_refuses_a_folder_without_a_run_record(tmp_path: Path) -> None:
    from ilc_steering.cli import main

    assert main(["current", str(tmp_path)]) == 2


def test_a_report_whose_cells_a_resume_would_restore_counts_as_results_of_its_code(tmp_path: Path) -> None:
    """A clone's run folder holds compare.json and no cells/: a resume restores its cells, so they
    must be of this code too."""
    folder = RunFolder(tmp_path / "run", "cells", "compare")
    settings = {"quick": True, "version": ilc_steering.__version__}
    folder.prepare(settings, {}, ["compare.json"])
    record = json.loads((tmp_path / "run" / "run.json").read_text())
    record["provenance"] = {**record["provenance"], "code": "0" * 16, "files": {"agents/ilc.py": "0" * 16}}
    write_json(tmp_path / "run" / "run.json", record)
    assert folder.prepare(settings, {}, ["compare.json"])  # nothing held yet: the folder is taken over
    write_json(tmp_path / "run" / "run.json", record)
    write_json(tmp_path / "run" / "compare.json", {"cells": []})
    with pytest.raises(ValueError, match="made by other code"):
        folder.prepare(settings, {}, ["compare.json"])
