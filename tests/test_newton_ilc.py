"""The re-identifying learner (agents/newton_ilc.py): exact on the nominal plant, the true parameters
identified inside its family, and no worse than eqs. 33-34 outside it."""

import dataclasses

import gymnasium as gym
import numpy as np
import pytest

import ilc_steering  # noqa: F401  (registers the envs)
from ilc_steering.agents import LearnerContext
from ilc_steering.agents.ilc import make_ilc
from ilc_steering.agents.newton_ilc import NewtonILC, make_newton_ilc
from ilc_steering.config import load_config
from ilc_steering.core.family import ModelFamily
from ilc_steering.core.score import within_tolerance
from ilc_steering.loop import run_trials

EVERY_TASK = ["forward_parking", "forward_parking_saturated", "parallel_parking", "chained_perturbed"]


def config_with(name, **plant):
    config = load_config(name)
    return dataclasses.replace(config, plant=dataclasses.replace(config.plant, **plant)) if plant else config


def unperturbed(name):
    if name == "chained_perturbed":
        return config_with(name, v1_gain=1.0, v2_gain=1.0)
    plant = load_config(name).plant
    return config_with(name, true_wheelbase=plant.wheelbase, true_wheel_radius=plant.wheel_radius)


def setup(config, seed=0):
    env = gym.make("ilc_steering/ChainedSteering-v0", config=config)
    u = env.unwrapped
    learning = config.learning
    context = LearnerContext(u.nominal_model, u.action_space, u.observation_space, seed, learning.nu_a, learning.nu_b)
    return env, context


def trials_to_tolerance(config, make, trials=10):
    env, context = setup(config)
    learner = make(context)
    rollout = run_trials(env, learner, trials, seed=0)
    hits = [k for k, info in enumerate(rollout.infos, 1) if within_tolerance(config.learning.tolerance, info)]
    return (hits[0] if hits else None), learner


@pytest.mark.parametrize("name", ["forward_parking", "parallel_parking", "chained_perturbed"])
def test_the_family_at_theta_zero_is_the_nominal_model(name):
    # (with a steering limit it is not: the family keeps the stop, eq. 23 does not)
    model = setup(load_config(name))[1].model
    family = ModelFamily(model)
    c = model.solve() * np.array([1.0, *np.full(model.profile.v2_terms, 0.9)])
    q, ok = family.configurations(np.zeros(family.size), np.stack([model.solve(), c]))
    assert ok.all()
    expected = np.stack([model.final_state(model.solve()), model.final_state(c)])
    np.testing.assert_allclose(family.to_chained(q), expected, atol=1e-8)


@pytest.mark.parametrize("name", EVERY_TASK)
def test_one_update_lands_on_the_goal_on_the_nominal_plant(name):
    config = unperturbed(name)
    env, context = setup(config)
    model = context.model
    start = model.solve() + 0.05 * model.action_scale()  # a trial well off the goal
    learner = NewtonILC(model, start, context.action_space.low, context.action_space.high)
    rollout = run_trials(env, learner, 2, seed=0)
    assert rollout.infos[0]["error_norm"] > 1e-3
    assert rollout.infos[1]["error_norm"] < 1e-8
    np.testing.assert_allclose(learner.theta, 0.0, atol=1e-6)  # nothing to identify


@pytest.mark.parametrize(
    "name, truth",
    [
        ("forward_parking", {"wheelbase_ratio": 1.1, "wheel_radius_ratio": 1.1}),
        ("forward_parking_saturated", {"wheelbase_ratio": 1.1, "wheel_radius_ratio": 1.1}),
        ("chained_perturbed", {"v1_gain": 1.1, "v2_gain": 0.9}),
    ],
)
def test_the_identified_parameters_converge_to_the_true_ones(name, truth):
    config = load_config(name)
    if name != "chained_perturbed":
        config = config_with(name, true_wheelbase=0.2 * 1.05, true_wheel_radius=0.02 * 0.93)
        truth = {"wheelbase_ratio": 1.05, "wheel_radius_ratio": 0.93}
    env, context = setup(config)
    learner = make_newton_ilc(context)
    run_trials(env, learner, 3, seed=0)
    for key, value in learner.family.parameters(learner.theta).items():
        assert value == pytest.approx(truth[key], abs=1e-6), key


@pytest.mark.parametrize("name", EVERY_TASK)
def test_a_perturbation_inside_the_family_takes_two_trials(name):
    ilc, _ = trials_to_tolerance(load_config(name), make_ilc)
    ours, _ = trials_to_tolerance(load_config(name), make_newton_ilc)
    assert ours == 2 and ilc > ours  # ilc: 3 on parallel parking (its third error lands on 0.5 mm), 4 elsewhere


@pytest.mark.parametrize("name", ["forward_parking", "forward_parking_saturated"])
@pytest.mark.parametrize("perturbation", [{"steering_offset": 0.02}, {"steering_lag": 0.05}, {"speed_lag": 0.1}])
@pytest.mark.slow
def test_outside_the_family_it_converges_no_later_than_one_trial_after_eqs_33_34(name, perturbation):
    config = config_with(name, **perturbation)
    ilc, _ = trials_to_tolerance(config, make_ilc, 12)
    ours, learner = trials_to_tolerance(config, make_newton_ilc, 12)
    assert ilc is not None and ours is not None and ours <= ilc + 1
    assert 0.9 < learner.family.parameters(learner.theta)["wheel_radius_ratio"] < 1.2  # the fit stays physical


def test_a_trial_that_left_the_chart_falls_back_to_eqs_33_34():
    env, context = setup(load_config("forward_parking"))
    learner = make_newton_ilc(context)
    c = learner.act()
    info = {"action": c, "error": np.array([0.5, 1.0, -0.3, 0.2]), "left_chart": True}
    learner.learn(info)
    law = make_ilc(context)
    law.learn(info)
    np.testing.assert_allclose(learner.act(), law.act(), rtol=1e-12)
    np.testing.assert_allclose(learner.theta, 0.0)  # a halted trial is not fitted


def test_after_a_trial_that_left_the_chart_it_halves_the_step_from_the_best_trial():
    env, context = setup(load_config("forward_parking"))
    learner = make_newton_ilc(context)
    run_trials(env, learner, 1, seed=0)  # a best trial now exists
    best = learner._best.c
    wild = best + 0.4 * context.model.action_scale()
    learner.learn({"action": wild, "error": np.ones(4), "left_chart": True})
    np.testing.assert_allclose(learner.act(), best + 0.2 * context.model.action_scale(), rtol=1e-12)


def test_from_a_blind_start_it_still_needs_two_trials():
    config = load_config("forward_parking_saturated")
    env = gym.make("ilc_steering/ChainedSteering-v0", config=config)
    u = env.unwrapped
    for seed in (0, 1):
        context = LearnerContext(u.nominal_model, u.action_space, u.observation_space, seed, prior="none")
        rollout = run_trials(env, make_newton_ilc(context), 3, seed=seed)
        assert rollout.infos[0]["true_cartesian_error"] > 0.1
        assert within_tolerance(config.learning.tolerance, rollout.infos[1])
