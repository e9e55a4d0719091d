"""ChainedSteeringEnv: the Gymnasium and SB3 contracts, determinism, bad input, what it reveals."""

import doctest
import pickle
import warnings
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from gymnasium.wrappers import RescaleAction

import ilc_steering  # noqa: F401  (registers the envs)
from ilc_steering.config import load_config
from ilc_steering.core.robots.car import CarModel
from ilc_steering.envs import steering_env

ENV_ID = "ilc_steering/ChainedSteering-v0"
CONFIGS = Path(__file__).resolve().parents[1] / "configs"
# The one warning check_env gives by design: the action box is in physical units (see the docstring).
DOCUMENTED = ("symmetric and normalized space",)


def make(config="forward_parking"):
    return gym.make(ENV_ID, config=config)


@pytest.mark.parametrize(
    "config", ["forward_parking", "forward_parking_saturated", "parallel_parking", "chained_perturbed"]
)
def test_gymnasium_check_env_passes_with_only_documented_warnings(config):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(make(config).unwrapped, skip_render_check=True)
    unexpected = [str(w.message) for w in caught if not any(d in str(w.message) for d in DOCUMENTED)]
    assert unexpected == []


@pytest.mark.extra("rl")
def test_sb3_check_env_passes_through_rescale_action_without_warnings():
    from stable_baselines3.common.env_checker import check_env as sb3_check_env

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        sb3_check_env(RescaleAction(make().unwrapped, np.float32(-1.0), np.float32(1.0)))
    assert [str(w.message) for w in caught] == []


def test_one_step_episode_and_info():
    env = make()
    obs, info = env.reset(seed=3)
    assert env.observation_space.contains(obs)
    np.testing.assert_array_equal(info["q_goal"], [0.0, 0.0, np.pi / 4, 0.0])
    c = env.unwrapped.nominal_model.solve()
    obs2, reward, terminated, truncated, info = env.step(c)
    assert (terminated, truncated) == (True, False)
    np.testing.assert_array_equal(obs2, obs)
    for key in (
        "q_final",
        "z_final",
        "error",
        "error_norm",
        "cartesian_error",
        "orientation_error",
        "left_chart",
        "action",
    ):
        assert key in info
    assert reward == pytest.approx(-(info["cartesian_error"] + info["orientation_error"]))
    assert info["cartesian_error"] == pytest.approx(np.hypot(*info["q_final"][:2]))
    np.testing.assert_allclose(info["error"], env.unwrapped.nominal_model.z_goal - info["z_final"])


def test_seeded_resets_are_deterministic_and_the_env_pickles():
    env = make("forward_parking_saturated")
    c = env.unwrapped.nominal_model.solve()
    first = [env.reset(seed=7)[0], env.step(c)[1]]
    again = [env.reset(seed=7)[0], env.step(c)[1]]
    clone = pickle.loads(pickle.dumps(env))
    cloned = [clone.reset(seed=7)[0], clone.step(c)[1]]
    for other in (again, cloned):
        np.testing.assert_array_equal(first[0], other[0])
        assert first[1] == other[1]


def test_bad_actions_raise_and_out_of_bound_actions_are_clipped():
    env = make()
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"shape \(4,\)"):
        env.step(np.zeros(3))
    with pytest.raises(ValueError, match="finite"):
        env.step(np.array([0.2, np.nan, 0.0, 0.0]))
    with pytest.raises(ValueError, match="numeric"):
        env.step(["a", "b", "c", "d"])
    big = env.unwrapped.action_space.high * 5
    *_, info = env.step(big)
    assert info["clipped"]
    np.testing.assert_allclose(info["action"], env.unwrapped.action_space.high)


def test_the_agent_sees_only_the_nominal_model():
    env = make()
    model = env.unwrapped.nominal_model
    assert model.chained_map == CarModel(0.2, 0.02)
    reachable = (
        [v for v in vars(model).values()] + list(vars(model.chained_map).values()) + list(vars(model.profile).values())
    )
    for value in reachable:
        assert not np.any(np.isin(np.atleast_1d(np.asarray(value, dtype=object)), [0.22, 0.022]))


def test_make_from_a_path_a_name_and_a_config_object():
    by_path = make(CONFIGS / "parallel_parking.yaml").unwrapped
    by_name = make("parallel_parking").unwrapped
    by_object = make(load_config("parallel_parking")).unwrapped
    for env in (by_path, by_object):
        np.testing.assert_array_equal(env.action_space.high, by_name.action_space.high)


@pytest.mark.parametrize("config", ["forward_parking", "parallel_parking", "forward_parking_saturated"])
def test_random_actions_from_the_box_always_give_a_finite_outcome(config):
    env = make(config)
    env.reset(seed=0)
    env.action_space.seed(11)
    chart_exits = 0
    for _ in range(300):
        *_, info = env.step(env.action_space.sample())
        assert np.all(np.isfinite(info["q_final"])) and np.isfinite(info["error_norm"])
        assert abs(info["q_final"][2] - env.unwrapped.config.task.start[2]) < np.pi
        chart_exits += info["left_chart"]
    assert chart_exits > 0  # the box is wide enough to reach the guard, which is what this tests


def test_render_mode_is_checked():
    with pytest.raises(ValueError, match="render_mode"):
        steering_env.ChainedSteeringEnv("forward_parking", render_mode="human")


def test_docstring_example_runs():
    results = doctest.testmod(steering_env, raise_on_error=False)
    assert results.attempted > 0 and results.failed == 0
