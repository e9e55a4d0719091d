"""A robot that does not repeat itself (issue 48): no drive nobody asked for, no failing trial
resent, convergence that stays, and learners that know the scatter.

The plant is ``tests/counted_car.py``: the kinematic car behind ``ExternalPlantBase``, counting
every call of its ``run_trials`` (a drive of a real robot), with an optional scatter of its final pose.
"""

from __future__ import annotations

import json
import re
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import ilc_steering  # noqa: F401  (registers the envs)
from ilc_steering.agents.ilc import ILCAgent
from ilc_steering.cli import main
from ilc_steering.core import robots
from ilc_steering.errors import PlantError
from ilc_steering.loop import run_trials
from ilc_steering.runner import run_ilc

HERE = Path(__file__).parent
ENV = "ilc_steering/ChainedSteering-v0"


@pytest.fixture
def counted(tmp_path, monkeypatch):
    """A function ``(scatter, trials, tolerance, seed) -> YAML path`` of forward parking on the
    counted car (``seed`` its scatter's plant seed), registered in this process, its drive log emptied."""
    monkeypatch.syspath_prepend(str(HERE))
    robots.names()  # the installed packages' robots are read into the table this test copies
    monkeypatch.setattr(robots, "ROBOTS", dict(robots.ROBOTS))
    monkeypatch.setattr(robots, "_LOADED", dict(robots._LOADED))
    robots.register("counted_car", "counted_car:CountedCarConfig")
    import counted_car

    counted_car.DRIVES.clear()

    def write(scatter: float = 0.0, trials: int = 3, tolerance: float = 5e-4, seed: int = 0) -> Path:
        path = tmp_path / f"counted_{scatter:g}_{trials}_{tolerance:g}_{seed}.yaml"
        path.write_text(counted_car.CONFIG.format(scatter=scatter, trials=trials, tolerance=tolerance, seed=seed))
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
    from ilc_steering.compare.args import Args
    from ilc_steering.compare.cells import run_cell
    from ilc_steering.compare.plan import plan

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


def test_the_vector_envs_drive_an_external_plant_once_per_counted_trial(counted):
    """The vector env runs a step's trials in one call of the plant, one drive each; Gymnasium's
    sync vector env of one-trial envs drives each env's plant once; resets drive nothing."""
    import numpy as np

    path = str(counted())
    envs = gym.make_vec(ENV, num_envs=3, vectorization_mode="vector_entry_point", config=path)
    envs.reset(seed=0)
    c = np.tile(envs.unwrapped.nominal_model.solve(), (3, 1))
    envs.step(c)
    envs.step(c)
    assert counted.drives == [3, 3]
    counted.drives.clear()
    sync = gym.make_vec(ENV, num_envs=2, vectorization_mode="sync", config=path)
    sync.reset(seed=0)
    sync.step(c[:2])
    assert counted.drives == [1, 1]


def test_the_cyclic_env_drives_an_external_plant_once_per_segment(counted, tmp_path):
    """A cycle of two segments on the counted car: one drive per step (a segment, a counted trial)."""
    import numpy as np

    from ilc_steering.agents.cyclic_ilc import CyclicILCAgent

    cyclic = (HERE.parent / "configs/cyclic_home_goal.yaml").read_text()
    plant = counted().read_text().split("task:")[0].split("plant:")[1]
    path = tmp_path / "cyclic_counted.yaml"
    path.write_text(cyclic.split("plant:")[0] + "plant:" + plant + "task:" + cyclic.split("task:")[1])
    env = gym.make("ilc_steering/CyclicSteering-v0", config=str(path))
    rollout = run_trials(env, CyclicILCAgent(env.unwrapped.nominal_models), 4, seed=0)
    assert len(rollout) == 4 and counted.drives == [1, 1, 1, 1]
    assert np.all(np.isfinite([info["error_norm"] for info in rollout.infos]))


# 3. No learner repeats a failing trial ------------------------------------------------------------

EXTRAS = {"RL": "stable_baselines3", "cma_es": "cma", "bayes_opt": "botorch"}
"""The module each optional learner needs (its extra), by family or id."""
SLOW = {"RL", "bayes_opt"}  # an SB3 model's or a GP's set-up and updates take seconds per trial


