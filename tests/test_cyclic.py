"""The cyclic env and learner (section 6): no resets, eq. 41's contraction, simulation 4."""

import dataclasses
import doctest
import pickle
import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import ilc_steering  # noqa: F401  (registers the envs)
from ilc_steering.agents import CyclicILCAgent
from ilc_steering.cli import main
from ilc_steering.config import load_config
from ilc_steering.envs import cyclic_env
from ilc_steering.errors import ConfigError
from ilc_steering.runner import run_cyclic_ilc

ENV_ID = "ilc_steering/CyclicSteering-v0"
DOCUMENTED = ("symmetric and normalized space", "infinity")


def chained_cycle(nu=0.6, gains=(1.0, 1.0)):
    return load_config(
        {
            "name": "chained_cycle",
            "plant": {"model": "chained", "dimension": 4, "v1_gain": gains[0], "v2_gain": gains[1]},
            "task": {
                "waypoints": [[0.0, 0.0, 0.0, 0.0], [1.0, 0.2, -0.3, 0.1], [2.0, -0.1, 0.2, 0.3]],
                "segments": [{"pieces": [2.0], "v1_fixed": [], "v2_terms": 3}],
                "action_bound": [1e3, 1e6, 1e6, 1e6],  # this test is about eq. 41, not the box
            },
            "learning": {"nu_a": nu, "nu_b": nu, "trials": 6, "tolerance": {"error": 1e-8}},
        }
    )


def waypoint_errors(config, cycles, start=None):
    env = gym.make(ENV_ID, config=config, cycles=cycles)
    agent = CyclicILCAgent(env.unwrapped.nominal_models, config.learning.nu_a, config.learning.nu_b)
    obs, _ = env.reset(seed=0, options=None if start is None else {"start": start})
    errors, truncated = [], False
    while not truncated:
        obs, _, _, truncated, info = env.step(agent.act(obs))
        agent.learn(info)
        errors.append(info["waypoint_error"])
    r = env.unwrapped.num_segments
    return np.array(errors).reshape(cycles, r, -1)


def test_check_env_passes_with_only_documented_warnings():
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(cyclic_env.CyclicSteeringEnv("cyclic_home_goal"), skip_render_check=True)
    assert [str(w.message) for w in caught if not any(d in str(w.message) for d in DOCUMENTED)] == []


def test_truncated_after_the_configured_cycles_and_never_reset():
    env = gym.make(ENV_ID, config="cyclic_pickup_dropoff", cycles=2)
    obs, info = env.reset(seed=0)
    model = env.unwrapped.nominal_models
    steps, truncated = 0, False
    while not truncated:
        segment = int(np.argmax(obs[4:]))
        obs, _, terminated, truncated, info = env.step(model[segment].solve())
        steps += 1
        assert not terminated and info["segment"] == segment and info["waypoint"] == segment + 1
        np.testing.assert_array_equal(obs[:4], info["z_final"])  # the next segment starts where this one ended
    assert steps == 2 * 3 and info["cycle"] == 2


def test_seeded_runs_repeat_and_the_env_pickles():
    env = cyclic_env.CyclicSteeringEnv("cyclic_home_goal")
    c = env.nominal_models[0].solve()
    first = [env.reset(seed=1)[0], env.step(c)[0]]
    clone = pickle.loads(pickle.dumps(env))
    again = [clone.reset(seed=1)[0], clone.step(c)[0]]
    for a, b in zip(first, again):
        np.testing.assert_array_equal(a, b)


def test_bad_input_is_named():
    env = cyclic_env.CyclicSteeringEnv("cyclic_home_goal")
    with pytest.raises(ValueError, match=r"options\['start'\] must have shape \(4,\)"):
        env.reset(options={"start": [0.0, 0.0]})
    with pytest.raises(ValueError, match="finite"):
        env.reset(options={"start": [np.nan, 0.0, 0.0, 0.0]})
    with pytest.raises(ValueError, match="theta"):
        env.reset(options={"start": [0.0, 0.0, 1.6, 0.0]})
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"action must have shape \(4,\)"):
        env.step(np.zeros(5))
    with pytest.raises(ValueError, match="needs task.waypoints"):
        cyclic_env.CyclicSteeringEnv("forward_parking")


@pytest.mark.parametrize("nu", [0.6, 1.4])
def test_waypoint_errors_contract_by_one_minus_nu_from_an_offset_start(nu):
    errors = waypoint_errors(chained_cycle(nu), 5, start=[0.3, -0.2, 0.1, 0.4])
    assert np.abs(errors[0]).max() > 0.05
    np.testing.assert_allclose(errors[1:], (1 - nu) * errors[:-1], rtol=1e-7, atol=1e-12)


