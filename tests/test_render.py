"""Rendering and trajectory recording: frames from both envs, Gymnasium's render checks, and
recorded trajectories checked against the trial's final state and a solve_ivp reference."""

import dataclasses
import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import ilc_steering  # noqa: F401  (registers the envs)
from ilc_steering.agents import CyclicILCAgent
from ilc_steering.config import load_config
from ilc_steering.core.reference import reference_trial
from ilc_steering.core.robots.car import car_outline, chained_inputs

STEERING, CYCLIC = "ilc_steering/ChainedSteering-v0", "ilc_steering/CyclicSteering-v0"
DOCUMENTED = ("symmetric and normalized space", "observation space minimum", "observation space maximum")


def ink(frame):
    """The fraction of pixels that are not (near) white."""
    return float(np.mean(np.any(frame < 240, axis=-1)))


@pytest.mark.parametrize(
    ("env_id", "config"),
    [
        (STEERING, "forward_parking"),
        (STEERING, "forward_parking_saturated"),
        (STEERING, "chained_perturbed"),
        (CYCLIC, "cyclic_home_goal"),
    ],
)
def test_a_frame_shows_the_task_and_then_the_trial(env_id, config):
    env = gym.make(env_id, config=config, render_mode="rgb_array")
    env.reset(seed=0)
    before = env.render()
    models = getattr(env.unwrapped, "nominal_models", None) or [env.unwrapped.nominal_model]
    env.step(models[0].solve())
    after = env.render()
    for frame in (before, after):
        assert frame.shape == (480, 480, 3) and frame.dtype == np.uint8
        assert 0.01 < ink(frame) < 0.6  # axes, cars and text, on a white page
    assert len(np.unique(after.reshape(-1, 3), axis=0)) > 20
    assert np.any(before != after)  # the trial's path and cars appeared
    env.close()


@pytest.mark.parametrize(("env_id", "config"), [(STEERING, "forward_parking"), (CYCLIC, "cyclic_home_goal")])
def test_gymnasium_render_checks_pass(env_id, config):
    assert gym.spec(env_id) is not None
    for render_mode in (None, "rgb_array"):
        env = gym.make(env_id, config=config, render_mode=render_mode)
        assert env.unwrapped.metadata["render_modes"] == ["rgb_array"] and env.unwrapped.metadata["render_fps"] > 0
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            check_env(env.unwrapped)  # with render_mode None it makes one env per declared mode
        unexpected = [str(w.message) for w in caught if not any(d in str(w.message) for d in DOCUMENTED)]
        assert unexpected == []


def test_render_without_a_render_mode_warns_and_returns_none():
    env = gym.make(STEERING, config="forward_parking")
    env.reset(seed=0)
    with pytest.warns(UserWarning, match="render_mode"):
        assert env.unwrapped.render() is None


def test_car_outline_puts_the_front_wheel_one_wheelbase_ahead_turned_by_phi():
    q = np.array([1.0, 2.0, 0.3, -0.4])
    body, rear, front = car_outline(q, 0.2)
    assert np.allclose(rear.mean(axis=0), q[:2])
    assert np.allclose(front.mean(axis=0), q[:2] + 0.2 * np.array([np.cos(0.3), np.sin(0.3)]))
    direction = front[1] - front[0]
    assert np.isclose(np.arctan2(direction[1], direction[0]), 0.3 - 0.4)
    assert np.allclose(body[0], body[-1])  # a closed polygon


def test_trajectories_are_off_by_default_and_do_not_change_the_trial():
    plain = gym.make(STEERING, config="forward_parking_saturated")
    recording = gym.make(STEERING, config="forward_parking_saturated", record_trajectory=True)
    c = plain.unwrapped.nominal_model.solve() * 1.05
    for env in (plain, recording):
        env.reset(seed=0)
    *_, info = plain.step(c)
    *_, recorded = recording.step(c)
    assert "trajectory" not in info
    assert np.array_equal(info["q_final"], recorded["q_final"])  # bit for bit
    trajectory = recorded["trajectory"]
    assert np.array_equal(trajectory.q[-1], recorded["q_final"])
    assert np.array_equal(trajectory.q[0], plain.unwrapped._scenario.start)
    assert trajectory.t[0] == 0.0 and np.isclose(trajectory.t[-1], 5.0) and np.all(np.diff(trajectory.t) > 0)
    assert np.max(np.abs(trajectory.q[:, 3])) <= np.pi / 4 + 1e-15  # the wheel stays at the stop
    assert np.sum(np.isclose(np.abs(trajectory.q[:, 3]), np.pi / 4)) > 10  # and rests there a while


