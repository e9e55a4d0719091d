"""Names resolved once, at the start, to what they name (issue 64).

A packaged config's name is the packaged config, whatever folder of that name the working directory
holds, and it is read once: ``session new`` copies its text, ``sweep`` hands its rows the file it
named at the start, so a run folder of the same name (``sweep NAME --out NAME``) changes nothing.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from ilc_steering.cli import main
from ilc_steering.config import load_config
from ilc_steering.config.loading import resolve_config
from ilc_steering.errors import ConfigError
from ilc_steering.sweep.command import plan
from ilc_steering.sweep.rows import SweepArgs

PACKAGED = Path(__file__).resolve().parents[1] / "configs"


def test_a_folder_named_like_a_packaged_config_does_not_hide_it(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "forward_parking").mkdir()
    (tmp_path / "forward_parking" / "notes.txt").write_text("a run folder")
    assert load_config("forward_parking").name == "forward_parking"
    assert load_config(Path("forward_parking")).name == "forward_parking"


def test_a_regular_file_of_the_name_is_still_the_users(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    text = (PACKAGED / "unicycle_parking.yaml").read_text()
    (tmp_path / "forward_parking").write_text(text)
    assert load_config("forward_parking").name == "unicycle_parking"


def test_a_name_is_read_once_and_its_text_kept(tmp_path):
    source = resolve_config("experiment_forward_process")
    assert source.text == (PACKAGED / "experiment_forward_process.yaml").read_text()
    assert source.origin == "experiment_forward_process.yaml (packaged)" and source.folder is None
    assert load_config(source).name == "experiment_forward_process"


@pytest.mark.parametrize("name", ["no_such_scenario", Path("no_such_scenario")])
def test_an_unknown_name_is_named_as_typed(name):
    with pytest.raises(ConfigError) as refused:
        load_config(name)
    message = str(refused.value)
    assert message.startswith("'no_such_scenario' is neither") and "PosixPath" not in message


def test_session_new_takes_a_packaged_configs_name_and_copies_its_text(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "experiment_forward_process").mkdir()  # a folder of that name changes nothing
    assert main(["session", "new", "s", "--config", "experiment_forward_process", "--trials", "3"]) == 0
    assert (tmp_path / "s" / "config.yaml").read_text() == (PACKAGED / "experiment_forward_process.yaml").read_text()


def test_a_sweeps_rows_load_the_config_the_name_named_at_the_start(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    the_plan = plan(SweepArgs(config="forward_parking", grid=2, trials=2, out=tmp_path / "forward_parking"))
    (tmp_path / "forward_parking").mkdir()  # the run folder, made after the plan
    assert Path(the_plan.args.config).is_absolute()
    assert load_config(the_plan.args.config) == the_plan.config
    assert the_plan.settings["config"] == "forward_parking"  # what run.json records is the name


@pytest.mark.slow  # worker processes
def test_sweep_name_out_name_finishes_every_row(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    argv = ["sweep", "forward_parking", "--out", "forward_parking", "--grid", "2", "--trials", "2", "--workers", "1"]
    assert main(argv) == 0
    assert "all 2 rows finished" in capsys.readouterr().out
