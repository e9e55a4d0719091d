"""Section 5's trapezoidal v1: V and W in closed form against quadrature, the kernel against them,
and the learning law's contraction by exactly 1 - nu_b (eq. 36) with it."""

from itertools import pairwise
from math import factorial

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from ilc_steering.agents.ilc import ILCAgent
from ilc_steering.core.nominal import NominalModel
from ilc_steering.core.profiles import InputProfile
from ilc_steering.core.robots.chained import ChainedPlant
from ilc_steering.core.simulate import simulate
from ilc_steering.core.trapezoid import TrapezoidProfile
from ilc_steering.errors import ParameterError

PROFILES = [
    TrapezoidProfile((12.0,), (), 3, 1.0),  # experiment 1's shape
    TrapezoidProfile((5.0, 5.0), (-0.12,), 3, 0.8),  # experiment 2's: forward, then backward
    TrapezoidProfile((2.0, 1.5, 3.0), (0.7, -0.4), 5, 0.3),
]


def linear_reference(profile, c, n, z0b):
    """z_b(T) of dz_b/dt = v1(t) N z_b + e1 v2(t) by DOP853 at rtol 1e-12, restarted at every span."""

    def field(t, z):
        v1, v2 = profile.evaluate(c, np.array(t))
        dz = np.zeros_like(z)
        dz[0] = v2
        dz[1:] = float(v1) * z[:-1]
        return dz

    z = np.array(z0b, dtype=float)
    for t0, t1 in zip(profile.breakpoints[:-1], profile.breakpoints[1:]):
        z = solve_ivp(field, (t0, t1), z, method="DOP853", rtol=1e-12, atol=1e-12).y[:, -1]
    return z


@pytest.mark.parametrize("profile", PROFILES, ids=["one", "two", "three"])
@pytest.mark.parametrize("n", [3, 4, 6])
@pytest.mark.slow  # scipy quadrature
def test_V_and_W_against_quadrature(profile, n):
    assert isinstance(profile, InputProfile)
    rng = np.random.default_rng(n)
    c = np.concatenate([[0.3], rng.normal(size=profile.v2_terms) * 0.2])
    V, W = profile.transition(c[0], n)
    z0b = rng.normal(size=n - 1)
    np.testing.assert_allclose(V @ z0b + W @ c[1:], linear_reference(profile, c, n, z0b), atol=1e-9)
    # and every column of W on its own (z0b = 0, c2 = e_j)
    for j in range(profile.v2_terms):
        e = np.zeros_like(c)
        e[0], e[1 + j] = c[0], 1.0
        np.testing.assert_allclose(W[:, j], linear_reference(profile, e, n, np.zeros(n - 1)), atol=1e-9)


@pytest.mark.parametrize("profile", PROFILES, ids=["one", "two", "three"])
def test_v1_is_continuous_and_its_area_is_eq_12s(profile):
    c = np.concatenate([[0.25], np.zeros(profile.v2_terms)])
    t = np.linspace(0, profile.breakpoints[-1], 200001)
    v1, _ = profile.evaluate(c, t)
    assert v1[0] == 0.0 and abs(v1[-1]) < 1e-12
    assert np.max(np.abs(np.diff(v1))) < 1e-3  # no jump anywhere: ramps at both ends of each piece
    area = np.trapezoid(v1, t)
    assert area == pytest.approx(profile.learned_area * c[0] + profile.fixed_displacement, abs=1e-8)


@pytest.mark.parametrize("profile", PROFILES, ids=["one", "two", "three"])
def test_the_kernel_agrees_with_V_and_W(profile):
    n = 5
    plant = ChainedPlant(n)
    rng = np.random.default_rng(1)
    c = np.concatenate([[0.4], rng.normal(size=profile.v2_terms) * 0.1])[None]
    z0 = rng.normal(size=n) * 0.1
    final = simulate(plant, profile, z0[None], c).final[0]
    V, W = profile.transition(c[0, 0], n)
    assert final[0] == pytest.approx(z0[0] + profile.learned_area * c[0, 0] + profile.fixed_displacement, abs=1e-12)
    np.testing.assert_allclose(final[1:], V @ z0[1:] + W @ c[0, 1:], atol=1e-9)


@pytest.mark.parametrize("nu_b", [0.5, 1.0, 1.5])
def test_eq_36_the_error_contracts_by_exactly_one_minus_nu_b(nu_b):
    profile = TrapezoidProfile((5.0, 5.0), (-0.12,), 4, 0.8)
    n = 5
    model = NominalModel(n, profile, np.zeros(n), np.array([0.3, 0.0, 0.1, -0.05, 0.02]))
    agent = ILCAgent(model, nu_a=1.0, nu_b=nu_b, start=model.solve() * 0.8)
    plant = ChainedPlant(n)
    errors = []
    for _ in range(5):
        c = agent.act()
        final = simulate(plant, profile, model.z_start[None], c[None]).final[0]
        error = model.z_goal - final
        errors.append(error[1:])
        agent.learn({"action": c, "error": error})
    for before, after in pairwise(errors[1:]):  # z1 is exact after the first update
        np.testing.assert_allclose(after, (1 - nu_b) * before, atol=1e-9)


