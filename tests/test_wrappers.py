"""ResidualAction, the cyclic env's vector entry point, and same-step autoreset of make_vec."""

import doctest

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import data_equivalence
from gymnasium.vector import AutoresetMode
from gymnasium.wrappers import RescaleAction

import ilc_steering  # noqa: F401  (registers the envs)
from ilc_steering.agents import CyclicILCAgent
from ilc_steering.agents.base import LearnerContext
from ilc_steering.boxes import RESIDUAL_SCALE
from ilc_steering.envs import CyclicSteeringVectorEnv, ResidualAction, cyclic_vector_env, wrappers

STEERING, CYCLIC = "ilc_steering/ChainedSteering-v0", "ilc_steering/CyclicSteering-v0"


def residual(config="forward_parking", **kwargs):
    return ResidualAction(gym.make(STEERING, config=config), **kwargs)


@pytest.mark.parametrize("config", ["forward_parking", "parallel_parking", "chained_perturbed"])
def test_zero_is_the_nominal_solution_and_one_the_box_edge(config):
    env = residual(config)
    model = env.unwrapped.nominal_model
    c0, s = model.solve(), RESIDUAL_SCALE * model.action_scale()
    (d,) = env.action_space.shape
    env.reset(seed=0)
    sent = {}
    for a, expected in [(0.0, c0), (1.0, c0 + s), (-1.0, c0 - s), (3.0, c0 + s), (-7.0, c0 - s)]:
        info = env.step(np.full(d, a, dtype=np.float32))[4]
        np.testing.assert_array_equal(info["action"], expected)  # past +-1: clipped to the edge
        assert not info["clipped"]  # the residual box lies inside the env's
        sent[a] = info
    # +1 and -1 are 2s apart and straddle the nominal solution: not a no-op, not the rescaled box
    assert not np.array_equal(sent[1.0]["action"], sent[-1.0]["action"])
    half = np.linspace(1.0, -0.5, d, dtype=np.float32)
    np.testing.assert_allclose(env.step(half)[4]["action"], c0 + s * half, rtol=1e-15)


def test_the_box_is_the_comparisons_search_box_bit_for_bit():
    env = residual()
    u = env.unwrapped
    centre, half = LearnerContext(u.nominal_model, u.action_space, u.observation_space).search_box()
    np.testing.assert_array_equal(env.centre, centre)
    np.testing.assert_array_equal(env.half, half)


def test_spaces():
    env = residual()
    assert env.action_space == gym.spaces.Box(np.float32(-1), np.float32(1), (4,), np.float32)
    assert env.observation_space == env.unwrapped.observation_space
    assert env.action_space.sample() in env.action_space


def test_scale_is_in_units_of_the_action_scale():
    model = residual().unwrapped.nominal_model
    for scale in (0.05, 1.0, 9):
        env = residual(scale=scale)
        np.testing.assert_allclose(env.half, scale * model.action_scale(), rtol=1e-15)
        np.testing.assert_array_equal(env.centre, model.solve())
    env = residual(scale=9.0)
    env.reset(seed=0)
    assert not env.step(np.ones(4))[4]["clipped"]  # the documented room: up to 9 without clipping


def test_on_a_manoeuvre_the_box_is_every_segments_end_to_end():
    env = ResidualAction(gym.make("ilc_steering/SegmentedSteering-v0", config="segmented_parking"))
    views = env.unwrapped.segment_views()
    centre = np.concatenate([view.nominal_model.solve() for view in views])
    half = np.concatenate([RESIDUAL_SCALE * view.nominal_model.action_scale() for view in views])
    assert env.action_space.shape == env.unwrapped.action_space.shape == centre.shape
    np.testing.assert_allclose(env.half, half, rtol=1e-15)
    env.reset(seed=0)
    info = env.step(np.zeros(centre.size))[4]
    box = env.unwrapped.action_space
    np.testing.assert_array_equal(info["action"], np.clip(centre, np.float64(box.low), np.float64(box.high)))
    assert not info["clipped"] and info["cartesian_error"] < 0.2  # a = 0: the nominal manoeuvre
    sizes = [view.action_space.shape[0] for view in views]
    signs = np.sign(env.action(-np.ones(centre.size))[np.cumsum([0, *sizes[:-1]])])
    assert list(signs) == [1.0, -1.0]  # c11 keeps each segment's direction (forward, then reverse)