def test_trajectory_matches_solve_ivp_at_every_sample():
    env = gym.make(STEERING, config="forward_parking", record_trajectory=True)
    env.reset(seed=0)
    c = env.unwrapped.nominal_model.solve() * np.array([1.1, 0.9, 1.05, 0.95])
    *_, info = env.step(c)
    trajectory = info["trajectory"]
    scenario = env.unwrapped._scenario
    field = scenario.plant.reference_field(scenario.profile, c)[0]
    for k in (20, 57, 100, 143):
        reference = reference_trial(field, scenario.x_start, np.array([0.0, trajectory.t[k]]))
        assert np.max(np.abs(scenario.to_world(reference) - trajectory.q[k])) < 1e-9


def test_inputs_are_eqs_4_5_with_the_nominal_geometry_at_the_measured_configuration():
    env = gym.make(STEERING, config="parallel_parking", record_trajectory=True)
    env.reset(seed=0)
    model = env.unwrapped.nominal_model
    c = model.solve()
    *_, info = env.step(c)
    trajectory = info["trajectory"]
    v1, v2 = model.profile.evaluate(c, trajectory.t)
    task = env.unwrapped._scenario.to_task(trajectory.q)
    for k in (0, 33, 79, 81, 150, 160):
        u1, u2 = chained_inputs(task[k, 2], task[k, 3], v1[k], v2[k], 0.2, 0.02)
        assert np.allclose(trajectory.u[k], [u1, u2], rtol=1e-12, atol=1e-12)
    assert np.isclose(trajectory.u[0, 0], c[0] / (0.02 * np.cos(task[0, 2])))  # u1 = v1 / (rho cos theta)
    assert trajectory.u[10, 0] > 0 > trajectory.u[-10, 0]  # forward, then backward


def test_a_trial_that_leaves_the_chart_ends_where_the_car_halted():
    env = gym.make(STEERING, config="forward_parking", record_trajectory=True)
    env.reset(seed=0)
    c = env.unwrapped.nominal_model.solve()
    c[1] = env.action_space.high[1]  # steer hard: theta runs to pi/2
    *_, info = env.step(c)
    trajectory = info["trajectory"]
    assert info["left_chart"] and trajectory.left_chart
    assert trajectory.t[-1] < 5.0
    assert np.array_equal(trajectory.q[-1], info["q_final"])
    assert np.any(trajectory.q[-1] != trajectory.q[-2])  # no standstill kept after the halt


def test_cyclic_segments_record_their_own_time_and_chain_up():
    env = gym.make(CYCLIC, config="cyclic_home_goal", cycles=2, record_trajectory=True)
    obs, _ = env.reset(seed=0)
    agent = CyclicILCAgent(env.unwrapped.nominal_models, 1.0, 1.0)
    previous = None
    truncated = False
    while not truncated:
        obs, _, _, truncated, info = env.step(agent.act(obs))
        agent.learn(info)
        trajectory = info["trajectory"]
        assert trajectory.t[0] == 0.0 and np.isclose(trajectory.t[-1], 5.0)
        assert np.array_equal(trajectory.q[-1], info["q_final"])
        if previous is not None:
            assert np.allclose(trajectory.q[0], previous, atol=1e-12)  # never reset
        previous = info["q_final"]


def test_equal_relative_perturbation_of_wheelbase_and_radius_leaves_theta_and_phi_nominal():
    """The yaw rate rho u1 tan(phi) / ell keeps its nominal value when ell and rho grow by the same
    factor: only the speed along the path changes (why simulation 1's orientation error is round-off)."""
    config = load_config("forward_parking")
    nominal = dataclasses.replace(
        config, plant=dataclasses.replace(config.plant, true_wheelbase=0.2, true_wheel_radius=0.02)
    )
    c = np.array([0.2, -0.3, 0.1, 0.02])
    runs = []
    for cfg in (config, nominal):
        env = gym.make(STEERING, config=cfg, record_trajectory=True)
        env.reset(seed=0)
        runs.append(env.step(c)[-1]["trajectory"].q)
    perturbed, exact = runs
    assert np.max(np.abs(perturbed[:, 2:] - exact[:, 2:])) < 1e-12
    assert np.max(np.abs(perturbed[:, :2] - exact[:, :2])) > 0.01  # the path itself differs
