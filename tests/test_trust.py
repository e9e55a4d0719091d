"""Issue 26, results you can trust: one test (or more) per class of bad input, each able to fail."""

from __future__ import annotations

import json
import os
import stat
import tracemalloc
from pathlib import Path

import pytest

from ilc_steering.cli import main
from ilc_steering.config import ConfigError, load_config
from ilc_steering.inputs import MAX_DEPTH, read_json, read_text

CONFIGS = Path(__file__).resolve().parents[1] / "configs"
FORWARD = (CONFIGS / "forward_parking.yaml").read_text()


def _config(tmp_path: Path, old: str, new: str, name: str = "c.yaml") -> Path:
    assert old in FORWARD
    path = tmp_path / name
    path.write_text(FORWARD.replace(old, new))
    return path


# YAML surprises and the one reader


@pytest.mark.parametrize(("text", "reading"), [("010", "8"), ("1:30", "90"), ("-007", "-7")])
def test_yaml_integers_that_yaml_1_1_misreads_are_refused_naming_the_key(tmp_path, text, reading):
    path = _config(tmp_path, "trials: 10 ", f"trials: {text} ")
    message = rf"c\.yaml: learning\.trials: '{text}' is ambiguous: YAML 1\.1 reads it as {reading}"
    with pytest.raises(ConfigError, match=message):
        load_config(path)


def test_a_leading_zero_under_a_string_key_stays_text_and_plain_integers_are_read(tmp_path):
    assert load_config(_config(tmp_path, "name: forward_parking", "name: 010")).name == "010"
    assert load_config(_config(tmp_path, "trials: 10 ", "trials: 12 ")).learning.trials == 12
    assert load_config(_config(tmp_path, "trials: 10 ", "trials: 0x10 ")).learning.trials == 16


def test_a_merge_key_is_honoured_and_an_override_is_no_duplicate(tmp_path):
    tolerance = "  tolerance: {cartesian: 5.0e-4, orientation: 5.0e-4}"
    merged = "  tolerance:\n    <<: {cartesian: 1.0e-3, orientation: 1.0e-3}\n    orientation: 5.0e-4"
    config = load_config(_config(tmp_path, tolerance, merged))
    assert (config.learning.tolerance.cartesian, config.learning.tolerance.orientation) == (1e-3, 5e-4)
    with pytest.raises(ConfigError, match="duplicate key 'orientation'"):
        load_config(_config(tmp_path, tolerance, merged + "\n    orientation: 1.0e-4"))


def test_a_huge_config_is_refused_from_its_size_before_it_is_read(tmp_path):
    path = tmp_path / "huge.yaml"
    with open(path, "wb") as file:
        file.write(FORWARD.encode())
        file.truncate(3 << 30)  # sparse: 3 GB that would cost 3 GB to read
    tracemalloc.start()
    try:
        with pytest.raises(ConfigError, match=r"huge\.yaml: 3221225472 bytes; at most 1048576 bytes are read"):
            load_config(path)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 10 << 20


def test_the_reader_reads_at_most_its_limit_of_a_file_that_grows(tmp_path):
    path = tmp_path / "a.json"
    path.write_text("[" + "1," * 100 + "1]")
    with pytest.raises(ValueError, match=r"a\.json: .* at most 10 bytes"):
        read_text(path, 10)
    assert read_json(path, 1000) == [1] * 101


@pytest.mark.parametrize("depth", [MAX_DEPTH + 1, 20_000])
def test_deep_nesting_is_refused_with_a_message_not_a_recursion_error(tmp_path, depth):
    yaml_path = tmp_path / "deep.yaml"
    yaml_path.write_text("name: " + "[" * depth + "]" * depth + "\n")
    with pytest.raises(ConfigError, match=rf"deep\.yaml: nested deeper than {MAX_DEPTH} levels"):
        load_config(yaml_path)
    json_path = tmp_path / "deep.json"
    json_path.write_text('{"kind": "trials", "x": ' + "[" * depth + "]" * depth + "}")
    assert main(["plot", str(json_path), "--out", str(tmp_path / "p")]) == 2
    with pytest.raises(ValueError, match=rf"deep\.json: nested deeper than {MAX_DEPTH} levels"):
        read_json(json_path, 1 << 30)


def test_a_config_mapping_is_bounded_in_depth_too():
    data: list = []
    for _ in range(MAX_DEPTH + 5):
        data = [data]
    with pytest.raises(ConfigError, match="nested deeper"):
        load_config({"name": data})


def test_run_trials_is_bounded(capsys):
    assert main(["run", "forward_parking", "--trials", "1000000000"]) == 2
    assert "--trials" in capsys.readouterr().err


# One writer for every output


@pytest.mark.parametrize("kind", ["fifo", "folder"])
def test_run_json_onto_a_special_file_is_refused_and_the_file_kept(tmp_path, capsys, kind):
    target = tmp_path / "out.json"
    if kind == "fifo":
        os.mkfifo(target)
    else:
        target.mkdir()
    assert main(["run", "forward_parking", "--trials", "1", "--json", str(target)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "--json" in err and ("regular file" in err or "folder" in err)
    assert (stat.S_ISFIFO if kind == "fifo" else stat.S_ISDIR)(os.lstat(target).st_mode)


def test_the_writer_refuses_a_special_file_it_is_handed(tmp_path):
    from ilc_steering.output import write_atomic, write_json

    fifo = tmp_path / "f"
    os.mkfifo(fifo)
    with pytest.raises(ValueError, match="is a FIFO, not a regular file"):
        write_json(fifo, {})
    link = tmp_path / "link.json"
    (tmp_path / "real.json").write_text("old")
    link.symlink_to(tmp_path / "real.json")
    write_atomic(link, "new")
    assert link.is_symlink() and (tmp_path / "real.json").read_text() == "new"


@pytest.mark.parametrize(("mask", "mode"), [(0o022, 0o644), (0o077, 0o600), (0o002, 0o664)])
def test_outputs_keep_the_umask_and_a_replaced_file_its_mode(tmp_path, mask, mode):
    from ilc_steering.output import write_json
    from ilc_steering.tables import write_results

    old = os.umask(mask)
    try:
        write_json(tmp_path / "a.json", {"x": 1})
        write_results([{"a": 1}], tmp_path / "t", "s", "| a |\n")
    finally:
        os.umask(old)
    assert stat.S_IMODE(os.stat(tmp_path / "a.json").st_mode) == mode
    assert {stat.S_IMODE(p.stat().st_mode) for p in (tmp_path / "t").iterdir()} == {mode}
    os.chmod(tmp_path / "a.json", 0o640)
    write_json(tmp_path / "a.json", {"x": 2})
    assert stat.S_IMODE(os.stat(tmp_path / "a.json").st_mode) == 0o640
    assert json.loads((tmp_path / "a.json").read_text()) == {"x": 2}