@pytest.mark.parametrize("scale", [0, -0.3, float("nan"), float("inf"), True, "0.3", None, [0.3]])
def test_bad_scale_is_refused_by_name(scale):
    with pytest.raises(ValueError, match=r"^scale must be a number in \(0, 100\]") as error:
        residual(scale=scale)
    assert "\n" not in str(error.value)


def test_what_it_cannot_wrap_is_refused_by_name():
    vector = gym.make_vec(STEERING, num_envs=2, vectorization_mode="vector_entry_point")
    with pytest.raises(ValueError, match="wraps one env from gym.make.*wrappers=\\[ResidualAction\\]"):
        ResidualAction(vector)
    with pytest.raises(ValueError, match="needs an ilc_steering env.*PendulumEnv"):
        ResidualAction(gym.make("Pendulum-v1"))
    env = residual()
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"action must have shape \(4,\) = a in \[-1, 1\]\^4, got shape \(5,\)"):
        env.step(np.zeros(5))
    with pytest.raises(ValueError, match="action must be finite"):
        env.step([0.0, np.nan, 0.0, 0.0])
    rescaled = RescaleAction(gym.make(STEERING), np.float32(-1), np.float32(1))
    with pytest.raises(ValueError, match="must wrap the env's own action box"):
        ResidualAction(rescaled)


def test_the_cyclic_env_gets_each_segments_nominal_solution():
    env = ResidualAction(gym.make(CYCLIC, config="cyclic_pickup_dropoff", cycles=2))
    models = env.unwrapped.nominal_models
    np.testing.assert_array_equal(env.centres, [m.solve() for m in models])
    np.testing.assert_array_equal(env.halves, [RESIDUAL_SCALE * m.action_scale() for m in models])
    assert len({tuple(c) for c in env.centres}) == len(models) == 3  # three different segments
    for _ in range(2):  # the second episode checks that reset goes back to the first segment
        _, info = env.reset(seed=0)
        truncated, steps = False, 0
        while not truncated:
            _, _, _, truncated, info = env.step(np.full(4, 0.5))
            m = models[info["segment"]]
            np.testing.assert_array_equal(info["action"], m.solve() + 0.5 * RESIDUAL_SCALE * m.action_scale())
            steps += 1
        assert steps == 6


def test_it_works_under_make_vec_wrappers():
    envs = gym.make_vec(
        STEERING,
        num_envs=2,
        vectorization_mode="sync",
        wrappers=[ResidualAction],
        vector_kwargs={"autoreset_mode": AutoresetMode.SAME_STEP},
    )
    envs.reset(seed=0)
    info = envs.step(np.zeros((2, 4), dtype=np.float32))[4]
    c0 = envs.call("get_wrapper_attr", "centre")[0]
    np.testing.assert_array_equal(info["final_info"]["action"], [c0, c0])


@pytest.mark.parametrize("module", [wrappers, cyclic_vector_env])
def test_docstring_examples_run(module):
    results = doctest.testmod(module, raise_on_error=False)
    assert results.attempted > 0 and results.failed == 0


# The cyclic env's vector entry point


def native(num_envs, config, **kwargs):
    return gym.make_vec(CYCLIC, num_envs=num_envs, vectorization_mode="vector_entry_point", config=config, **kwargs)


def sync(num_envs, config, **kwargs):
    return gym.make_vec(
        CYCLIC,
        num_envs=num_envs,
        vectorization_mode="sync",
        config=config,
        vector_kwargs={"autoreset_mode": AutoresetMode.SAME_STEP},
        **kwargs,
    )


def test_both_envs_have_a_vector_entry_point():
    for env_id, cls in [(STEERING, "ChainedSteeringVectorEnv"), (CYCLIC, "CyclicSteeringVectorEnv")]:
        assert gym.spec(env_id).vector_entry_point.endswith(f":{cls}")
        assert type(gym.make_vec(env_id, num_envs=2).unwrapped).__name__ == cls  # make_vec's default mode


