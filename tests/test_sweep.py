"""Robustness maps (``ilc-steering sweep``): a learner per plant in lock-step on a vector env with
a true plant per env, against the one trial loop on each plant alone."""

import dataclasses
import json

import gymnasium as gym
import numpy as np
import pytest

import ilc_steering  # noqa: F401  (registers the envs)
from ilc_steering.agents import ILCAgent
from ilc_steering.cli import main
from ilc_steering.config import load_config
from ilc_steering.core.score import within_tolerance
from ilc_steering.envs.steering_vector_env import ChainedSteeringVectorEnv
from ilc_steering.loop import run_trials
from ilc_steering.sweep.rows import SweepArgs, lockstep, run_row


def alone(config, ratios, trials):
    """Trials to tolerance of the paper's law on the car at ``ratios`` (true / nominal), through run_trials."""
    plant = config.plant
    true = {"true_wheelbase": plant.wheelbase * ratios[0], "true_wheel_radius": plant.wheel_radius * ratios[1]}
    config = dataclasses.replace(config, plant=dataclasses.replace(plant, **true))
    env = gym.make("ilc_steering/ChainedSteering-v0", config=config)
    learner = ILCAgent(env.unwrapped.nominal_model, config.learning.nu_a, config.learning.nu_b)
    rollout = run_trials(env, learner, trials, seed=0)
    hits = [k for k, info in enumerate(rollout.infos, 1) if within_tolerance(config.learning.tolerance, info)]
    return hits[0] if hits else 0


def test_lockstep_on_a_vector_env_of_plants_equals_each_plant_in_the_trial_loop():
    config = load_config("forward_parking")
    ratios = np.array([[1.0, 1.0], [1.2, 0.9], [0.8, 1.1], [0.6, 1.4], [1.1, 1.1]])
    base = config.plant.plant().true_factors()
    envs = ChainedSteeringVectorEnv(len(ratios), config, true_factors=ratios / base)
    learners = [ILCAgent(envs.nominal_model) for _ in ratios]
    result = lockstep(envs, learners, 15, config.learning.tolerance)
    expected = [alone(config, r, 15) for r in ratios]
    assert result["trials_to"].tolist() == expected
    assert 0 in expected and max(expected) > 1  # one plant beyond the law's reach, others slower than the nominal


def test_a_row_is_the_first_factor_fixed_and_the_second_swept():
    args = SweepArgs(grid=5, trials=12)
    row = run_row(args, "ilc_paper", None, 2)  # wheelbase ratio 1.0
    config = load_config("forward_parking")
    assert row["trials_to"] == [alone(config, (1.0, r), 12) for r in np.linspace(0.5, 1.5, 5)]
    assert row["trials_to"][2] == 1  # the nominal plant: the nominal solution is exact


def test_the_vector_env_refuses_bad_true_factors():
    with pytest.raises(ValueError, match=r"true_factors must have shape \(3, 2\)"):
        ChainedSteeringVectorEnv(3, "forward_parking", true_factors=np.ones((2, 2)))
    with pytest.raises(ValueError, match=r"true_factors\[1\]: wheelbase_ratio: must be a ratio in .*, got 0.0"):
        ChainedSteeringVectorEnv(2, "forward_parking", true_factors=[[1.0, 1.0], [0.0, 1.0]])
    with pytest.raises(ValueError, match="true_factors must be finite"):
        ChainedSteeringVectorEnv(2, "forward_parking", true_factors=[[1.0, np.nan], [1.0, 1.0]])