def test_a_ramp_too_long_for_its_pieces_is_refused():
    with pytest.raises(ParameterError, match="ramp: must be > 0 s and less than half the shortest piece"):
        TrapezoidProfile((5.0, 1.0), (0.1,), 3, 0.5)


def trapezoid_config(**task):
    """Experiment 1's task (section 5: T = 12 s, (0, 0, 0, 0) to (1.8, 0.8, 0, 0)) on a 10 %-perturbed
    car with trapezoidal v1 (the MARIO plant itself is not built yet)."""
    from ilc_steering.config import load_config

    data = {
        "name": "trapezoid_forward",
        "plant": {
            "model": "car",
            "wheelbase": 0.24,
            "wheel_radius": 0.0365,
            "true_wheelbase": 0.264,
            "true_wheel_radius": 0.0402,
        },
        "task": {
            "start": [0.0, 0.0, 0.0, 0.0],
            "goal": [1.8, 0.8, 0.0, 0.0],
            "pieces": [12.0],
            "v1_fixed": [],
            "v2_terms": 3,
            "v1_shape": "trapezoid",
            "ramp": 1.0,
            **task,
        },
        "learning": {"nu_a": 1.0, "nu_b": 1.0, "trials": 8, "tolerance": {"cartesian": 5e-4, "orientation": 5e-4}},
    }
    return load_config(data)


def test_a_car_with_trapezoidal_v1_within_1e9_of_solve_ivp_and_ilc_converges():
    import gymnasium as gym

    import ilc_steering  # noqa: F401  (registers the envs)
    from ilc_steering.core.reference import trial as car_trial
    from ilc_steering.core.score import within_tolerance
    from ilc_steering.envs.scenario import Scenario
    from ilc_steering.loop import run_trials

    config = trapezoid_config()
    scenario = Scenario.from_config(config)
    assert isinstance(scenario.profile, TrapezoidProfile)
    c = scenario.nominal.solve()
    np.testing.assert_allclose(
        scenario.run(c[None]).final[0], car_trial(scenario.plant, scenario.profile, scenario.x_start, c), atol=1e-9
    )
    env = gym.make("ilc_steering/ChainedSteering-v0", config=config)
    rollout = run_trials(env, ILCAgent(env.unwrapped.nominal_model), 8)
    hits = [k for k, info in enumerate(rollout.infos, 1) if within_tolerance(config.learning.tolerance, info)]
    assert hits and hits[0] <= 6
    u1 = env.unwrapped.nominal_model  # the wheel speed starts and ends at rest: v1 is 0 at both ends
    v1, _ = u1.profile.evaluate(rollout.infos[-1]["action"], np.array([0.0, 12.0]))
    np.testing.assert_allclose(v1, 0.0, atol=1e-12)


@pytest.mark.parametrize(
    "task, message",
    [
        ({"ramp": None}, r"task\.ramp: v1_shape: trapezoid needs the ramp"),
        ({"ramp": 7.0}, r"task\.ramp: must be > 0 s and less than half the shortest piece"),
        ({"v1_shape": "constant"}, r"task\.ramp: is for v1_shape: trapezoid"),
        ({"v1_shape": "sine"}, r"task\.v1_shape: must be one of \['constant', 'trapezoid'\]"),
    ],
)
def test_bad_trapezoid_keys_name_the_key(task, message):
    from ilc_steering.errors import ConfigError

    with pytest.raises(ConfigError, match=message):
        trapezoid_config(**task)


@pytest.mark.slow  # scipy quadrature
def test_V_and_W_match_scipy_quad_to_1e12():
    profile = PROFILES[1]  # experiment 2's shape: two trapezoids, forward then backward
    from scipy.integrate import quad
    from scipy.linalg import expm

    n = 4
    c11 = 0.3
    c = np.concatenate([[c11], np.zeros(profile.v2_terms)])
    V, W = profile.transition(c11, n)
    T = profile.breakpoints[-1]

    def S(t):  # int_0^t v1, by quad
        return quad(lambda s: float(profile.evaluate(c, np.array(s))[0]), 0.0, t, points=profile.breakpoints[1:-1])[0]

    total = S(T)
    shift = np.diag(np.ones(n - 2), -1)
    np.testing.assert_allclose(V, expm(shift * total), atol=1e-12)
    for j in range(profile.v2_terms):
        e = np.zeros_like(c)
        e[1 + j] = 1.0
        for k in range(n - 1):
            value = quad(
                lambda s, k=k, e=e: (total - S(s)) ** k / factorial(k) * float(profile.evaluate(e, np.array(s))[1]),
                0.0,
                T,
                points=profile.breakpoints[1:-1],
                epsabs=1e-14,
                epsrel=1e-13,
                limit=200,
            )[0]
            assert W[k, j] == pytest.approx(value, abs=1e-12), (k, j)
