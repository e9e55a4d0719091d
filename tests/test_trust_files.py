"""Issue 34, class 3: files that block or crash a run.

Every file a run reads goes through :mod:`ilc_steering.readers` and every file it writes through
:mod:`ilc_steering.output`; a hostile path (a FIFO, a loop of links, a dangling link, a path under
a regular file, a name too long, a folder) is a one-line ``ValueError`` naming it, never a block
and never another exception. The property tests draw the path's kind and where it sits.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from ilc_steering.cli import main
from ilc_steering.output import check_output_dir, check_writable, write_atomic
from ilc_steering.readers import read_json, read_text

KINDS = ["fifo", "loop", "dangling", "under_file", "too_long", "folder", "missing", "link_to_fifo"]


def _hostile(root: Path, kind: str, name: str) -> Path:
    """A path of ``kind`` in ``root`` (created fresh for each draw)."""
    path = root / name
    if kind == "fifo":
        os.mkfifo(path)
    elif kind == "loop":
        path.symlink_to(path)
    elif kind == "dangling":
        path.symlink_to(root / "nowhere" / "x.json")
    elif kind == "under_file":
        (root / "plain").write_text("x")
        path = root / "plain" / name
    elif kind == "too_long":
        path = root / (name * (300 // len(name) + 1))
    elif kind == "folder":
        path.mkdir()
    elif kind == "link_to_fifo":
        os.mkfifo(root / "pipe")
        path.symlink_to(root / "pipe")
    return path


_NAMES = st.text(st.sampled_from("abcXYZ019_-."), min_size=1, max_size=12).filter(lambda s: s not in (".", ".."))


@pytest.mark.timeout(60)
@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(kind=st.sampled_from(KINDS), name=_NAMES, limit=st.integers(1, 1 << 20))
def test_the_reader_refuses_every_hostile_path_in_one_line_naming_it(tmp_path_factory, kind, name, limit):
    root = tmp_path_factory.mktemp("read")
    path = _hostile(root, kind, name)
    with pytest.raises(ValueError) as caught:
        read_text(path, limit)
    message = str(caught.value)
    assert str(path) in message and "\n" not in message


@pytest.mark.timeout(60)
@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(kind=st.sampled_from(KINDS), name=_NAMES)
def test_an_output_path_is_usable_or_refused_before_any_work_naming_the_option(tmp_path_factory, kind, name):
    root = tmp_path_factory.mktemp("write")
    path = _hostile(root, kind, name)
    try:
        check_writable(path, "--json")
    except ValueError as error:
        assert str(error).startswith("--json") and "\n" not in str(error)
        assert kind in ("fifo", "loop", "under_file", "too_long", "folder", "link_to_fifo")
        return
    assert kind in ("dangling", "missing")  # a new file (a dangling link: the file it names)
    write_atomic(path, "{}")  # what was checked is what is written
    assert read_json(path, 10) == {}


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(kind=st.sampled_from(["fifo", "loop", "under_file", "too_long", "link_to_fifo"]), name=_NAMES)
def test_the_writer_turns_every_os_error_into_a_value_error_naming_the_path(tmp_path_factory, kind, name):
    path = _hostile(tmp_path_factory.mktemp("atomic"), kind, name)
    with pytest.raises(ValueError, match="not a regular file|cannot|is a file, not a folder"):
        write_atomic(path, b"x")


def test_a_name_as_long_as_the_file_system_takes_is_written(tmp_path):
    path = tmp_path / ("a" * 250 + ".json")  # the temporary file's name must fit where this one does
    check_writable(path)
    write_atomic(path, "[]")
    assert read_json(path, 10) == []


@pytest.mark.timeout(30)
@pytest.mark.parametrize("kind", ["fifo", "loop", "dangling", "under_file", "too_long", "link_to_fifo"])
def test_plot_of_a_hostile_run_file_is_exit_2_at_once(tmp_path, capsys, kind):
    path = _hostile(tmp_path, kind, "run.json")
    assert main(["plot", str(path), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and str(path) in err


@pytest.mark.parametrize("kind", ["fifo", "loop", "under_file", "too_long"])
def test_an_output_folder_that_cannot_be_one_is_refused_naming_the_option(tmp_path, kind):
    path = _hostile(tmp_path, kind, "out")
    with pytest.raises(ValueError, match="^--out"):
        check_output_dir(path, "--out")


@pytest.mark.parametrize("kind", ["fifo", "folder", "loop"])
def test_a_report_path_that_cannot_be_written_is_refused_before_any_work(tmp_path, kind):
    from ilc_steering.output import check_reports

    _hostile(tmp_path, kind, "compare.md")
    with pytest.raises(ValueError, match=r"^--out \(compare\.md\)"):
        check_reports(tmp_path, ["compare.json", "compare.md"])
    assert not (tmp_path / "compare.json").exists()  # the check leaves nothing behind


@pytest.mark.timeout(30)
@pytest.mark.parametrize("kind", ["fifo", "loop", "folder", "link_to_fifo", "missing"])
def test_a_run_folders_lock_cannot_block_and_is_a_regular_file(tmp_path, kind):
    import fcntl

    from ilc_steering.output import open_lock

    path = _hostile(tmp_path, kind, ".lock")
    if kind != "missing":
        with pytest.raises(ValueError, match=r"\.lock"):
            open_lock(path)
        return
    descriptor = open_lock(path)
    try:
        fcntl.flock(descriptor, fcntl.LOCK_EX | fcntl.LOCK_NB)
    finally:
        os.close(descriptor)
    assert path.is_file()
