"""The car's chained-form map (eqs. 4-5) and the frame rotation of section 4's closing remark."""

import numpy as np
import pytest

from ilc_steering.config import load_config
from ilc_steering.core.chained_form import chained_rhs
from ilc_steering.core.robots.car import CarModel, car_velocity, chained_inputs, frame_angle, rotate
from ilc_steering.core.robots.car_fields import closed_loop_velocity
from ilc_steering.errors import ConfigError

CAR = CarModel(wheelbase=0.2, wheel_radius=0.02)


def test_alpha_round_trip():
    rng = np.random.default_rng(1)
    q = np.column_stack(
        [rng.normal(size=50), rng.normal(size=50), rng.uniform(-1.4, 1.4, 50), rng.uniform(-1.2, 1.2, 50)]
    )
    np.testing.assert_allclose(CAR.from_chained(CAR.to_chained(q)), q, atol=1e-12)


def paper_alpha(q):
    """Section 2.1's change of coordinates, typed from the paper; works on complex q."""
    x, y, theta, phi = q
    return np.array([x, np.tan(phi) / (CAR.wheelbase * np.cos(theta) ** 3), np.tan(theta), y])


def test_beta_makes_the_nominal_car_chained():
    """d/dt alpha(q) along the car driven by beta(q) v equals eq. 1 at z = alpha(q)."""
    rng = np.random.default_rng(2)
    for _ in range(20):
        q = np.array([*rng.normal(size=2), rng.uniform(-1.2, 1.2), rng.uniform(-1.0, 1.0)])
        v1, v2 = rng.normal(size=2)
        u1, u2 = CAR.inputs(q, v1, v2)
        qdot = np.array(car_velocity(q[2], q[3], float(u1), float(u2), CAR.wheelbase, CAR.wheel_radius))
        np.testing.assert_allclose(CAR.to_chained(q), paper_alpha(q), rtol=1e-15)
        zdot = paper_alpha(q + 1e-30j * qdot).imag / 1e-30  # complex-step derivative along qdot
        np.testing.assert_allclose(zdot, chained_rhs(CAR.to_chained(q), v1, v2), rtol=1e-12, atol=1e-12)


def test_closed_loop_velocity_is_eq3_after_eqs4_5():
    """The integrator's fused field equals the composition of the two published maps."""
    rng = np.random.default_rng(3)
    nominal, true = (0.2, 0.02), (0.22, 0.022)
    for _ in range(20):
        theta, phi = rng.uniform(-1.4, 1.4, size=2)
        v1, v2 = rng.normal(size=2)
        u1, u2 = chained_inputs(theta, phi, v1, v2, *nominal)
        expected = car_velocity(theta, phi, u1, u2, *true)
        np.testing.assert_allclose(closed_loop_velocity(theta, phi, v1, v2, *nominal, *true), expected, rtol=1e-13)


def test_map_is_undefined_at_theta_pi_over_2():
    with pytest.raises(ValueError, match="theta"):
        CAR.to_chained([0.0, 0.0, np.pi / 2, 0.0])
    with pytest.raises(ValueError, match="phi"):
        CAR.to_chained([0.0, 0.0, 0.0, -np.pi / 2])
    with pytest.raises(ValueError, match="finite"):
        CAR.to_chained([np.nan, 0.0, 0.0, 0.0])


def test_frame_rotation_brings_both_orientations_into_the_chart():
    assert frame_angle(0.3, -0.2) == 0.0  # the paper's tasks keep their coordinates
    angle = frame_angle(2.0, 2.9)
    rotated = rotate(np.array([[1.0, 2.0, 2.0, 0.1], [0.0, 0.0, 2.9, 0.0]]), angle)
    assert np.all(np.abs(rotated[:, 2]) < np.pi / 2)
    back = rotate(rotated, -angle)
    np.testing.assert_allclose(back[0], [1.0, 2.0, 2.0, 0.1], atol=1e-14)


def test_a_half_turn_task_is_rejected_with_an_intermediate_configuration():
    with pytest.raises(ValueError, match="intermediate configuration with theta = 1.5708"):
        frame_angle(0.0, np.pi)
    raw = {
        "name": "u_turn",
        "plant": {
            "model": "car",
            "wheelbase": 0.2,
            "wheel_radius": 0.02,
            "true_wheelbase": 0.2,
            "true_wheel_radius": 0.02,
        },
        "task": {"start": [0, 0, 0.0, 0], "goal": [1, 1, 3.2, 0], "pieces": [5.0], "v1_fixed": [], "v2_terms": 3},
        "learning": {"nu_a": 1.0, "nu_b": 1.0, "trials": 3, "tolerance": {"cartesian": 1e-3, "orientation": 1e-3}},
    }
    with pytest.raises(ConfigError, match="task.goal: .*intermediate"):
        load_config(raw)
