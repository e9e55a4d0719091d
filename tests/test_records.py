"""A record on disk is hostile until checked: a ``run.json`` whose provenance, configs or
sessions are of the wrong shape, or whose code hash is not the hash of its files, is refused by
``current`` and ``tables`` in one line naming the file and the key (exit 2), never exit 3, never
reported current; so are a compare cell (``cells/*.json``, or one of ``compare.json``'s), a sweep
row (``rows/*.json``) and a ``sweep.json`` of the wrong shape (a wrong type, a missing key, an
unknown key, a list one short), by every command that reads them."""

import contextlib
import copy
import io
import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from ilc_steering.cli import main

COMPARE = Path(__file__).resolve().parents[1] / "results" / "compare"
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
    "codes": ([1], "codes: must be a mapping"),
    "report": (5, "report: must be a string"),
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
    forged = {"0123456789abcdef": {"roots": ["ilc_steering.loop"], "files": {"ilc_steering/loop.py": "0" * 16}}}
    folder, _ = tampered(tmp_path, "codes", forged)
    assert main(["current", str(folder)]) == 2
    assert "codes.0123456789abcdef: not the hash of its files" in capsys.readouterr().err


# Forged records x the commands that read them ------------------------------------------------------

ROOT = Path(__file__).resolve().parents[1]
CELL_FORGERIES = {  # what is done to a cell -> the key the refusal names and its problem
    "a wrong type": (lambda c: {**c, "seed": "0"}, "seed: must be an integer"),
    "a missing key": (lambda c: {k: v for k, v in c.items() if k != "budget"}, "budget: missing required key"),
    "an unknown key": (lambda c: {**c, "evil": 1}, "evil: unknown key"),
    "a list one short": (lambda c: {**c, "curve": [c["curve"][0][:1], *c["curve"][1:]]}, "curve[0]: needs 2 values"),
    "a name leading elsewhere": (lambda c: {**c, "scenario": "../../evil"}, "scenario: String should match pattern"),
}
ROW_FORGERIES = {
    "a wrong type": (lambda r: {**r, "row": "0"}, "row: must be an integer"),
    "a missing key": (lambda r: {k: v for k, v in r.items() if k != "wall_s"}, "wall_s: missing required key"),
    "an unknown key": (lambda r: {**r, "evil": 1}, "evil: unknown key"),
    "a list one short": (lambda r: {**r, "trials_to": r["trials_to"][:-1]}, "trials_to: needs 3 values"),
    "a name leading elsewhere": (lambda r: {**r, "method": "../evil"}, "method: String should match pattern"),
}
SWEEP_FORGERIES = {
    "a wrong type": (lambda d: {**d, "ratios": "x"}, "ratios: must be a list"),
    "a missing key": (lambda d: {k: v for k, v in d.items() if k != "rows"}, "rows: missing required key"),
    "an unknown key": (lambda d: {**d, "rows": [{**d["rows"][0], "evil": 1}]}, "rows[0].evil: unknown key"),
    "a list one short": (lambda d: {**d, "axes": d["axes"][:1]}, "axes: needs 2 values"),
}
COMPARE_ARGV = ["compare", "--quick", "--methods", "ilc", "--priors", "nominal", "--scenarios", "forward_parking"]
COMPARE_ARGV += ["--seeds", "0", "--workers", "1"]
SWEEP_ARGV = ["sweep", "forward_parking", "--grid", "3", "--trials", "3", "--methods", "ilc", "--nu-b", "1"]
SWEEP_ARGV += ["--workers", "1"]


def quiet(argv):
    """``main(argv)`` and what it wrote on stderr."""
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        code = main(argv)
    return code, err.getvalue().strip()


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """A compare run of one cell and a sweep of one 3 x 3 map (about 10 s each)."""
    home = tmp_path_factory.mktemp("records")
    assert quiet([*COMPARE_ARGV, "--out", str(home / "compare")])[0] == 0
    assert quiet([*SWEEP_ARGV, "--out", str(home / "sweep")])[0] == 0
    return home


def refused(code, err, path, message):
    assert code == 2 and len(err.splitlines()) == 1, (code, err)
    assert str(path) in err and message in err, err


@pytest.mark.parametrize("command", ["compare (resume)", "compare --against", "tables", "--against compare.json"])
@pytest.mark.parametrize("forgery", sorted(CELL_FORGERIES))
def test_a_forged_cell_is_refused_in_one_line_naming_the_file_and_the_key(runs, tmp_path, command, forgery):
    forge, message = CELL_FORGERIES[forgery]
    folder = tmp_path / "run"
    shutil.copytree(runs / "compare", folder)
    cell_file = next((folder / "cells").glob("*.json"))
    if command in ("compare (resume)", "compare --against"):
        cell_file.write_text(json.dumps(forge(json.loads(cell_file.read_text()))))
        where = cell_file
    else:  # the cells of compare.json (a clone that did not keep cells/)
        shutil.rmtree(folder / "cells")
        report = json.loads((folder / "compare.json").read_text())
        report["cells"][0] = forge(report["cells"][0])
        (folder / "compare.json").write_text(json.dumps(report))
        where, message = folder / "compare.json", f"cells[0].{message}"
    if command == "compare (resume)":
        argv = [*COMPARE_ARGV, "--out", str(folder)]
    elif command == "tables":
        page = tmp_path / "page.md"
        page.write_text("<!-- compare-table: nominal -->\nx\n<!-- /compare-table -->\n")
        argv = ["tables", str(folder), "--into", str(page), "--check"]
    else:
        argv = ["compare", "--methods", "newton", "--against", str(folder), "--out", str(tmp_path / "mine")]
    refused(*quiet(argv), where, message)