@pytest.mark.parametrize("config", ["cyclic_home_goal", "cyclic_pickup_dropoff"])
def test_cyclic_vector_env_matches_sync_vector_env_step_by_step_bit_for_bit(config):
    a, b = native(6, config, cycles=2), sync(6, config, cycles=2)
    assert a.metadata["autoreset_mode"] == AutoresetMode.SAME_STEP
    assert a.action_space == b.action_space and a.observation_space == b.observation_space
    assert data_equivalence(a.reset(seed=3), b.reset(seed=3), exact=True)
    models = a.unwrapped.nominal_models
    r = len(models)
    rng = np.random.default_rng(0)
    clipped = left = truncated = 0
    for step in range(2 * 2 * r + 1):  # two episodes, through the same-step reset, and one step on
        spread = 0.05 if step % 3 else 20.0  # now and then far off: clipped, and some leave the chart
        c = models[step % r].solve() * (1 + spread * rng.standard_normal((6, 4)))
        out_a, out_b = a.step(c), b.step(c)
        for name, x, y in zip(["obs", "rewards", "terminations", "truncations", "info"], out_a, out_b):
            assert data_equivalence(x, y, exact=True), (step, name)
        info = out_a[4].get("final_info", out_a[4])
        clipped += info["clipped"].sum()
        left += info["left_chart"].sum()
        truncated += out_a[3].all()
        assert out_a[3].all() == ((step + 1) % (2 * r) == 0)  # cycles x segments steps an episode
    assert clipped > 0 and left > 0 and truncated == 2
    assert out_a[4]["cycle"].tolist() == [1] * 6 and out_a[4]["waypoint"].tolist() == [1] * 6


def test_cyclic_vector_env_drives_each_robot_as_its_own_scalar_env():
    """Per-robot starts, each robot with its own learner: the batch equals six scalar envs."""
    starts = np.array([[0.1 * i, -0.05 * i, 0.1 - 0.04 * i, 0.02 * i] for i in range(6)])
    envs = native(6, "cyclic_home_goal", cycles=4)
    singles = [gym.make(CYCLIC, config="cyclic_home_goal", cycles=4) for _ in range(6)]
    models = envs.unwrapped.nominal_models
    agents = [CyclicILCAgent(models, 1.0, 1.0) for _ in range(6)]
    obs, info = envs.reset(seed=0, options={"start": starts})
    outs = [env.reset(seed=0, options={"start": q}) for env, q in zip(singles, starts)]
    np.testing.assert_array_equal(obs, [o for o, _ in outs])
    np.testing.assert_array_equal(info["q"], starts)
    errors = []
    for _ in range(6):
        c = np.array([agent.act(o) for agent, o in zip(agents, obs)])
        obs, rewards, _, truncations, info = envs.step(c)
        steps = [env.step(ci) for env, ci in zip(singles, c)]
        np.testing.assert_array_equal(obs, [s[0] for s in steps])
        np.testing.assert_array_equal(rewards, [s[1] for s in steps])
        for i, (agent, s) in enumerate(zip(agents, steps)):
            for key in ("error", "q_final", "cartesian_error", "segment", "cycle"):
                np.testing.assert_array_equal(info[key][i], s[4][key])
            agent.learn(s[4])
        errors.append(info["cartesian_error"])
    assert not truncations.any()
    assert len({tuple(e) for e in errors[:2]}) == 2 and len(set(errors[0])) == 6  # six different robots
    assert np.max(errors[-1]) < 0.2 * np.max(errors[0])  # and the cyclic law converges on each


def test_cyclic_vector_env_parallel_equals_serial():
    rng = np.random.default_rng(1)
    serial = CyclicSteeringVectorEnv(5, "cyclic_home_goal", parallel=False)
    parallel = CyclicSteeringVectorEnv(5, "cyclic_home_goal", parallel=True)
    serial.reset(seed=0), parallel.reset(seed=0)
    for segment in range(2):
        c = serial.nominal_models[segment].solve() * (1 + 0.3 * rng.standard_normal((5, 4)))
        assert data_equivalence(serial.step(c), parallel.step(c), exact=True)


