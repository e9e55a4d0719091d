"""The learning law (eqs. 33-34) against its error dynamics (eq. 36), and on the paper's car."""

import gymnasium as gym
import numpy as np
import pytest

import ilc_steering  # noqa: F401  (registers the envs)
from ilc_steering.agents import ILCAgent
from ilc_steering.config import load_config
from ilc_steering.loop import run_trials
from ilc_steering.runner import run_ilc


def chained_config(n, pieces, v1_fixed, nu_a=1.0, nu_b=1.0, gains=(1.0, 1.0)):
    rng = np.random.default_rng(n + len(pieces))
    start = rng.normal(scale=0.3, size=n)
    goal = rng.normal(scale=0.3, size=n)
    return load_config(
        {
            "name": f"chained_n{n}_p{len(pieces)}",
            "plant": {"model": "chained", "dimension": n, "v1_gain": gains[0], "v2_gain": gains[1]},
            "task": {
                "start": start.tolist(),
                "goal": goal.tolist(),
                "pieces": pieces,
                "v1_fixed": v1_fixed,
                "v2_terms": n - 1,
            },
            "learning": {"nu_a": nu_a, "nu_b": nu_b, "trials": 8, "tolerance": {"error": 1e-9}},
        }
    )


def errors(config, trials):
    env = gym.make("ilc_steering/ChainedSteering-v0", config=config)
    agent = ILCAgent(env.unwrapped.nominal_model, config.learning.nu_a, config.learning.nu_b)
    model = env.unwrapped.nominal_model
    rollout = run_trials(env, agent, trials, seed=0)
    return np.array(
        [model.z_goal - model.z_start] + [info["error"] for info in rollout.infos]
    )  # from the zero iteration


@pytest.mark.parametrize("nu_b", [0.5, 1.5])
@pytest.mark.parametrize(
    "n, pieces, v1_fixed", [(4, [5.0], []), (5, [2.0, 1.5], [0.6]), (3, [1.0, 1.0, 2.0], [-0.5, 0.8])]
)
def test_error_contracts_by_one_minus_nu_on_the_nominal_system(n, pieces, v1_fixed, nu_b):
    nu_a = 0.7
    eps = errors(chained_config(n, pieces, v1_fixed, nu_a, nu_b), 6)
    # Eq. 36 for z_b from the zero iteration on; eq. 33's integrator for z_a from the first real trial.
    np.testing.assert_allclose(eps[1:, 1:], (1 - nu_b) * eps[:-1, 1:], rtol=1e-7, atol=1e-11)
    np.testing.assert_allclose(eps[2:, 0], (1 - nu_a) * eps[1:-1, 0], rtol=1e-9, atol=1e-13)


def test_nu_one_steers_exactly_after_the_first_update():
    eps = errors(chained_config(4, [5.0], [], 1.0, 1.0), 2)
    assert np.linalg.norm(eps[0]) > 0.1
    assert np.linalg.norm(eps[1]) < 1e-10
    # With a fixed v1 piece the zero iteration ignores it (section 4): z_b is exact at once, z_a one trial later.
    eps = errors(chained_config(5, [2.0, 1.5], [0.6]), 2)
    assert np.linalg.norm(eps[1, 1:]) < 1e-10 and abs(eps[1, 0]) > 0.5
    assert np.linalg.norm(eps[2]) < 1e-10


def test_nominal_car_contracts_like_the_chained_form():
    config = load_config("forward_parking")
    plant = {**config.plant.__dict__, "true_wheelbase": 0.2, "true_wheel_radius": 0.02}
    learning = {**config.learning.__dict__, "nu_b": 0.5}
    nominal = type(config)(config.name, type(config.plant)(**plant), config.task, type(config.learning)(**learning))
    eps = errors(nominal, 4)
    np.testing.assert_allclose(eps[1:, 1:], 0.5 * eps[:-1, 1:], rtol=1e-6, atol=1e-10)


@pytest.mark.parametrize("name, expected", [("forward_parking", 4), ("parallel_parking", 5), ("chained_perturbed", 8)])
def test_perturbed_plants_converge(name, expected):
    result = run_ilc(name)
    assert result.converged_at == expected
    errors = [t.error_norm for t in result.trials]
    assert errors[-1] < 1e-3 * errors[0]


def test_saturated_car_converges_with_the_learning_law_unchanged():
    result = run_ilc("forward_parking_saturated")
    assert result.converged_at is not None and result.converged_at <= 9
    cartesian = [t.cartesian_error for t in result.trials]
    assert cartesian[-1] < 1e-4


def test_ilc_actions_stay_inside_the_action_box():
    for name in ["forward_parking", "forward_parking_saturated", "parallel_parking", "chained_perturbed"]:
        env = gym.make("ilc_steering/ChainedSteering-v0", config=name)
        rollout = run_trials(env, ILCAgent(env.unwrapped.nominal_model), 6)
        for info in rollout.infos:
            c = info["action"]
            assert env.action_space.contains(c.astype(np.float32)), (name, c)
            assert not info["clipped"]


def test_agent_interface():
    env = gym.make("ilc_steering/ChainedSteering-v0", config="forward_parking")
    agent = ILCAgent(env.unwrapped.nominal_model)
    first = agent.act()
    first[0] = 99.0  # act() hands out a copy
    env.reset()
    *_, info = env.step(agent.act())
    agent.learn(info)
    assert not np.allclose(agent.act(), info["action"])
    agent.reset()
    np.testing.assert_array_equal(agent.act(), info["action"])
    for bad in (0.0, 2.0, -1.0):
        with pytest.raises(ValueError, match="nu_b"):
            ILCAgent(env.unwrapped.nominal_model, nu_b=bad)
