"""The robot's side (issue 68): each robot's function from chained inputs to its own inputs is its
model's ``inputs``, bit for bit, and does what defines it: driven by what it returns, the robot's
chained coordinates move by eq. 1, with the derivative taken by a central difference of the
library's map (``to_chained``), which no formula of the functions is reused in."""

import dataclasses

import numpy as np
import pytest

from ilc_steering.core.robots import car_inputs, trailer_inputs, unicycle_inputs
from ilc_steering.core.robots.car_model import CarModel, car_velocity, chained_inputs
from ilc_steering.core.robots.car_trailer import TrailerModel, trailer_velocity
from ilc_steering.core.robots.unicycle import UnicycleModel, unicycle_velocity

CAR = CarModel(0.2, 0.02)
UNICYCLE = UnicycleModel(0.03, 0.3)
TRAILER = TrailerModel(0.2, 0.02, 0.3)


def car_side(model, q, v1, v2):
    return car_inputs(q[..., 2], q[..., 3], v1, v2, model.wheelbase, model.wheel_radius)


def unicycle_side(model, q, v1, v2):
    return unicycle_inputs(q[..., 2], v1, v2)


def trailer_side(model, q, v1, v2):
    return trailer_inputs(q[..., 2], q[..., 3], q[..., 4], v1, v2, *dataclasses.astuple(model))


def car_motion(model, q, u1, u2):
    return np.array(car_velocity(q[2], q[3], u1, u2, model.wheelbase, model.wheel_radius))


def unicycle_motion(model, q, v, omega):
    return np.array(unicycle_velocity(q[2], v, omega))


def trailer_motion(model, q, u1, u2):
    return np.array(trailer_velocity(q[2], q[3], q[4], u1, u2, *dataclasses.astuple(model)))


ROBOTS = {  # name: (model, its side, its kinematics, the size of q)
    "car": (CAR, car_side, car_motion, 4),
    "unicycle": (UNICYCLE, unicycle_side, unicycle_motion, 3),
    "car_trailer": (TRAILER, trailer_side, trailer_motion, 5),
}


def configurations(rng, size, count, span=1.2):
    """Random configurations inside the chart: every angle within ``span`` [rad] of 0."""
    q = rng.normal(size=(count, size))
    q[:, 2:] = rng.uniform(-span, span, size=(count, size - 2))
    return q


def test_the_public_place_reexports_each_robots_own_function():
    from ilc_steering.core.robots import car_trailer, unicycle

    assert car_inputs is chained_inputs
    assert unicycle_inputs is unicycle.unicycle_inputs
    assert trailer_inputs is car_trailer.trailer_inputs


@pytest.mark.parametrize("name", sorted(ROBOTS))
def test_the_function_is_the_models_inputs_bit_for_bit(name):
    """On a batch (arrays of any shape) and on one configuration with Python floats."""
    model, side, _, size = ROBOTS[name]
    rng = np.random.default_rng(11)
    q = configurations(rng, size, 600).reshape(20, 30, size)
    v1, v2 = rng.normal(size=(2, 20, 30))
    for got, expected in zip(side(model, q, v1, v2), model.inputs(q, v1, v2)):
        assert np.asarray(got).shape == (20, 30)
        assert np.array_equal(got, expected)
    one, a, b = q[3, 4], float(v1[3, 4]), float(v2[3, 4])
    for got, expected in zip(side(model, one, a, b), model.inputs(one, a, b)):
        assert float(got) == float(expected)


def chained_field(z, v1, v2):
    """Eq. 1: ``dz1/dt = v1``, ``dz2/dt = v2``, ``dz_i/dt = z_{i-1} v1``."""
    return np.array([v1, v2, *(z[1:-1] * v1)])


def worst_miss(model, side, motion, q_all, v_all, factor=1.0):
    """The largest relative gap between ``d/dt to_chained(q)`` (a five-point central difference
    along the robot's motion under the inputs ``side`` returns, times ``factor``) and eq. 1's field."""
    h, worst = 1e-3, 0.0
    for q, (v1, v2) in zip(q_all, v_all):
        inputs = [factor * float(u) for u in side(model, q, v1, v2)]
        qdot = motion(model, q, *inputs)
        speed = float(np.linalg.norm(qdot))  # steps of h along the unit direction, then scaled
        z = [model.to_chained(q + k * h * qdot / speed) for k in (-2, -1, 1, 2)]
        zdot = speed * (z[0] - 8 * z[1] + 8 * z[2] - z[3]) / (12 * h)  # O(h^4)
        expected = chained_field(model.to_chained(q), v1, v2)
        worst = max(worst, float(np.max(np.abs(zdot - expected) / np.maximum(1.0, np.abs(expected)))))
    return worst


@pytest.mark.parametrize("name", sorted(ROBOTS))
def test_the_inputs_move_the_chained_coordinates_by_eq_1(name):
    """Along random configurations (every angle within 1 rad of 0), the robot driven by the
    function's inputs moves ``z = alpha(q)`` as the chained form says, to the difference's error
    (at most 6e-7 here, the trailer's); the same inputs 10 % too large (a wheel 10 % smaller than
    assumed) miss by more than 1e-2: the check can fail."""
    model, side, motion, size = ROBOTS[name]
    rng = np.random.default_rng(5)
    q_all = configurations(rng, size, 100, span=1.0)
    v_all = rng.normal(size=(100, 2))
    assert worst_miss(model, side, motion, q_all, v_all) < 1e-5
    assert worst_miss(model, side, motion, q_all, v_all, factor=1.1) > 1e-2
