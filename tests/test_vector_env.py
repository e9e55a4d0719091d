"""The natively batched env against Gymnasium's SyncVectorEnv of scalar envs, and SB3 on top of it."""

import doctest
from dataclasses import replace

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import data_equivalence
from gymnasium.vector import AutoresetMode
from gymnasium.wrappers import RescaleAction
from gymnasium.wrappers.vector import RescaleAction as VectorRescaleAction

import ilc_steering  # noqa: F401  (registers the envs)
from ilc_steering.config import load_config
from ilc_steering.envs import steering_vector_env
from ilc_steering.envs.steering_vector_env import ChainedSteeringVectorEnv

ENV_ID = "ilc_steering/ChainedSteering-v0"
CONFIGS = ["forward_parking", "forward_parking_saturated", "parallel_parking", "chained_perturbed"]


def native(num_envs, config, **kwargs):
    return gym.make_vec(ENV_ID, num_envs=num_envs, vectorization_mode="vector_entry_point", config=config, **kwargs)


def sync(num_envs, config):
    return gym.make_vec(
        ENV_ID,
        num_envs=num_envs,
        vectorization_mode="sync",
        config=config,
        vector_kwargs={"autoreset_mode": AutoresetMode.SAME_STEP},
    )


def actions(space, rng, num_envs, spread=1.5):
    """Random actions across (and past, so some are clipped) the box; some trials leave the chart."""
    high = space.high.astype(np.float64)
    return rng.uniform(-spread, spread, size=(num_envs, high.size)) * high


@pytest.mark.parametrize("config", CONFIGS)
def test_vector_env_matches_sync_vector_env_of_scalar_envs_bit_for_bit(config):
    a, b = native(6, config), sync(6, config)
    assert a.metadata["autoreset_mode"] == AutoresetMode.SAME_STEP
    assert a.action_space == b.action_space and a.observation_space == b.observation_space
    assert data_equivalence(a.reset(seed=3), b.reset(seed=3), exact=True)
    rng = np.random.default_rng(0)
    clipped = left = 0
    for _ in range(3):
        c = actions(a.single_action_space, rng, 6)
        out_a, out_b = a.step(c), b.step(c)
        for name, x, y in zip(["obs", "rewards", "terminations", "truncations", "info"], out_a, out_b):
            assert data_equivalence(x, y, exact=True), name
        assert out_a[2].all() and not out_a[3].any()  # every step is a whole trial: no reset steps
        clipped += out_a[4]["final_info"]["clipped"].sum()
        left += out_a[4]["final_info"]["left_chart"].sum()
    assert clipped > 0 and (left > 0 or config == "chained_perturbed")  # covered clipping and the car's chart guard


def test_every_step_is_a_trial_with_the_nominal_solution():
    envs = native(4, "forward_parking")
    obs, _ = envs.reset(seed=0)
    c = np.tile(envs.unwrapped.nominal_model.solve(), (4, 1))
    for _ in range(3):
        next_obs, rewards, terminations, truncations, info = envs.step(c)
        np.testing.assert_array_equal(next_obs, obs)  # the next episode's task
        np.testing.assert_allclose(info["final_info"]["cartesian_error"], 0.1, rtol=1e-6)  # 10% perturbation
        np.testing.assert_array_equal(
            rewards, -(info["final_info"]["cartesian_error"] + info["final_info"]["orientation_error"])
        )


def test_parallel_batches_equal_serial_ones():
    rng = np.random.default_rng(1)
    serial = ChainedSteeringVectorEnv(80, "forward_parking_saturated", parallel=False)
    parallel = ChainedSteeringVectorEnv(80, "forward_parking_saturated")
    assert parallel.parallel and not serial.parallel
    c = actions(serial.single_action_space, rng, 80, spread=0.5)
    serial.reset(seed=0), parallel.reset(seed=0)
    assert data_equivalence(serial.step(c), parallel.step(c), exact=True)


def lagged(config, lag, offset):
    """``config`` with its car's steering lag [s] and offset [rad] replaced."""
    return replace(config, plant=replace(config.plant, steering_lag=lag, steering_offset=offset))


