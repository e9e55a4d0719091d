"""The ilc-steering command: exit codes users gate CI on, the JSON it writes, reproduce."""

import json
import subprocess
import sys
from pathlib import Path

import pytest

from ilc_steering.cli import main
from ilc_steering.compare import command as compare

ROOT = Path(__file__).resolve().parents[1]


def test_run_writes_json_and_exits_0_when_converged(tmp_path, capsys):
    out = tmp_path / "run.json"
    assert main(["run", "forward_parking", "--json", str(out)]) == 0
    data = json.loads(out.read_text())
    assert data["name"] == "forward_parking" and data["converged_at"] == 4
    assert [t["trial"] for t in data["trials"]] == list(range(1, 11))
    first = data["trials"][0]
    assert set(first) >= {"trial", "cartesian_error", "orientation_error", "final_state", "error", "action"}
    assert len(first["final_state"]) == 4 and len(first["error"]) == 4 and len(first["action"]) == 4
    assert first["cartesian_error"] > data["trials"][-1]["cartesian_error"]
    assert "converged at trial 4" in capsys.readouterr().out


def test_run_exits_1_when_the_tolerance_is_not_met(capsys):
    assert main(["run", "forward_parking", "--trials", "2", "--hold", "2"]) == 1
    assert "not converged within 2 trials" in capsys.readouterr().out


def test_run_exits_2_with_the_key_on_a_bad_config(tmp_path, capsys):
    bad = tmp_path / "bad.yaml"
    bad.write_text("name: x\nplant: {model: car}\n")
    assert main(["run", str(bad)]) == 2
    err = capsys.readouterr().err
    assert "bad.yaml" in err and "plant.wheelbase: missing required key" in err


def test_chained_run_prints_the_error_norm(capsys):
    assert main(["run", "chained_perturbed"]) == 0
    assert "error norm" in capsys.readouterr().out


def _printed(text: str) -> list[str]:
    """What reproduce printed, but the committed file's header and where it wrote its JSON."""
    return [line for line in text.splitlines() if not line.startswith(("#", "wrote "))]


@pytest.mark.slow  # reproduce: six tasks and 10 seeds of two experiments
def test_reproduce_prints_the_comparison_table_and_writes_the_figures(tmp_path, capsys):
    figures = tmp_path.parent / f"{tmp_path.name}-figures"
    assert main(["reproduce", "--json-dir", str(tmp_path), "--plots", str(figures)]) == 0
    out = capsys.readouterr().out
    committed = (ROOT / "results/reproduce/reproduce.txt").read_text()
    assert _printed(out) == _printed(committed), (
        "results/reproduce/reproduce.txt is not what `ilc-steering reproduce` prints with this code: regenerate it "
        "with the command on its first line"
    )
    assert "| forward_parking | Figs. 3-6 | 4 | 4 |" in out
    assert "| parallel_parking | Figs. 11-14 | 5 | 5 |" in out
    assert "| cyclic_home_goal | Figs. 23-25 | not stated | 6 |" in out
    assert "forward_parking_saturated:" in out  # where it differs, it says why
    assert "| experiment_forward | Figs. 16-18 | 5 |" in out and "| experiment_parallel | Figs. 19-21 | 5 |" in out
    assert "Over 10 seeds of the localization noise" in out and "10/10 converged" in out
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "cyclic_home_goal.json",
        "experiment_forward.json",
        "experiment_parallel.json",
        "forward_parking.json",
        "forward_parking_saturated.json",
        "parallel_parking.json",
    ]
    one_trial = [
        f"{name}_{kind}.png"
        for name in (
            "experiment_forward",
            "experiment_parallel",
            "forward_parking",
            "forward_parking_saturated",
            "parallel_parking",
        )
        for kind in ("trajectory", "coordinates", "inputs", "errors")
    ]
    cyclic = ["cyclic_home_goal_path.png", "cyclic_home_goal_waypoint_errors.png"]
    assert sorted(p.name for p in figures.iterdir()) == sorted(one_trial + cyclic)


@pytest.mark.slow  # a fresh process
def test_python_dash_m_entry_point(tmp_path):
    # Outside the checkout: from its root, `python -m` would find the bare ilc_steering/ folder first.
    done = subprocess.run(
        [sys.executable, "-m", "ilc_steering", "run", "forward_parking", "--trials", "6"],
        capture_output=True,
        text=True,
        timeout=300,
        cwd=tmp_path,
    )
    assert done.returncode == 0, done.stderr
    assert "converged at trial 4" in done.stdout


@pytest.mark.slow
@pytest.mark.extra("rl", "bo")  # every default method: the RL ones and bayes_opt
def test_compare_quick_runs_every_method(quick_comparison):
    tmp_path = quick_comparison  # main(["compare", "--quick", "--out", ...]) == 0, once per session (conftest.py)
    table = (tmp_path / "compare.md").read_text()
    model_based = ("ilc", "ilc_paper", "newton", "newton_ilc")
    for method in (*model_based, "least_squares", "gauss_newton", "nelder_mead", "cma_es"):
        assert f"| forward_parking | {method} |" in table
    for method in ("ppo", "sac", "td3"):
        assert f"| forward_parking_noisy | {method} |" in table
    methods = len(compare.DEFAULT_METHODS)
    assert len(list((tmp_path / "cells").glob("*.json"))) == 2 * 6 * methods * 2  # priors, scenarios, methods, seeds