def test_nominal_car_contracts_like_the_chained_form():
    config = load_config("cyclic_home_goal")
    plant = {**config.plant.__dict__, "true_wheelbase": 0.2, "true_wheel_radius": 0.02}
    learning = {**config.learning.__dict__, "nu_a": 0.5, "nu_b": 0.5}
    nominal = type(config)(config.name, type(config.plant)(**plant), config.task, type(config.learning)(**learning))
    errors = waypoint_errors(nominal, 4, start=[0.05, -0.05, 0.1, 0.0])
    np.testing.assert_allclose(errors[1:], 0.5 * errors[:-1], rtol=1e-6, atol=1e-10)


def test_simulation_4_converges_on_the_perturbed_car():
    result = run_cyclic_ilc("cyclic_home_goal")
    assert result.converged_at == 6
    last = result.cycles[-1].waypoints
    assert [w.trial for w in last] == [1, 2] and max(w.cartesian_error for w in last) < 1e-5


@pytest.mark.parametrize("start", [None, [0.15, -0.1, 0.2, 0.05]])
def test_three_waypoint_loop_converges(start):
    result = run_cyclic_ilc("cyclic_pickup_dropoff", start=start)
    assert result.converged_at is not None and result.converged_at <= 8
    assert len(result.cycles[0].waypoints) == 3


def test_cli_runs_cyclic_configs(tmp_path, capsys):
    out = tmp_path / "cycle.json"
    assert main(["run", "cyclic_home_goal", "--json", str(out)]) == 0
    import json

    data = json.loads(out.read_text())
    assert data["converged_at"] == 6 and len(data["cycles"]) == 10
    waypoint = data["cycles"][0]["waypoints"][1]
    assert waypoint["index"] == 2 and {"cartesian_error", "orientation_error", "final_state"} <= set(waypoint)
    assert main(["run", "cyclic_home_goal", "--trials", "3"]) == 1
    assert "wp2 cartesian [m]" in capsys.readouterr().out


def test_cyclic_config_errors():
    raw = chained_cycle().__dict__
    base = {
        "name": "c",
        "plant": {"model": "chained", "dimension": 4},
        "learning": {"nu_a": 1.0, "nu_b": 1.0, "trials": 2, "tolerance": {"error": 1e-3}},
    }
    assert raw["name"] == "chained_cycle"
    with pytest.raises(ConfigError, match="task.segments: needs 1 entry or one per segment"):
        load_config(
            {
                **base,
                "task": {
                    "waypoints": [[0, 0, 0, 0], [1, 0, 0, 0], [2, 0, 0, 0]],
                    "segments": [{"pieces": [1.0], "v1_fixed": [], "v2_terms": 3}] * 2,
                },
            }
        )
    with pytest.raises(ConfigError, match="task: needs exactly one of the keys"):
        load_config({**base, "task": {"pieces": [1.0]}})
    with pytest.raises(ConfigError, match=r"task.waypoints\[1\]: needs 4 values"):
        load_config(
            {
                **base,
                "task": {
                    "waypoints": [[0, 0, 0, 0], [1, 0, 0]],
                    "segments": [{"pieces": [1.0], "v1_fixed": [], "v2_terms": 3}],
                },
            }
        )


def test_docstring_example_runs():
    results = doctest.testmod(cyclic_env, raise_on_error=False)
    assert results.attempted > 0 and results.failed == 0


@pytest.mark.parametrize("servo", [{"steering_offset": 0.002}, {"steering_lag": 0.05}, {"speed_lag": 0.05}])
def test_the_cycle_runs_every_servo_plant_the_config_accepts(servo):
    """A servo car's state has the lab kernel's twelve entries (the wheel and drive lags fifth and sixth,
    play and encoders off): the cycle carries them from
    segment to segment, a reset starts them at rest, and the cycle still learns (the lag makes it slower)."""
    data = dataclasses.asdict(load_config("cyclic_home_goal"))
    data["plant"].update(servo)
    env = gym.make(ENV_ID, config=load_config(data), cycles=8)
    agent = CyclicILCAgent(env.unwrapped.nominal_models, 1.0, 1.0)
    for options in (None, {"start": [0.05, -0.02, 0.1, 0.0]}):
        obs, _ = env.reset(seed=0, options=options)
        assert env.unwrapped._x.shape == (12,) and env.unwrapped._x[5] == 0.0  # at rest: the wheel's speed 0
        truncated, errors = False, []
        while not truncated:
            obs, _, _, truncated, info = env.step(agent.act(obs))
            agent.learn(info)
            errors.append(info["cartesian_error"])
        assert errors[-1] < 0.05 * errors[0]
