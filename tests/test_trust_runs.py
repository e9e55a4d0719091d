"""A run refused before it starts where it could not end well (issue 64): a hold its trials can never
reach, a MuJoCo task that is no whole number of control periods (the config's error, not the
plant's), an output folder that is a loop of links, for every command that makes one."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from ilc_steering.cli import main

CONFIGS = Path(__file__).resolve().parents[1] / "configs"


def one_line(capsys: pytest.CaptureFixture[str]) -> str:
    err = capsys.readouterr().err
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    return err


@pytest.mark.parametrize(("trials", "says"), [("2", "--trials 2"), (None, "the 2 trials of short (learning.trials)")])
def test_a_run_too_short_for_the_default_hold_is_refused(tmp_path, capsys, trials, says):
    data = yaml.safe_load((CONFIGS / "forward_parking.yaml").read_text())
    data["name"], data["learning"]["trials"] = "short", 2
    path = tmp_path / "short.yaml"
    path.write_text(yaml.safe_dump(data))
    assert main(["run", str(path), *(["--trials", trials] if trials else [])]) == 2
    assert f"the default --hold 3 is more than {says}: the run could never hold 3 trials" in one_line(capsys)
    assert main(["run", str(path), "--hold", "2", *(["--trials", trials] if trials else [])]) in (0, 1, 5)


@pytest.mark.extra("mujoco")
def test_a_mujoco_task_of_no_whole_control_periods_is_the_configs_error(tmp_path, capsys):
    data = yaml.safe_load((CONFIGS / "mujoco_forward_parking.yaml").read_text())
    data["task"]["pieces"] = [5.005]  # 500.5 periods of 0.01 s
    path = tmp_path / "mujoco.yaml"
    path.write_text(yaml.safe_dump(data))
    assert main(["run", str(path), "--trials", "3"]) == 2
    err = one_line(capsys)
    assert err.startswith("ilc-steering: config error: task.pieces: add up to 5.005 s, not a whole number")


@pytest.mark.parametrize(
    "argv",
    [
        ["run", "forward_parking", "--trials", "3", "--plots", "{loop}"],
        ["run", "forward_parking", "--trials", "3", "--json", "{loop}/run.json"],
        ["reproduce", "--json-dir", "{loop}"],
        ["session", "new", "{loop}", "--config", "experiment_forward_process"],
        ["session", "new", "{loop}/s", "--config", "experiment_forward_process"],
        ["sweep", "forward_parking", "--out", "{loop}"],
        ["compare", "--scenarios", "forward_parking", "--methods", "ilc", "--out", "{loop}"],
    ],
    ids=lambda argv: " ".join(argv[:2]) + (" (under it)" if "{loop}/" in " ".join(argv) else ""),
)
def test_an_output_folder_that_is_a_loop_of_links_is_refused_before_any_work(tmp_path, capsys, argv):
    loop = tmp_path / "loop"
    loop.symlink_to(loop)
    assert main([part.replace("{loop}", str(loop)) for part in argv]) == 2
    assert "Too many levels of symbolic links" in one_line(capsys)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["loop"]
