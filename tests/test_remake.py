"""``benchmarks/remake.py``: every committed result folder has the commands that make it again."""

import importlib.util
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def remake():
    spec = importlib.util.spec_from_file_location("remake_benchmark", ROOT / "benchmarks" / "remake.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)  # a script of benchmarks/, not a package
    sys.modules[spec.name] = module  # dataclasses look their module up by name
    spec.loader.exec_module(module)
    return module


def test_every_result_folder_is_made_by_a_command_of_the_table_or_kept_as_measured():
    """Every folder of committed results (git's tracked files: not results/ci, which CI's benchmarks write)."""
    table = remake().FOLDERS
    tracked = subprocess.run(["git", "ls-files", "results"], cwd=ROOT, capture_output=True, text=True, check=True)
    folders = {(ROOT / name).parent for name in tracked.stdout.split()}
    assert len(folders) > 20
    for folder in sorted(folders):
        relative = folder.relative_to(ROOT)
        covered = any(relative == Path(key) or Path(key) in relative.parents for key in table)
        kept = any((part / "kept.json").is_file() for part in (folder, *folder.parents))
        assert covered or kept, f"{relative}: no command of benchmarks/remake.py makes it, nor is it kept"
    for folder, commands in table.items():
        assert (ROOT / folder).is_dir() and commands, folder
        for command in commands:
            word = command.split()
            assert word[0] in ("python", "ilc-steering") and (word[0] != "python" or (ROOT / word[1]).is_file())


def test_remake_refuses_a_folder_that_is_not_in_its_table(capsys):
    with pytest.raises(SystemExit) as exit_:
        remake().main(["--only", "results/nowhere", "--dry-run"])
    assert exit_.value.code == 2 and "'results/nowhere' is no folder of the table" in capsys.readouterr().err
