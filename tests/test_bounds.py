"""Numbers at bounds: a computed value that meets a limit is judged the same on every CPU.

The last bits of a float64 computation (a BLAS kernel, an FMA) differ from one machine to
another; a bound that a documented edge meets exactly must not decide by them (issue 64: the
fast tier was red on another x86-64 machine, ``ResidualAction(scale=9)`` clipped there only).
Each bound is tested one ulp either side of its edge.
"""

import dataclasses

import gymnasium as gym
import numpy as np
import pytest

import ilc_steering  # noqa: F401  (registers the envs)
from ilc_steering.boxes import action_box
from ilc_steering.config import load_config
from ilc_steering.core.nominal import NominalModel
from ilc_steering.core.robots.car import CAR
from ilc_steering.core.robots.process_limits import LIMIT_RTOL, ProcessLimits, check_path
from ilc_steering.envs import ResidualAction
from ilc_steering.errors import LimitError

STEERING, CYCLIC = "ilc_steering/ChainedSteering-v0", "ilc_steering/CyclicSteering-v0"
UP, DOWN = np.inf, -np.inf


def ulps(value, count):
    """``value`` moved ``count`` float64 ulps (up for a positive count)."""
    for _ in range(abs(count)):
        value = np.nextafter(value, UP if count > 0 else DOWN)
    return value


# 144 + 1.8e-12 (the other CPU's bound, whose nearest float32 lies below it), 144 - 4.5e-13 (this
# CPU's, above it), exact float32 values, and values far from 1.
BOUNDS = [144.00000000000182, 143.99999999999955, 144.0, 0.2, 2.8799999999999915, 1e-7, 3.0e11]


@pytest.mark.parametrize("bound", BOUNDS)
def test_the_action_box_holds_its_float64_bound_and_is_the_tightest_that_does(bound):
    box = action_box(np.array([bound]))
    high, low = float(box.high[0]), float(box.low[0])
    assert box.dtype == np.float32 and low == -high
    assert high >= bound  # the documented edge is inside, on every CPU
    assert float(np.nextafter(np.float32(high), np.float32(0))) < bound  # and not a float32 step more


def bounded(config, bound):
    """``config`` with every ``task.action_bound`` entry set to ``bound``."""
    loaded = load_config(config)
    task = loaded.task
    size = (task.segments[0] if hasattr(task, "segments") else task).v2_terms + 1
    return dataclasses.replace(loaded, task=dataclasses.replace(loaded.task, action_bound=(bound,) * size))


@pytest.mark.parametrize("bound", BOUNDS[:3])
@pytest.mark.parametrize("env_id, config", [(STEERING, "forward_parking"), (CYCLIC, "cyclic_home_goal")])
def test_an_action_one_ulp_either_side_of_the_documented_bound_is_not_clipped(env_id, config, bound):
    env = gym.make(env_id, config=bounded(config, bound))
    env.reset(seed=0)
    size, high = env.action_space.shape[0], float(env.action_space.high[1])
    for edge in (ulps(bound, -1), bound, ulps(bound, 1)):
        action = np.full(size, 1e-3)
        action[1] = edge
        assert env.step(action)[4]["clipped"] == (edge > high), edge  # the bound itself: never clipped
    past = np.full(size, 1e-3)
    past[1] = float(np.nextafter(env.action_space.high[1], np.float32(np.inf)))  # a float32 step past the box
    info = env.step(past)[4]
    assert info["clipped"] and info["action"][1] == env.action_space.high[1]


@pytest.mark.parametrize("env_id, config", [(STEERING, "forward_parking"), (CYCLIC, "cyclic_home_goal")])
def test_the_vector_entry_points_build_the_same_box(env_id, config):
    single = gym.make(env_id, config=config).action_space
    vector = gym.make_vec(env_id, num_envs=2, config=config, vectorization_mode="vector_entry_point")
    assert vector.single_action_space == single


@pytest.mark.parametrize("count", [-3, -1, 0, 1, 3])
def test_residual_action_s_documented_room_holds_whatever_the_last_bits_of_the_scale(monkeypatch, count):
    """``scale=9`` reaches ``c0 + 9 s``, ten times ``action_scale()``: the env's own box. The scale's
    last bits moved a few ulps either way (another CPU's BLAS) must not clip it."""
    original = NominalModel.action_scale
    monkeypatch.setattr(NominalModel, "action_scale", lambda self: ulps(original(self), count))
    env = ResidualAction(gym.make(STEERING, config="forward_parking"), scale=9.0)
    env.reset(seed=0)
    for a in (1.0, -1.0):
        assert not env.step(np.full(4, a))[4]["clipped"]


def path_at(speed, steering, rate, x_max):
    """A straight path along x at ``speed`` [m/s], reaching ``x_max``, with ``phi`` rising at
    ``rate`` [rad/s] to ``steering``, sampled every 0.1 s."""
    times = np.arange(11) * 0.1
    x = x_max - speed * (times[-1] - times)
    phi = np.minimum(rate * times, steering)
    return times, np.column_stack([x, np.zeros_like(x), np.zeros_like(x), phi])


LIMITS = ProcessLimits(workspace=(-2.0, 1.5, -1.0, 1.0), speed=0.5, steering=0.3, steering_rate=0.6)


@pytest.mark.parametrize("count", [-1, 0, 1])
def test_a_path_that_meets_a_limit_to_the_last_bit_is_within_it(count):
    times, world = path_at(LIMITS.speed, LIMITS.steering, LIMITS.steering_rate, LIMITS.workspace[1])
    world[-1, 0] = ulps(world[-1, 0], count)  # the wall
    world[:, 3] = ulps(world[:, 3], count)  # the steering angle, and so its rate
    check_path(LIMITS, CAR, times, world, "trial 1", "the robot")  # no LimitError


@pytest.mark.parametrize("key", ["workspace", "speed", "steering", "steering_rate"])
def test_a_path_past_a_limit_by_more_than_its_tolerance_is_refused(key):
    past = 1 + 1e3 * LIMIT_RTOL
    factors = {"speed": 1.0, "steering": 1.0, "steering_rate": 1.0, "workspace": 1.0, key: past}
    times, world = path_at(
        LIMITS.speed * factors["speed"],
        LIMITS.steering * factors["steering"],
        LIMITS.steering_rate * factors["steering_rate"],
        LIMITS.workspace[1] * factors["workspace"],
    )
    with pytest.raises(LimitError, match=rf"^plant\.limits\.{key}"):
        check_path(LIMITS, CAR, times, world, "trial 1", "the robot")