def _every_learner():
    from ilc_steering.agents.registry import REGISTRY

    for name, spec in REGISTRY.items():
        marks = [pytest.mark.slow] if SLOW & {name, spec.family} else []
        yield pytest.param(name, marks=marks, id=name)


@pytest.mark.parametrize("name", list(_every_learner()))
@pytest.mark.slow  # over 2.5 s: the README's test command stays under 5 min
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


@pytest.mark.parametrize("learner", ["newton_ilc", "robust_ilc"])
def test_a_model_s_misfit_on_a_plant_that_repeats_itself_is_not_averaged_away(learner):
    """On the trailer with a hitch (outside the learners' families, deterministic), the refit model's
    misfit once read as a scatter of 17 cm: ``newton_ilc`` entered the scatter's band and sent trial 4's
    coefficients from trial 5 to 30. One repeat shows the plant repeats itself; after it no action
    is sent a third time, and the band ends."""
    import numpy as np

    from ilc_steering.agents.scatter_band import shown_to_repeat
    from ilc_steering.agents.trial import Trial
    from ilc_steering.config import load_config
    from ilc_steering.core.score import within_tolerance

    config = load_config("trailer_hitch")
    result = run_ilc(config, learner=learner, trials=15)
    failed = [
        tuple(np.asarray(t.action).tolist())
        for t in result.trials
        if not within_tolerance(
            config.learning.tolerance,
            {
                "true_cartesian_error": t.cartesian_error,
                "true_orientation_error": t.orientation_error,
                "left_chart": t.left_chart,
            },
        )
    ]
    assert failed, "the test needs failed trials"
    assert max(failed.count(a) for a in failed) <= 2, f"{learner} sends a failed action three times or more"
    assert len(set(failed)) >= len(failed) - 1
    c, z = np.zeros(3), np.ones(4)
    same = [Trial(c, z, z, 1.0), Trial(c.copy(), z.copy(), z.copy(), 1.0)]
    assert shown_to_repeat(same) and not shown_to_repeat([same[0], Trial(c, z, z + 1e-3, 1.0)])


def test_outcomes_that_creep_are_not_draws_of_the_estimated_scatter():
    from ilc_steering.verdict import APART, apart

    rng = np.random.default_rng(0)
    groups = ((0, 1), (2,))
    sigma = np.array([2e-3, 1e-3])
    draws = rng.normal(size=(5, 3)) * np.array([2e-3, 2e-3, 1e-3])
    assert apart(draws, sigma, groups) and apart(draws[:1], sigma, groups)  # one outcome says nothing
    creeping = np.linspace(0.2, 0.16, 5)[:, None] * np.array([1.0, 0.0, 2.0])  # 1 cm a trial: sigma 0.34 m
    assert not apart(creeping, np.array([0.34, 0.21]), groups)
    # at the bound: half the mean square of the differences equals APART sigma^2 in every coordinate
    steps = np.cumsum(np.full((5, 3), np.sqrt(2 * APART)) * np.array([2e-3, 2e-3, 1e-3]), axis=0)
    assert apart(steps * (1 + 1e-9), sigma, groups) and not apart(steps * (1 - 1e-6), sigma, groups)


def test_run_does_not_call_a_diverging_run_on_a_deterministic_plant_converged_to_its_floor(capsys):
    """Eqs. 33-34 on the trailer with a hitch creep away from the goal; the residuals of the nominal
    model once read as a scatter of 8.8 m, and `run` said "converged to the plant's floor" (exit 5)."""
    code = main(["run", "trailer_hitch", "--learner", "ilc", "--trials", "30"])
    out = capsys.readouterr().out
    assert code == 1 and "floor" not in out and "repeatability" not in out


# 2. "Converged" means it stays -------------------------------------------------------------------


def test_a_run_has_converged_when_its_last_trials_hold_the_tolerance():
    from ilc_steering.verdict import verdict

    v = verdict([False, True, True, False, True, True, True])
    assert (v.converged_at, v.held, v.relapses) == (5, 3, [[2, 3]])
    v = verdict([False, True, False, True, True])  # two at the end: not yet
    assert (v.converged_at, v.held, v.relapses) == (None, 2, [[2, 2]])
    v = verdict([True, True, True, True, False])  # entered at once, and left at the last trial
    assert (v.converged_at, v.held, v.relapses) == (None, 0, [[1, 4]])
    assert verdict([False, True, True], hold=2).converged_at == 2
    assert verdict([]).converged_at is None


