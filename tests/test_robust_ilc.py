"""``robust_ilc`` (global identification, continuation, a trust region) and the oracle of the maps."""

import dataclasses
import json

import numpy as np
import pytest

from ilc_steering.agents.base import LearnerContext
from ilc_steering.agents.newton_ilc import make_newton_ilc
from ilc_steering.agents.robust_ilc import make_robust_ilc
from ilc_steering.cli import main
from ilc_steering.config import load_config
from ilc_steering.core.family import ModelFamily
from ilc_steering.envs.scenario import Scenario
from ilc_steering.envs.steering_vector_env import ChainedSteeringVectorEnv
from ilc_steering.oracle import SOLVED, final_errors, oracle_map, solve_plants
from ilc_steering.sweep.rows import SweepArgs, lockstep, row_plants


def learn(config, plants, make, trials):
    """Trials to the config's tolerance of ``make``'s learner on each plant (0: not within ``trials``),
    and the true error norm of the last trial."""
    envs = ChainedSteeringVectorEnv(len(plants), config, true_plants=plants)
    context = LearnerContext(envs.nominal_model, envs.single_action_space, envs.single_observation_space)
    learners = [make(context) for _ in plants]
    result = lockstep(envs, learners, trials, config.learning.tolerance)
    return result["trials_to"].tolist(), result["error"], learners


def car(config, wheelbase, wheel_radius):
    """The config's car with its true geometry at these ratios to the nominal one."""
    plant = config.plant
    return dataclasses.replace(
        plant, true_wheelbase=plant.wheelbase * wheelbase, true_wheel_radius=plant.wheel_radius * wheel_radius
    ).plant()


def test_on_the_nominal_plant_the_first_update_lands_on_the_goal():
    config = load_config("forward_parking")
    trials, error, learners = learn(config, [car(config, 1.0, 1.0)], make_robust_ilc, 3)
    assert trials == [1]
    assert error[0] < 1e-9


@pytest.mark.slow  # about 8 s of identification
def test_where_the_nominal_solution_leaves_the_chart_it_identifies_the_plant_and_converges():
    # A wheelbase of half the nominal: the nominal solution jackknifes the true car; newton_ilc
    # never recovers, robust_ilc aims nearer the start, identifies the car and parks it.
    config = load_config("parallel_parking")
    plants = [car(config, 0.5, 1.0), car(config, 0.5, 1.375)]
    robust, error, learners = learn(config, plants, make_robust_ilc, 10)
    assert all(0 < k <= 6 for k in robust), robust
    assert np.all(error < 1e-6)
    assert np.allclose(learners[0].theta, [np.log(0.5), 0.0], atol=1e-6)  # the true geometry, identified
    newton, _, _ = learn(config, plants, make_newton_ilc, 10)
    assert newton == [0, 0]


def test_a_trailer_with_a_longer_hitch_is_learned_in_two_trials():
    # Its family leaves the hitch free: the first trial identifies it, the second parks the trailer.
    config = load_config("trailer_hitch")
    trials, error, learners = learn(config, [config.plant.plant()], make_robust_ilc, 5)
    assert trials == [2]
    ratios = ModelFamily(learners[0].model).parameters(learners[0].theta)
    assert ratios == pytest.approx({"wheelbase_ratio": 0.95, "wheel_radius_ratio": 1.0, "hitch_length_ratio": 1.2})