@pytest.mark.parametrize(
    ("kwargs", "reset", "message"),
    [
        ({"num_envs": 0}, None, r"num_envs must be an integer in \[1, 100000\]"),
        ({"cycles": 0}, None, "cycles must be a whole number >= 1"),
        ({"config": "forward_parking"}, None, "needs task.waypoints"),
        ({"render_mode": "rgb_array"}, None, "render_mode must be one of"),
        ({}, {"start": [0.0, 0.0, 0.0]}, r"options\['start'\] must have shape \(4,\)"),
        ({}, {"start": np.zeros((2, 4))}, r"options\['start'\] must have shape \(3, 4\)"),
        ({}, {"start": [[0, 0, 0, 0], [0, 0, 2.0, 0], [0, 0, 0, 0]]}, r"options\['start'\]\[1\]: "),
        ({}, {"begin": [0, 0, 0, 0]}, "unknown key 'begin'"),
    ],
)
def test_cyclic_vector_env_refuses_bad_input_by_name(kwargs, reset, message):
    with pytest.raises(ValueError, match=message) as error:
        envs = CyclicSteeringVectorEnv(**{"num_envs": 3, "config": "cyclic_home_goal", **kwargs})
        envs.reset(seed=0, options=reset)
    assert "\n" not in str(error.value)


def test_cyclic_vector_env_refuses_a_wrong_action_shape():
    envs = native(3, "cyclic_home_goal")
    envs.reset(seed=0)
    with pytest.raises(ValueError, match=r"actions must have shape \(3, 4\)"):
        envs.step(np.zeros(4))


# Same-step autoreset of make_vec's sync and async modes


@pytest.mark.parametrize("mode", ["sync", "async"])
def test_same_step_autoreset_makes_every_step_a_trial(mode):
    def make(**kwargs):
        return gym.make_vec(STEERING, num_envs=2, vectorization_mode=mode, config="forward_parking", **kwargs)

    c = np.tile(gym.make(STEERING, config="forward_parking").unwrapped.nominal_model.solve(), (2, 1))
    default = make()  # Gymnasium's default, next-step autoreset: every other step only resets
    default.reset(seed=0)
    rewards = [default.step(c)[1] for _ in range(4)]
    default.close()
    assert [bool(np.all(r == 0)) for r in rewards] == [False, True, False, True]
    envs = make(vector_kwargs={"autoreset_mode": gym.vector.AutoresetMode.SAME_STEP})
    envs.reset(seed=0)
    for _ in range(4):
        _, rewards, terminations, _, info = envs.step(c)
        assert terminations.all()
        np.testing.assert_allclose(info["final_info"]["true_cartesian_error"], 0.1, rtol=1e-9)  # a real trial
        np.testing.assert_array_equal(
            rewards, -(info["final_info"]["cartesian_error"] + 1.0 * info["final_info"]["orientation_error"])
        )
    envs.close()


def test_cyclic_vector_env_noise_is_seeded_and_leaves_the_truth_alone():
    noisy = [native(3, "cyclic_home_goal", measurement_noise=1e-3) for _ in range(2)]
    exact = native(3, "cyclic_home_goal")
    c = np.tile(exact.unwrapped.nominal_models[0].solve(), (3, 1))
    outs = []
    for envs in [*noisy, exact]:
        envs.reset(seed=5)
        outs.append(envs.step(c))
    assert data_equivalence(outs[0], outs[1], exact=True)  # the same seed, the same draws
    info, truth = outs[0][4], outs[2][4]
    np.testing.assert_array_equal(info["true_cartesian_error"], truth["cartesian_error"])
    measured = info["cartesian_error"] - truth["cartesian_error"]
    assert np.all(measured != 0) and np.all(np.abs(measured) < 1e-2)  # measured with mm-sized errors
    assert not np.array_equal(outs[0][0], outs[2][0])  # the observation is the noisy measurement