def test_the_scatter_estimate_is_unbiased_and_leaves_out_the_far_trials():
    import numpy as np

    from ilc_steering.core.scatter import MIN_TRIALS, estimate

    rng = np.random.default_rng(0)
    sigma = np.array([2e-3, 5e-4])  # [m] x and y, [rad] theta
    squares = []
    for _ in range(400):
        residuals = np.array([0.3, -0.1, 0.02]) + rng.standard_normal((12, 3)) * sigma[[0, 0, 1]]
        found = estimate(residuals, np.full(12, 1e-3), [(0, 1), (2,)])
        assert found is not None and found[1] == 11
        squares.append(found[0] ** 2)
    np.testing.assert_allclose(np.sqrt(np.mean(squares, axis=0)), sigma, rtol=0.04)
    # the first trials of a run, far from the goal, are not the scatter's
    residuals = np.vstack([[[0.5, 0.5, 0.2]], [[0.05, 0.01, 0.02]], rng.standard_normal((10, 3)) * 1e-3])
    errors = np.concatenate([[1.0, 0.1], np.full(10, 2e-3)])
    kept, dof = estimate(residuals, errors, [(0, 1), (2,)])
    assert dof == 9 and np.all(kept < 2e-3)
    assert estimate(residuals[: MIN_TRIALS - 1], errors[: MIN_TRIALS - 1], [(0, 1), (2,)]) is None
    with pytest.raises(ValueError, match=r"residuals \(m, nq\) and errors \(m,\) of one m"):
        estimate(residuals, errors[:3], [(0, 1)])


def test_an_estimate_far_above_what_the_last_trials_measure_is_not_the_plant_s():
    import numpy as np

    from ilc_steering.core.scatter import consistent

    sigma, groups = np.array([1e-3, 2e-3]), [(0, 1), (2,)]
    assert consistent(np.array([[1e-3, -5e-4, 2e-3]] * 3), sigma, groups)  # mean square 0.75 sigma^2
    assert not consistent(np.array([[4e-4, -4e-4, 8e-4]] * 3), sigma, groups)  # 0.16: the learner's moves


def test_run_says_a_tolerance_below_the_plant_s_scatter_is_its_floor(counted, capsys, tmp_path):
    """The counted car scattered by 1 mm / 1 mrad, a tolerance of 0.5 mm / 0.5 mrad, the paper's law:
    one trial within it (11; plant seed 2, run's env seed 1), out again; the estimated scatter and the
    floor are reported, exit 5."""
    import json

    from ilc_steering.cli import main

    path, out = counted(scatter=1e-3, trials=15, tolerance=5e-4, seed=2), tmp_path / "run.json"
    assert main(["run", str(path), "--json", str(out)]) == 5
    lines = capsys.readouterr().out.splitlines()
    assert "relapsed: within the tolerance at trial 11, out again at trial 12" in lines
    floor = [line for line in lines if "below this plant's repeatability" in line]
    assert len(floor) == 1 and floor[0].startswith("tolerance 0.0005 m / 0.0005 rad is below")
    assert floor[0].endswith(": converged to the plant's floor")
    assert not any(line.startswith(("converged at", "not converged")) for line in lines)
    run = json.loads(out.read_text())
    assert run["converged_at"] is None and run["hold"] == 3 and run["floor"] is True
    assert 1e-3 / 1.5 < run["scatter"]["cartesian"] < 1.5e-3 and run["scatter"]["dof"] == 13
    assert run["below"]["cartesian"][1] == pytest.approx(3 * run["scatter"]["cartesian"])
    assert counted.drives == [1] * 15


def test_a_tolerance_below_the_scatter_is_said_also_when_the_run_ends_outside_it(counted, capsys):
    """Asked to hold for all 15 trials, the first of them 10 cm off: not converged (exit 1), the
    tolerance still named as below the plant's repeatability, and no floor claimed."""
    from ilc_steering.cli import main

    assert main(["run", str(counted(scatter=1e-3, trials=15, tolerance=5e-4)), "--hold", "15"]) == 1
    lines = capsys.readouterr().out.splitlines()
    floor = [line for line in lines if "below this plant's repeatability" in line]
    assert len(floor) == 1 and "converged to the plant's floor" not in floor[0]
    assert lines[-1] == "not converged within 15 trials"