@pytest.mark.parametrize(
    "argv",
    [
        [],
        ["bogus"],
        ["run", "forward_parking", "--trials", "abc"],
        ["run"],
        ["compare", "--workers", "x"],
        ["sweep", "forward_parking", "--grid", "x"],
        ["session", "record", "folder", "--final", "abc", "0", "0"],
        ["session", "record", "folder"],
        ["session"],
        ["current"],
        ["tables", "results/compare"],
        ["plot", "run.json"],
        ["plot", "run.json", "--out", ""],
        ["compare", "--quick", "--out", ""],  # before: the working directory taken as the run folder
        ["sweep", "forward_parking", "--out", ""],
    ],
)
def test_a_bad_argument_is_one_line_naming_it_and_exit_2(argv, capsys):
    with pytest.raises(SystemExit) as stopped:
        main(argv)
    assert stopped.value.code == 2
    err = capsys.readouterr().err
    assert len(err.splitlines()) == 1, err
    assert err.startswith("ilc-steering") and ": error: " in err and err.rstrip().endswith("--help)"), err


@pytest.mark.parametrize(
    ("option", "value", "says"),
    [
        ("--plots", "", "argument --plots: an empty path"),  # before: PNGs written into the working directory
        ("--json", "", "argument --json: an empty path"),
        ("--json", "new.json/", "argument --json: new.json/: ends in '/', a folder's name"),  # before: file new.json
    ],
)
def test_an_output_path_that_path_would_change_is_refused_and_nothing_written(
    tmp_path, monkeypatch, capsys, option, value, says
):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SystemExit) as stopped:
        main(["run", "forward_parking", "--trials", "1", "--hold", "1", option, value])
    assert stopped.value.code == 2
    err = capsys.readouterr().err
    assert says in err and len(err.splitlines()) == 1
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    ("argv", "says"),
    [
        (["--trials", "2", "--hold", "50"], "--hold 50 is more than --trials 2"),
        (["--hold", "11"], "--hold 11 is more than the 10 trials of forward_parking (learning.trials)"),
    ],
)
def test_a_hold_longer_than_the_run_is_refused_naming_both(capsys, argv, says):
    """A run of 2 trials can never hold 50 within the tolerance (before: accepted, "not converged")."""
    assert main(["run", "forward_parking", *argv]) == 2
    err = capsys.readouterr().err
    assert says in err and len(err.splitlines()) == 1
    # the default --hold as well (issue 64: before, a short run "not converged", which it could never be)
    assert main(["run", "forward_parking", "--trials", "2"]) == 2
    assert "the default --hold 3 is more than --trials 2" in capsys.readouterr().err


def test_a_value_error_deep_in_the_numerics_is_a_bug_not_the_users_input(monkeypatch, capsys):
    """Only :class:`~ilc_steering.errors.BadInput` (raised where the user's value enters) is exit 2;
    a ``ValueError`` of numpy or scipy from inside the library is a bug: exit 3, saying so."""
    from ilc_steering.core import nominal

    def broken(self):
        raise ValueError("math domain error")

    monkeypatch.setattr(nominal.NominalModel, "solve", broken)
    assert main(["run", "forward_parking", "--trials", "1", "--hold", "1"]) == 3
    err = capsys.readouterr().err.strip()
    assert err.startswith("ilc-steering: internal error: ValueError: math domain error. This is a bug")
    assert len(err.splitlines()) == 1
    assert main(["--debug", "run", "forward_parking", "--trials", "1", "--hold", "1"]) == 3
    assert "Traceback (most recent call last)" in capsys.readouterr().err


def test_the_users_bad_input_is_still_exit_2(tmp_path, capsys):
    from ilc_steering.errors import BadInput, ConfigError, LimitError, ParameterError

    assert all(issubclass(kind, BadInput) for kind in (ConfigError, LimitError, ParameterError))
    assert issubclass(BadInput, ValueError)  # the API's callers that catch ValueError keep working
    assert main(["run", "forward_parking", "--trials", "0"]) == 2
    assert main(["run", str(tmp_path / "missing.yaml")]) == 2
    assert main(["sweep", "forward_parking", "--grid", "1", "--out", str(tmp_path / "s")]) == 2
    errors = capsys.readouterr().err.strip().splitlines()
    assert len(errors) == 3 and all(line.startswith("ilc-steering: ") for line in errors)


def test_list_aligns_its_columns_for_long_names(monkeypatch, capsys):
    import ilc_steering.cli as cli

    long = "a_packaged_config_whose_name_is_longer_than_the_old_column"
    names = ["forward_parking", long, "experiment_forward"]
    real = cli.load_config
    monkeypatch.setattr(cli, "packaged_configs", lambda: names)
    monkeypatch.setattr(cli, "load_config", lambda name: real("forward_parking" if name == long else name))
    assert main(["list"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert [line.split()[0] for line in lines] == names
    second = {line.index(line.split()[1], len(line.split()[0])) for line in lines}
    assert second == {len(long) + 2}  # every kind starts in one column, past the longest name
    figures = {line.index("Fig") for line in lines if "Fig" in line}
    assert len(figures) == 1 and len([line for line in lines if "Fig" in line]) >= 2  # the third column too