@pytest.mark.parametrize("config_lag", [0.036, 0.0])
def test_each_true_plant_is_measured_as_the_single_env_with_it_bit_for_bit(config_lag):
    """Plants with and without a steering lag (and one with no servo at all, on the plain kernel)
    under a lagging config and under a lag-free one: env ``i`` of the vector env gives what the
    single env of plant ``i`` gives, noise included. (A lag-free car on the servo kernel reads its
    commanded wheel angle; the vector env once read every plant as the config's, the lag state.)"""
    config = lagged(load_config("parallel_parking_lag"), config_lag, 1e-4)
    points = [(0.0, 1e-4), (0.0125, 1e-4), (0.05, -0.02), (0.0, 0.0), (0.1, 0.0), (0.0, 0.03)]
    singles = [lagged(config, lag, offset) for lag, offset in points]
    envs = ChainedSteeringVectorEnv(
        len(points), config, measurement_noise=1e-4, true_plants=[c.plant.plant() for c in singles]
    )
    seeds = list(range(10, 10 + len(points)))
    envs.reset(seed=seeds)
    rng = np.random.default_rng(4)
    c = envs.nominal_model.solve() * (1 + 0.05 * rng.standard_normal((len(points), envs.single_action_space.shape[0])))
    final = envs.step(c)[4]["final_info"]
    measured_phi = []
    for i, single in enumerate(singles):
        env = gym.make(ENV_ID, config=single, measurement_noise=1e-4)
        env.reset(seed=seeds[i])
        info = env.step(c[i])[4]
        for key in ("error", "q_final", "z_final", "error_norm", "true_error_norm", "true_cartesian_error"):
            np.testing.assert_array_equal(final[key][i], info[key], err_msg=f"{points[i]}: {key}")
        measured_phi.append(info["q_final"][3])
    assert all(phi != 0.0 for phi in measured_phi)  # no wheel angle read from a state that never moved


def test_bad_input_is_named():
    envs = ChainedSteeringVectorEnv(3, "forward_parking")
    envs.reset(seed=0)
    with pytest.raises(ValueError, match=r"must have shape \(3, 4\)"):
        envs.step(np.zeros(4))
    c = np.zeros((3, 4))
    c[1, 2] = np.nan
    with pytest.raises(ValueError, match=r"rows \[1\]"):
        envs.step(c)
    with pytest.raises(ValueError, match="num_envs"):
        ChainedSteeringVectorEnv(0, "forward_parking")


@pytest.mark.extra("rl")
def test_sb3_adapter_matches_dummy_vec_env_and_ppo_trains_on_it():
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import DummyVecEnv, VecMonitor

    from ilc_steering.envs.sb3 import SB3VecEnv

    low, high = np.float32(-1), np.float32(1)
    batched = SB3VecEnv(VectorRescaleAction(native(4, "parallel_parking"), low, high))
    reference = DummyVecEnv([lambda: RescaleAction(gym.make(ENV_ID, config="parallel_parking"), low, high)] * 4)
    np.testing.assert_array_equal(batched.reset(), reference.reset())
    rng = np.random.default_rng(2)
    for _ in range(2):
        c = rng.uniform(-1, 1, size=(4, 4)).astype(np.float32)
        obs, rewards, dones, infos = batched.step(c)
        obs_r, rewards_r, dones_r, infos_r = reference.step(c)
        np.testing.assert_array_equal(obs, obs_r)
        np.testing.assert_array_equal(rewards, rewards_r)
        np.testing.assert_array_equal(dones, dones_r)
        for info, info_r in zip(infos, infos_r):
            assert info["cartesian_error"] == info_r["cartesian_error"]
            np.testing.assert_array_equal(info["terminal_observation"], info_r["terminal_observation"])
            assert info["TimeLimit.truncated"] is False and info_r["TimeLimit.truncated"] is False

    envs = VecMonitor(batched)
    model = PPO("MlpPolicy", envs, n_steps=8, batch_size=32, n_epochs=1, seed=0).learn(total_timesteps=64)
    assert model.num_timesteps == 64  # one timestep is one trial
    assert len(model.ep_info_buffer) == 64 and all(e["l"] == 1 for e in model.ep_info_buffer)
    assert envs.get_attr("render_mode") == [None] * 4


def test_docstring_example_runs():
    results = doctest.testmod(steering_vector_env, raise_on_error=False)
    assert results.attempted > 0 and results.failed == 0