def test_every_relapse_is_reported_on_one_line(counted, capsys):
    from ilc_steering.cli import main

    assert main(["run", str(counted(scatter=3e-3, trials=15, tolerance=5e-3, seed=2))]) == 5
    relapses = [line for line in capsys.readouterr().out.splitlines() if line.startswith("relapsed")]
    assert relapses == [
        "relapsed: within the tolerance at trial 4, out again at trial 5; at trials 7-8, out again at trial 9; "
        "at trials 11-12, out again at trial 13"
    ]


def test_run_without_scatter_converges_and_holds(counted, capsys, tmp_path):
    import json

    from ilc_steering.cli import main

    assert main(["run", str(counted(trials=6)), "--json", str(tmp_path / "run.json")]) == 0
    out = capsys.readouterr().out
    assert "converged at trial 4 (held for the last 3 trials)" in out and "repeatability" not in out
    run = json.loads((tmp_path / "run.json").read_text())
    assert run["converged_at"] == 4 and run["held"] == 3 and run["relapses"] == [] and run["below"] == {}
    assert main(["run", str(counted(trials=5))]) == 1  # trials 4 and 5 within it: not yet held
    assert "not converged within 5 trials (the last 2 within the tolerance, 3 needed)" in capsys.readouterr().out
    assert main(["run", str(counted(trials=5)), "--hold", "2"]) == 0