def test_it_repeats_a_trial_at_the_integrators_accuracy_and_records_every_update():
    config = load_config("forward_parking")
    envs = ChainedSteeringVectorEnv(1, config, true_plants=[car(config, 1.2, 0.9)])
    context = LearnerContext(envs.nominal_model, envs.single_action_space, envs.single_observation_space)
    learner = make_robust_ilc(context)
    envs.reset(seed=0)
    errors, actions = [], []
    for _ in range(6):
        actions.append(learner.act())
        _, _, _, _, info = envs.step(actions[-1][None])
        final = info["final_info"]
        errors.append(final["true_error_norm"][0])
        learner.learn({k: v[0] for k, v in final.items() if not k.startswith("_") and not k.startswith("true_")})
    assert errors[1] < 1e-8 < errors[0]  # one update from the nominal solution to the goal
    assert min(errors) < 1e-10  # then to the integrator's accuracy, where it repeats that trial
    assert np.array_equal(actions[-1], actions[-2])
    assert len(learner.update_seconds) == 6 and all(t >= 0 for t in learner.update_seconds)


@pytest.mark.parametrize("name", ["forward_parking", "unicycle_parking", "trailer_bay", "chained_perturbed"])
def test_the_family_batch_of_hypotheses_equals_one_hypothesis_at_a_time(name):
    config = load_config(name)
    family = ModelFamily(Scenario.from_config(config).nominal)
    rng = np.random.default_rng(3)
    thetas = rng.uniform(-0.3, 0.3, (4, family.size))
    c = np.tile(family.model.solve(), (4, 1)) * (1 + 0.01 * rng.standard_normal((4, family.model.solve().size)))
    many, ok_many = family.configurations_many(thetas, c)
    for k in range(4):
        one, ok = family.configurations(thetas[k], c[k])
        assert ok[0] == ok_many[k]
        assert np.array_equal(one[0], many[k])


def test_the_oracle_finds_coefficients_that_reach_the_goal_on_the_true_plant():
    config = load_config("parallel_parking")
    scenario = Scenario.from_config(config)
    args = SweepArgs(config="parallel_parking", grid=3)
    found = oracle_map(scenario, lambda row, reach: row_plants(args, config, row, reach), 3, 1)
    solvable = np.array(found["solvable"])
    assert solvable[1, 1]  # the nominal plant: its own solution
    assert solvable.sum() >= 7
    # checked independently: the solutions LM reaches from the nominal solution, run on each plant
    plants = row_plants(args, config, 0)
    c, _ = solve_plants(scenario, plants, np.tile(scenario.nominal.solve(), (3, 1)))
    errors = final_errors(scenario, plants, c)
    reached = errors < SOLVED
    assert np.all(solvable[0][reached])  # whatever one search reaches, the map counts as solvable
    envs = ChainedSteeringVectorEnv(3, config, true_plants=plants)
    envs.reset(seed=0)
    _, _, _, _, info = envs.step(c)
    assert np.allclose(info["final_info"]["true_error_norm"][reached], errors[reached], rtol=0, atol=1e-12)


@pytest.mark.slow  # a map with the oracle
def test_sweep_with_the_oracle_reports_the_share_of_the_solvable_region(tmp_path, capsys):
    out = tmp_path / "sweep"
    argv = ["sweep", "forward_parking", "--methods", "robust_ilc", "--grid", "3", "--trials", "6"]
    assert main([*argv, "--oracle", "--out", str(out)]) == 0
    report = json.loads((out / "sweep.json").read_text())
    oracle = json.loads((out / "oracle.json").read_text())
    lines = {line["method"]: line for line in report["rows"]}
    solvable = np.array(oracle["solvable"])
    assert lines["oracle"]["converged_fraction"] == pytest.approx(solvable.mean())
    first = np.array(report["maps"]["robust_ilc__nu1"])
    assert lines["robust_ilc"]["of_solvable"] == pytest.approx(((first > 0) & solvable).sum() / solvable.sum())
    assert "of the solvable region" in (out / "sweep.md").read_text()
    assert "knows the true plant" in (out / "sweep.md").read_text()
    # a resume reads the oracle's map back, checked; a tampered one is refused, naming the file
    assert main([*argv, "--oracle", "--out", str(out)]) == 0
    oracle["solvable"][0][0] = not oracle["solvable"][0][0]
    (out / "oracle.json").write_text(json.dumps(oracle))
    capsys.readouterr()
    assert main([*argv, "--oracle", "--out", str(out)]) == 2
    assert "oracle.json: solvable disagrees with error" in capsys.readouterr().err


