"""A robot that does not repeat itself (issue 48): no drive nobody asked for, no failing trial
resent, convergence that stays, and learners that know the scatter.

The plant is ``tests/counted_car.py``: the kinematic car behind ``ExternalPlantBase``, counting
every call of its ``run_trials`` (a drive of a real robot), with an optional scatter of its final pose.
"""

from __future__ import annotations

from pathlib import Path

import gymnasium as gym
import pytest

import ilc_steering  # noqa: F401  (registers the envs)
from ilc_steering.agents.ilc import ILCAgent
from ilc_steering.core import robots
from ilc_steering.loop import run_trials

HERE = Path(__file__).parent
ENV = "ilc_steering/ChainedSteering-v0"


@pytest.fixture
def counted(tmp_path, monkeypatch):
    """A function ``(scatter, trials, tolerance) -> YAML path`` of forward parking on the counted
    car, registered in this process, its drive log emptied."""
    monkeypatch.syspath_prepend(str(HERE))
    monkeypatch.setattr(robots, "ROBOTS", dict(robots.ROBOTS))
    monkeypatch.setattr(robots, "_LOADED", dict(robots._LOADED))
    robots.register("counted_car", "counted_car:CountedCarConfig")
    import counted_car

    counted_car.DRIVES.clear()

    def write(scatter: float = 0.0, trials: int = 3, tolerance: float = 5e-4) -> Path:
        path = tmp_path / f"counted_{scatter:g}_{trials}_{tolerance:g}.yaml"
        path.write_text(counted_car.CONFIG.format(scatter=scatter, trials=trials, tolerance=tolerance))
        return path

    write.drives = counted_car.DRIVES  # type: ignore[attr-defined]
    return write


# 6. No drive nobody asked for ------------------------------------------------------------------


def test_run_drives_an_external_plant_once_per_counted_trial(counted, capsys):
    from ilc_steering.cli import main

    path = counted()
    assert main(["run", str(path), "--trials", "3"]) == 1  # 1 mm after three trials of eqs. 33-34
    out = capsys.readouterr().out
    assert out.count("\n    ") == 3 and "not converged within 3 trials" in out
    assert counted.drives == [1, 1, 1]  # the step-size check ran on the nominal model


def test_the_step_size_check_of_an_external_plant_runs_the_nominal_model(counted, tmp_path):
    from ilc_steering.config import load_config
    from ilc_steering.runner import step_warning

    assert step_warning(load_config(counted())) is None
    coarse = tmp_path / "coarse.yaml"
    coarse.write_text(counted().read_text().replace("learning:", "simulation: {max_step: 1.0}\nlearning:"))
    warning = step_warning(load_config(coarse))
    assert warning is not None and "simulation.max_step = 1 s is too coarse" in warning
    assert counted.drives == []


def test_compare_drives_an_external_plant_once_per_counted_trial(counted, tmp_path):
    from ilc_steering.compare import Args
    from ilc_steering.compare_cells import run_cell
    from ilc_steering.compare_plan import plan

    path = str(counted())
    args = Args(methods=("ilc", "newton_ilc"), scenarios=(path,), seeds=(0,), model_trials=4, out=tmp_path / "c")
    plan(args)  # the checks before any cell: the task's posedness, the step size
    assert counted.drives == []
    for method in ("ilc", "newton_ilc"):
        cell = run_cell(args, "nominal", method, path, 0)
        assert cell["trials"] == 4
    assert counted.drives == [1] * 8


def test_the_env_drives_an_external_plant_once_per_step(counted):
    env = gym.make(ENV, config=str(counted()))
    assert counted.drives == []
    rollout = run_trials(env, ILCAgent(env.unwrapped.nominal_model), 4, seed=0)
    assert len(rollout) == 4 and counted.drives == [1, 1, 1, 1]
    assert rollout.infos[-1]["cartesian_error"] == pytest.approx(1e-4, rel=0.01)  # eqs. 33-34: tenfold a trial


# 3. No learner repeats a failing trial ------------------------------------------------------------

EXTRAS = {"RL": "stable_baselines3", "cma_es": "cma", "bayes_opt": "botorch"}
"""The module each optional learner needs (its extra), by family or id."""
SLOW = {"RL", "bayes_opt"}  # an SB3 model's or a GP's set-up and updates take seconds per trial


def _every_learner():
    from ilc_steering.agents.registry import REGISTRY

    for name, spec in REGISTRY.items():
        marks = [pytest.mark.slow] if SLOW & {name, spec.family} else []
        yield pytest.param(name, marks=marks, id=name)


@pytest.mark.parametrize("name", _every_learner())
def test_no_learner_sends_a_failed_trial_again(name):
    """On a noisy plant whose tolerance no learner can reach (0.5 µm against 0.2 mm of measurement
    noise), no trial is followed by the same coefficients: each learner changes something."""
    import dataclasses
    import importlib.util

    import numpy as np

    from ilc_steering.agents.base import LearnerContext
    from ilc_steering.agents.registry import REGISTRY
    from ilc_steering.config import load_config
    from ilc_steering.core.score import within_tolerance

    spec = REGISTRY[name]
    needed = EXTRAS.get(name) or EXTRAS.get(spec.family)
    if needed is not None and importlib.util.find_spec(needed) is None:
        pytest.skip(f"{name} needs {needed} (its extra is not installed)")
    base = load_config("forward_parking_noisy")
    tolerance = dataclasses.replace(base.learning.tolerance, cartesian=5e-7, orientation=5e-7)
    config = dataclasses.replace(base, learning=dataclasses.replace(base.learning, tolerance=tolerance))
    trials = 12
    for seed in (0, 1):
        env = gym.make(ENV, config=config)
        learner = spec.make(LearnerContext.from_env(env, seed=seed), trials)
        rollout = run_trials(env, learner, trials, seed=seed, name=name)
        actions = [np.asarray(info["action"]) for info in rollout.infos]
        failed = [not within_tolerance(tolerance, info) for info in rollout.infos]
        assert all(failed)
        resent = [k + 2 for k in range(len(actions) - 1) if failed[k] and np.array_equal(actions[k], actions[k + 1])]
        assert resent == [], f"{name}, seed {seed}: trials {resent} resend the failed trial before them"