@pytest.mark.parametrize("hold", ["0", "-1", "1000000000"])
def test_a_bad_hold_is_refused_in_one_line(hold, capsys):
    from ilc_steering.cli import main

    assert main(["run", "forward_parking", "--hold", hold]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--hold must be a whole number in [1, " in err


# 1. Learners that know the scatter -------------------------------------------------------------

SIGMA = 2e-4
"""[m, rad] forward_parking_noisy's measurement noise, per coordinate."""
SEEDS = (0, 1, 2, 3, 5)
"""Seed 4 is left out: its draws of the heading's noise over trials 3-15 have a sample standard
deviation of 0.50 sigma, so no estimate from them could be within a factor 1.5 of sigma."""


@pytest.mark.parametrize("learner", ["newton_ilc", "robust_ilc"])
@pytest.mark.slow  # over 2.5 s: the README's test command stays under 5 min
def test_learners_that_know_the_scatter_stop_chasing_it(learner):
    """Forward parking measured with 0.2 mm / 0.2 mrad of noise, 15 trials: the last five hold 4 sigma,
    the run's scatter estimate is within a factor 1.5 of sigma, and averaging brings the true error of
    the last five trials to 0.75 sigma (RMS over them, mean over the seeds). Measured: 0.52 sigma for
    both; eqs. 33-34, which pass every draw on whole, 1.5 sigma; on main newton_ilc (frozen at its
    luckiest trial) 1.1 sigma and robust_ilc 1.1 sigma."""
    import numpy as np

    from ilc_steering.runner import run_ilc

    rms = []
    for seed in SEEDS:
        result = run_ilc("forward_parking_noisy", trials=15, learner=learner, seed=seed)
        last = result.trials[-5:]
        assert max(t.cartesian_error for t in last) <= 4 * SIGMA and max(t.orientation_error for t in last) <= 4 * SIGMA
        scatter = result.verdict.scatter
        assert scatter is not None and result.converged_at is not None
        for key in ("cartesian", "orientation"):
            assert SIGMA / 1.5 < scatter[key] < 1.5 * SIGMA, (seed, key, scatter[key] / SIGMA)
        rms.append(np.sqrt(np.mean([t.cartesian_error**2 for t in last])))
    assert np.mean(rms) < 0.75 * SIGMA, np.array(rms) / SIGMA


# The scatter's seed follows the env's seed ---------------------------------------------------------


def _finals(env, seed, steps=3):
    """The true final configurations of ``steps`` trials of the nominal solution after ``reset(seed=seed)``."""
    import numpy as np

    env.reset(seed=seed)
    c = env.unwrapped.nominal_model.solve()
    return np.array([env.step(c)[4]["q_final"] for _ in range(steps)])


def test_an_external_plant_s_scatter_follows_the_env_s_seed(counted):
    """The same env seed gives the same trials (on a fresh env, and on the same env reset again),
    another seed another draw; the scatter is not the env's own stream of that seed."""
    import counted_car
    import numpy as np
    from gymnasium.utils import seeding

    path = str(counted(scatter=1e-3))
    first = _finals(gym.make(ENV, config=path), 5)
    again = gym.make(ENV, config=path)
    assert np.array_equal(_finals(again, 5), first)
    assert np.array_equal(_finals(again, 5), first)  # reset(seed=5) restarts the draws
    other = _finals(gym.make(ENV, config=path), 6)
    assert np.all(np.abs(other[:, :3] - first[:, :3]) > 1e-9)  # every coordinate of every trial moved
    assert np.ptp(first[:, :3], axis=0).min() > 1e-5  # the trials within a run differ (1 mm of scatter)
    env_stream = seeding.np_random(5)[0].standard_normal(6)
    plant_stream = counted_car.plant_generator(5, 0).standard_normal(6)
    assert np.all(env_stream != plant_stream)


def test_run_and_compare_seeds_reach_an_external_plant(counted, tmp_path):
    """``run``'s seed (``run_ilc(seed=...)``) and each of ``compare``'s seeds restart the plant's
    scatter: same seed, same trials; another seed, another draw."""
    from ilc_steering.compare.args import Args
    from ilc_steering.compare.cells import run_cell
    from ilc_steering.runner import run_ilc

    path = counted(scatter=1e-3, trials=4)

    def finals(seed):
        return [r.final_state for r in run_ilc(path, seed=seed).trials]

    assert finals(1) == finals(1)
    assert finals(1)[1:] != finals(2)[1:]
    args = Args(methods=("ilc",), scenarios=(str(path),), seeds=(0, 1), model_trials=4, out=tmp_path / "c")
    curves = [run_cell(args, "nominal", "ilc", str(path), seed)["curve"] for seed in (0, 0, 1)]
    assert curves[0] == curves[1] and curves[0] != curves[2]


def test_a_plant_written_before_reseed_keeps_working(counted):
    """An ``ExternalPlantBase`` subclass without a ``reseed`` of its own (the base's does nothing)
    still runs, its scatter its own seed's whatever the env's seed."""
    import counted_car
    import numpy as np

    from ilc_steering.core.external import ExternalPlantBase, is_external

    class Older(counted_car.CountedCarPlant):
        reseed = ExternalPlantBase.reseed

    def env_of_older():
        env = gym.make(ENV, config=str(counted(scatter=1e-3)))
        scenario = env.unwrapped._scenario
        scenario.external = scenario.plant = Older(scenario.external.car, 1e-3, 0)
        assert is_external(scenario.external)
        return env

    older = env_of_older()
    five = _finals(older, 5)
    assert np.array_equal(_finals(env_of_older(), 6), five)  # the env's seed does not reach it
    assert not np.array_equal(_finals(older, 5), five)  # nor restarts its draws


@pytest.mark.parametrize("seed", [-1, 1.5, True, "3"])
def test_a_bad_plant_seed_is_refused_in_one_line(seed):
    from ilc_steering.core.external import plant_generator

    with pytest.raises(ValueError, match=r"^an external plant's seed must be an integer >= 0, got") as error:
        plant_generator(seed)
    assert "\n" not in str(error.value)
    with pytest.raises(ValueError, match="plant seed"):
        plant_generator(0, seed)


def _hostile(mode: str, after: int = 0):
    """``run_trials`` of a user's in-process plant gone wrong in one way (``mode``), honest for its
    first ``after`` calls."""
    import counted_car

    from ilc_steering.core.external import ExternalTrials

    honest, calls = counted_car.CountedCarPlant.run_trials, []

    class Weird(BaseException):  # neither an Exception nor an interrupt
        pass

    def run_trials(self, profile, x0, c, record=False):
        calls.append(mode)
        if len(calls) <= after:
            return honest(self, profile, x0, c, record)
        b = c.shape[0]
        final = np.tile(x0[:, :4], 1)
        logs: object = [{} for _ in range(b)]
        if mode == "raises":
            raise ValueError("the robot's driver lost its socket")
        if mode in ("exits", "exits 3"):
            sys.exit(3 if mode == "exits 3" else 0)
        if mode == "weird":
            raise Weird("weird")
        if mode == "interrupt":
            raise KeyboardInterrupt
        if mode == "writes c":
            c[:] = np.nan  # the env's action, the learner's info["action"], if it were handed over
        if mode == "writes x0":
            x0[:] = 0.0
        if mode == "nan":
            final[0, 0] = np.nan
        if mode == "shape":
            final = final[:, :3]
        if mode == "strings":
            final = np.array([["a", "b", "c", "d"]] * b)
        logs = {"log object": [{"x": object()}], "log nan": [{"f": [1.0, np.nan]}], "log key": [{1: "a"}]}.get(
            mode, logs
        )
        logs = [{}, {}] if mode == "log count" else [] if mode == "no logs" else logs
        status = np.zeros(b, dtype=np.int64) + (7 if mode == "status" else 0)
        if mode == "type":
            return {"final": final}
        return ExternalTrials(final, status, logs=logs)

    run_trials.calls = calls  # type: ignore[attr-defined]  # cleared, the plant starts honest again
    return run_trials


READ_ONLY = "run_trials raised ValueError: assignment destination is read-only"


@pytest.mark.parametrize(
    ("mode", "says"),
    [
        ("raises", "run_trials raised ValueError: the robot's driver lost its socket"),
        ("exits", "run_trials raised SystemExit: 0"),  # before: exit 0, silent, no JSON
        ("exits 3", "run_trials raised SystemExit: 3"),  # before: exit 3, no message
        ("weird", "run_trials raised Weird: weird"),  # before: a traceback, exit 1
        ("writes c", READ_ONLY),  # before: NaN in info["action"], the learner blamed (LinAlgError)
        ("writes x0", READ_ONLY),  # (the profile's arrays: tests/test_protocols.py)
        ("nan", "not finite"),
        ("shape", "final states of shape (1, 3), not (1, 4)"),
        ("strings", "final states of dtype <U1, not real numbers"),  # before: "of shape (1, 4), not (1, 4)"
        ("status", "status [7]"),
        ("type", "a dict, not ExternalTrials"),
        ("log object", "a log that is not plain JSON data: logs[0]['x'] is <object"),  # before: exit 3 at write
        ("log nan", "logs[0]['f'][1] is nan, not a finite number"),  # before: a bare NaN in the --json file
        ("log key", "logs[0] has the key 1, not a string"),
        ("log count", "2 logs, not a list of one log per trial (1)"),
    ],
)
def test_a_users_in_process_plant_gone_wrong_is_named_as_the_failure(counted, monkeypatch, capsys, mode, says):
    """Not the learner's fault ("the env refused its action"), not an internal error, not a success:
    the plant's, exit 4, in one line; whatever it raises but an interrupt (``sys.exit()`` included)."""
    import counted_car

    monkeypatch.setattr(counted_car.CountedCarPlant, "run_trials", _hostile(mode))
    with pytest.raises(PlantError, match=re.escape(says)) as caught:
        run_ilc(counted(), trials=2)
    assert "the counted car" in str(caught.value)
    assert main(["run", str(counted()), "--trials", "2", "--hold", "2"]) == 4
    err = capsys.readouterr().err
    assert "the counted car" in err and len(err.splitlines()) == 1 and "bug" not in err


def test_a_plant_that_logs_nothing_runs_its_trials(counted, monkeypatch):
    """``ExternalTrials`` without ``logs`` (its default): each trial's log is ``{}`` (before: exit 3)."""
    import counted_car

    monkeypatch.setattr(counted_car.CountedCarPlant, "run_trials", _hostile("no logs"))
    assert [record.plant for record in run_ilc(counted(), trials=2).trials] == [{}, {}]


def test_a_plant_that_fails_after_trials_ran_keeps_them_in_strict_json(counted, monkeypatch, tmp_path, capsys):
    import counted_car

    monkeypatch.setattr(counted_car.CountedCarPlant, "run_trials", _hostile("log nan", after=2))
    out = tmp_path / "run.json"
    assert main(["run", str(counted()), "--trials", "3", "--json", str(out)]) == 4
    data = json.loads(out.read_text(), parse_constant=lambda name: pytest.fail(f"{name} in the JSON"))
    assert [t["trial"] for t in data["trials"]] == [1, 2] and data["trials"][0]["plant"] == {}


def test_an_interrupt_keeps_the_trials_that_ran_and_still_exits_as_interrupted(counted, monkeypatch, tmp_path, capsys):
    """Ctrl-C in trial 2 (the plant or the learner: the same loop): trial 1 is written where asked, one
    line says so, exit 130 (before: "ilc-steering: interrupted", no JSON)."""
    import counted_car

    hostile = _hostile("interrupt", after=1)
    monkeypatch.setattr(counted_car.CountedCarPlant, "run_trials", hostile)
    with pytest.raises(KeyboardInterrupt) as caught:
        run_ilc(counted(), trials=3)
    assert [t.trial for t in caught.value.partial.trials] == [1]
    hostile.calls.clear()
    out = tmp_path / "run.json"
    assert main(["run", str(counted()), "--trials", "3", "--json", str(out)]) == 130
    assert [t["trial"] for t in json.loads(out.read_text())["trials"]] == [1]
    err = capsys.readouterr().err
    assert err == f"ilc-steering: interrupted after 1 trial; what ran is kept in {out}\n"


def test_a_plant_whose_reseed_exits_is_named(counted, monkeypatch, capsys):
    import counted_car

    monkeypatch.setattr(counted_car.CountedCarPlant, "reseed", lambda self, seed: sys.exit(0))
    with pytest.raises(PlantError, match=r"the counted car: reseed raised SystemExit: 0"):
        run_ilc(counted(), trials=2)


def test_a_plant_seen_to_repeat_itself_has_no_scatter():
    from ilc_steering.core.scatter import repeats

    c, q = np.array([[1.0, 2.0], [1.5, 2.0], [1.0, 2.0]]), np.array([[0.1, 0.2], [0.3, 0.1], [0.1, 0.2]])
    assert repeats(c, q)
    assert not repeats(c, q + np.array([[0.0, 0.0], [0.0, 0.0], [1e-5, 0.0]]))  # one action, two outcomes: scatter
    assert not repeats(c[:2], q[:2]) and not repeats(c, np.where(np.arange(3)[:, None] == 2, np.nan, q))


CYCLE = """
import numpy as np


class Cycle:  # four actions about the nominal solution, in turn: each sent again every fourth trial
    def __init__(self, context):
        self.c0, self.k = context.first_action(), 0

    def reset(self):
        self.k = 0

    def act(self, observation):
        return self.c0 * (1.0 + 0.02 * (self.k % 4))

    def learn(self, info):
        self.k += 1


def make(context):
    return Cycle(context)
"""


def test_a_plant_that_repeats_itself_is_not_called_scattered(tmp_path, monkeypatch, capsys):
    """Parallel parking on the servo car (outside the nominal model's family): four actions in turn,
    12 trials. The nominal model's residuals differ from action to action and look like a scatter
    of centimetres; each action sent again ends where it did, so ``run`` says nothing of the plant's
    repeatability (before, "below this plant's repeatability, about 0.049 m / 0.15 rad")."""
    (tmp_path / "cycle.py").write_text(CYCLE)
    monkeypatch.syspath_prepend(str(tmp_path))
    text = (Path(__file__).parents[1] / "configs" / "parallel_parking_servo.yaml").read_text()
    path = tmp_path / "servo.yaml"
    path.write_text(text.replace("trials: 15", "trials: 12"))
    assert main(["run", str(path), "--learner", "cycle:make"]) == 1
    out = capsys.readouterr().out
    assert "repeatability" not in out and out.splitlines()[-1] == "not converged within 12 trials"


@pytest.mark.parametrize(("mode", "code"), [("interrupt", 130), ("exits", 4)])
def test_a_cyclic_run_ended_early_keeps_its_cycles(counted, monkeypatch, tmp_path, capsys, mode, code):
    """Cycle 1 (two segments) ran before the plant failed or the user interrupted in cycle 2: it is
    written (before: nothing was, whatever ended the run)."""
    import counted_car

    cyclic = (HERE.parent / "configs/cyclic_home_goal.yaml").read_text()
    plant = counted().read_text().split("task:")[0].split("plant:")[1]
    path = tmp_path / "cyclic_counted.yaml"
    path.write_text(cyclic.split("plant:")[0] + "plant:" + plant + "task:" + cyclic.split("task:")[1])
    monkeypatch.setattr(counted_car.CountedCarPlant, "run_trials", _hostile(mode, after=2))
    out = tmp_path / "cyclic.json"
    assert main(["run", str(path), "--trials", "3", "--json", str(out)]) == code
    assert [c["cycle"] for c in json.loads(out.read_text())["cycles"]] == [1]
    assert len(capsys.readouterr().err.splitlines()) == 1