@pytest.mark.slow  # a map
def test_sweep_over_plant_keys(tmp_path):
    out = tmp_path / "keys"
    argv = ["sweep", "trailer_hitch", "--methods", "robust_ilc", "--grid", "2", "--trials", "4"]
    axes = ["--axis", "true_hitch_length", "0.3", "0.36", "--axis", "true_wheelbase", "0.19", "0.2"]
    assert main([*argv, *axes, "--out", str(out)]) == 0
    report = json.loads((out / "sweep.json").read_text())
    assert report["axes"] == ["true_hitch_length", "true_wheelbase"]
    assert report["values"] == [[0.3, 0.36], [0.19, 0.2]]
    assert report["maps"]["robust_ilc__nu1"][0][1] == 1  # hitch 0.3, wheelbase 0.2: the nominal plant


@pytest.mark.parametrize(
    ("axes", "message"),
    [
        (["--axis", "no_such_key", "0", "1", "--axis", "true_wheelbase", "0.1", "0.3"], "no_such_key: not a key"),
        (["--axis", "true_wheelbase", "0.1", "0.3", "--axis", "true_wheelbase", "0.1", "0.3"], "given twice"),
        (["--axis", "true_wheelbase", "0.3", "0.1", "--axis", "true_wheel_radius", "0.01", "0.03"], "LOW < HIGH"),
        (["--axis", "true_wheelbase", "a", "0.3", "--axis", "true_wheel_radius", "0.01", "0.03"], "must be numbers"),
        (["--axis", "true_wheelbase", "0.1", "0.3"], "exactly two"),
        (["--axis", "true_wheelbase", "-0.1", "0.3", "--axis", "true_wheel_radius", "0.01", "0.03"], "invalid plant"),
        # a whole-number key was offered, and every grid of it refused: "must be a whole number ..., got 0.0"
        (["--axis", "encoder_pulses", "0", "1000", "--axis", "true_wheelbase", "0.1", "0.3"], "takes no real number"),
    ],
)
def test_sweep_refuses_bad_axes_in_one_line(tmp_path, capsys, axes, message):
    argv = ["sweep", "parallel_parking", "--grid", "3", "--trials", "2", *axes, "--out", str(tmp_path / "x")]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1


@pytest.mark.slow
def test_outside_the_geometry_family_it_identifies_the_servo_and_converges_where_eqs_33_34_do_not():
    # parallel_parking_servo: a 0.02 rad steering offset and a 0.05 s servo lag, neither in the
    # geometry's family; robust_ilc escalates to the family with the servo's parameters.
    from ilc_steering.agents.ilc import make_ilc_paper

    config = load_config("parallel_parking_servo")
    plant = config.plant.plant()
    robust, error, learners = learn(config, [plant], make_robust_ilc, 10)
    assert 0 < robust[0] <= 10, robust
    assert error[0] < 1e-6
    ratios = ModelFamily(learners[0].model).parameters(learners[0].theta[:2])
    assert ratios == pytest.approx({"wheelbase_ratio": 1.1, "wheel_radius_ratio": 1.1}, rel=1e-4)
    assert learners[0].theta[2:] == pytest.approx([0.02, 0.05], rel=1e-4)  # the offset [rad] and the lag [s]
    paper, _, _ = learn(config, [plant], make_ilc_paper, 10)
    assert paper == [0]


def test_inside_the_family_it_still_takes_two_trials():
    config = load_config("parallel_parking")
    trials, error, learners = learn(config, [car(config, 1.1, 1.1)], make_robust_ilc, 4)
    assert trials == [2]
    assert learners[0].family.names == ("wheelbase_ratio", "wheel_radius_ratio")  # no escalation