@pytest.mark.parametrize("forgery", sorted(ROW_FORGERIES))
def test_a_forged_sweep_row_is_refused_on_resume_in_one_line(runs, tmp_path, forgery):
    forge, message = ROW_FORGERIES[forgery]
    folder = tmp_path / "sweep"
    shutil.copytree(runs / "sweep", folder)
    row_file = sorted((folder / "rows").glob("*.json"))[0]
    row_file.write_text(json.dumps(forge(json.loads(row_file.read_text()))))
    refused(*quiet([*SWEEP_ARGV, "--out", str(folder)]), row_file, message)


@pytest.mark.parametrize("forgery", sorted(SWEEP_FORGERIES))
def test_a_forged_sweep_json_is_refused_by_the_robustness_report(tmp_path, forgery):
    forge, message = SWEEP_FORGERIES[forgery]
    out = tmp_path / "robustness"
    shutil.copytree(ROOT / "results" / "robustness", out)
    target = out / "forward_parking" / "sweep.json"
    target.write_text(json.dumps(forge(json.loads(target.read_text()))))
    done = subprocess.run(
        [sys.executable, "benchmarks/robustness.py", "--report", "--out", str(out)],
        capture_output=True,
        text=True,
        cwd=ROOT,
        env={"PYTHONPATH": str(ROOT), "PATH": ""},
    )
    refused(done.returncode, done.stderr.strip(), target, message)


@pytest.mark.parametrize(
    "folder",
    [
        "compare",
        "sweep",
        "sweep_blackbox",
        *sorted(p.name for p in (ROOT / "results" / "robustness").iterdir() if (p / "run.json").is_file()),
    ],
)
def test_the_committed_records_still_read(folder):
    """The committed folders are older formats in places (the maps' ``run.json`` hold no
    provenance): they read, and ``current`` calls each current (exit 0) or stale (exit 1), never
    malformed (exit 2) or an internal error (exit 3); a folder without provenance is stale."""
    results = ROOT / "results"
    path = results / folder if (results / folder).is_dir() else results / "robustness" / folder
    code, err = quiet(["current", str(path)])
    assert code in (0, 1), err
    if "provenance" not in json.loads((path / "run.json").read_text()):
        assert code == 1
    if (path / "compare.json").is_file():
        from ilc_steering.compare.cells import read_report

        assert len(read_report(path / "compare.json")["cells"]) > 0
    if (path / "sweep.json").is_file():
        from ilc_steering.sweep.report import read_report as read_sweep

        assert read_sweep(path / "sweep.json")["rows"]
    for row in sorted((path / "rows").glob("*.json"))[:20]:
        from ilc_steering.schema import check_record
        from ilc_steering.sweep.rows import RowRecord

        check_record(RowRecord, json.loads(row.read_text()), row)


VALUE_FORGERIES = {  # a cell of the right shape that its run could not have made -> the refusal's words
    "a level met at a negative trial": (lambda c: {**c, "trials_to": dict.fromkeys(c["trials_to"], -5)}, "trials_to"),
    "another budget": (lambda c: {**c, "budget": 3}, "holds budget 3, not 30"),
    "an unknown method": (lambda c: {**c, "method": "bogus_method"}, "not a cell of its run"),
    "a seed the run has not": (lambda c: {**c, "seed": 99}, "not a cell of its run"),
    "a best error that is not a number": (lambda c: {**c, "best_error": float("nan")}, "best_error nan"),
}


@pytest.mark.parametrize("forgery", [*sorted(VALUE_FORGERIES), "a cell twice"])
def test_tables_never_publish_a_cell_its_run_could_not_have_made(tmp_path, capsys, forgery):
    # the schema holds (a table of them rendered "-5 [-5, -5]", "(11/11)", a row "bogus_method"):
    # tables checks each cell as `compare --against` checks a committed run's
    folder = tmp_path / "run"
    folder.mkdir()
    shutil.copy(COMPARE / "run.json", folder / "run.json")
    report = json.loads((COMPARE / "compare.json").read_text())
    if forgery == "a cell twice":
        report["cells"].append(report["cells"][0])
        message = "twice"
    else:
        forge, message = VALUE_FORGERIES[forgery]
        report["cells"][0] = forge(report["cells"][0])
    (folder / "compare.json").write_text(json.dumps(report))
    page = tmp_path / "page.md"
    page.write_text("<!-- compare-table: nominal -->\nx\n<!-- /compare-table -->\n")
    assert main(["tables", str(folder), "--into", str(page)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "compare.json" in err and message in err, err
    assert page.read_text().count("\n") == 3  # not rewritten
