"""A run record on disk is hostile until checked: a ``run.json`` whose provenance, configs or
sessions are of the wrong shape, or whose code hash is not the hash of its files, is refused by
``current`` and ``tables`` in one line naming the file and the key (exit 2), never exit 3, never
reported current."""

import copy
import json
import shutil
from pathlib import Path

import pytest

from ilc_steering.cli import main

COMPARE = Path(__file__).resolve().parents[1] / "docs" / "compare"
CASES = {
    "provenance": ("x", "provenance: must be a mapping"),
    "sessions": (5, "sessions: must be a list"),
    "sessions.0.wall_s": ("long", "sessions[0].wall_s: must be a number"),
    "sessions.0.machine.cpus": ("two", "sessions[0].machine.cpus: must be an integer"),
    "provenance.files": ([1, 2], "provenance.files: must be a mapping"),
    "provenance.code": (5, "provenance.code: must be a string"),
    "provenance.dirty": ("no", "provenance.dirty: must be true or false"),
    "provenance.packages": (None, "provenance.packages: must be a mapping"),
    "provenance.evil": (1, "provenance.evil: unknown key"),
    "configs": ([1], "configs: must be a mapping"),
    "configs.forward_parking": (3, "configs.forward_parking: must be a string"),
}


def tampered(tmp_path, key, value):
    folder = tmp_path / "run"
    folder.mkdir()
    shutil.copy(COMPARE / "compare.json", folder / "compare.json")
    record = json.loads((COMPARE / "run.json").read_text())
    target = record
    *path, last = [int(p) if p.isdigit() else p for p in key.split(".")]
    for part in path:
        target = target[part]
    target[last] = copy.deepcopy(value)
    (folder / "run.json").write_text(json.dumps(record))
    page = tmp_path / "page.md"
    page.write_text("<!-- compare-table: run -->\nx\n<!-- /compare-table -->\n")
    return folder, page


@pytest.mark.parametrize("key", sorted(CASES))
def test_a_tampered_run_record_is_refused_in_one_line(tmp_path, capsys, key):
    value, message = CASES[key]
    folder, page = tampered(tmp_path, key, value)
    for argv in (["current", str(folder)], ["tables", str(folder), "--into", str(page), "--check"]):
        assert main(argv) == 2, argv
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and "run.json" in err and message in err, err


def test_a_record_whose_code_hash_is_not_its_files_hash_contradicts_itself(tmp_path, capsys):
    folder, _ = tampered(tmp_path, "provenance.code", "0123456789abcdef")
    assert main(["current", str(folder)]) == 2
    assert "contradicts itself" in capsys.readouterr().err