@pytest.mark.slow  # a map
def test_the_sweep_command_writes_a_map_and_resumes(tmp_path, capsys):
    out = tmp_path / "sweep"
    argv = ["sweep", "forward_parking", "--grid", "3", "--trials", "8", "--out", str(out), "--nu-b", "1", "0.5"]
    assert main(argv) == 0
    data = json.loads((out / "sweep.json").read_text())
    assert sorted(data["maps"]) == ["ilc_paper__nu0.5", "ilc_paper__nu1"]
    grid = np.array(data["maps"]["ilc_paper__nu1"])
    assert grid.shape == (3, 3) and grid[1, 1] == 1
    for gain in ("0.5", "1"):
        assert (out / f"sweep_ilc_paper_nu{gain}.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    rows = sorted((out / "rows").iterdir())
    assert len(rows) == 6
    stamps = [path.stat().st_mtime_ns for path in rows]
    assert main(argv) == 0  # resumed: nothing recomputed, the same map
    assert [path.stat().st_mtime_ns for path in rows] == stamps
    assert json.loads((out / "sweep.json").read_text())["maps"] == data["maps"]
    capsys.readouterr()
    assert main([*argv[:-3], "--trials", "9"]) == 2  # other settings: refused, not mixed
    assert "run.json was written with" in capsys.readouterr().err


@pytest.mark.parametrize(
    "extra, message",
    [
        (["--grid", "1"], "--grid must be"),
        (["--range", "1.5", "0.5"], "--range must be"),
        (["--methods", "ppo"], "RL trains a network per plant"),
        (["--methods", "nope"], "unknown method"),
        (["--nu-b", "nan"], "--nu-b must be"),
    ],
)
def test_the_sweep_command_refuses_bad_input_before_any_trial(tmp_path, capsys, extra, message):
    assert main(["sweep", "forward_parking", "--out", str(tmp_path / "s"), *extra]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1
    assert not (tmp_path / "s" / "rows").exists() or not any((tmp_path / "s" / "rows").iterdir())


def test_the_sweep_refuses_a_cyclic_task(tmp_path, capsys):
    assert main(["sweep", "cyclic_home_goal", "--out", str(tmp_path / "s")]) == 2
    assert "cyclic" in capsys.readouterr().err


def test_a_folder_with_rows_but_no_settings_is_refused(tmp_path, capsys):
    (tmp_path / "s" / "rows").mkdir(parents=True)
    (tmp_path / "s" / "rows" / "ilc_paper__nu1__000.json").write_text("{}")
    assert main(["sweep", "forward_parking", "--grid", "3", "--out", str(tmp_path / "s")]) == 2
    assert "no run.json" in capsys.readouterr().err


@pytest.mark.slow
@pytest.mark.parametrize(("method", "row"), [("ilc_paper", 0), ("ilc_paper", 7)])
def test_committed_robustness_rows_are_recomputed_bit_for_bit_or_said_stale(method, row):
    """The engine and the vector trial loop reproduce the committed rows of results/robustness exactly
    wherever a row's code says it is current; a stale row (its closure changed since) must be said
    stale by ``ilc-steering current``, and a resume recomputes it."""
    from pathlib import Path

    from ilc_steering.current import check_folders
    from ilc_steering.engine.provenance import read_run
    from ilc_steering.engine.staleness import configs_today, staleness

    folder = Path(__file__).parents[1] / "results" / "robustness" / "forward_parking"
    settings, record = read_run(folder)
    args = SweepArgs(
        config=settings["config"],
        grid=settings["grid"],
        low=settings["low"],
        high=settings["high"],
        trials=settings["trials"],
        seed=settings["seed"],
    )
    committed = json.loads((folder / "rows" / f"{method}__nu1__{row:03d}.json").read_text())
    if staleness({**committed, "config": settings["config"]}, record.codes, configs_today([settings["config"]])):
        current, lines = check_folders([folder])
        assert not current and any(f"of {method}:" in line for line in lines), lines
        return  # stale, and said to be: a resume recomputes it
    mine = run_row(args, method, None, row)
    for key in ("trials_to", "error", "left_chart", "nu_b", "row"):
        assert mine[key] == committed[key], key


def test_a_learner_that_cannot_be_imported_is_refused_before_any_row(tmp_path, capsys):
    out = tmp_path / "sweep"
    argv = ["sweep", "forward_parking", "--methods", "no_such_module:make", "--grid", "2", "--trials", "2"]
    assert main([*argv, "--out", str(out)]) == 2
    assert "cannot import it" in capsys.readouterr().err
    assert not out.exists()
