"""The compiled integrator against tight scipy references and the chained form's closed form."""

import gymnasium as gym
import numpy as np
import pytest
from scipy.integrate import solve_ivp

import ilc_steering  # noqa: F401  (registers the envs)
from ilc_steering.agents import ILCAgent
from ilc_steering.config import load_config
from ilc_steering.core import dop853
from ilc_steering.core import stepper as kernel
from ilc_steering.core.integrate import LEFT_CHART, OK, integrate
from ilc_steering.core.profiles import PiecewiseProfile
from ilc_steering.core.reference import reference_trial
from ilc_steering.core.robots.car_fields import ANGLE_KERNEL
from ilc_steering.core.robots.chained import ChainedPlant
from ilc_steering.core.simulate import simulate
from ilc_steering.envs.scenario import Scenario
from ilc_steering.loop import run_trials


def paper_car(q, v1, v2, nominal, true, limit):
    """Eq. 3 driven through eqs. 4-5, typed from the paper; the wheel angle is the clipped command."""
    theta, phi = q[2], np.clip(q[3], -limit, limit)
    ell, rho = nominal
    u1 = v1 / (rho * np.cos(theta))
    u2 = (
        -3 / ell * np.sin(theta) / np.cos(theta) ** 2 * np.sin(phi) ** 2 * v1
        + ell * np.cos(theta) ** 3 * np.cos(phi) ** 2 * v2
    )
    ell_t, rho_t = true
    return np.array([np.cos(theta) * rho_t * u1, np.sin(theta) * rho_t * u1, np.tan(phi) / ell_t * rho_t * u1, u2])


def reference(scenario, c):
    """DOP853 at rtol = atol = 1e-12 on the paper-typed field, restarted at every limit crossing."""
    plant = scenario.plant
    limit = np.inf if plant.steering_limit is None else plant.steering_limit
    nominal = (plant.nominal.wheelbase, plant.nominal.wheel_radius)
    true = (plant.true.wheelbase, plant.true.wheel_radius)

    def field(t, q):
        v1, v2 = scenario.profile.evaluate(c, np.array(t))
        return paper_car(q, float(v1), float(v2), nominal, true, limit)

    return reference_trial(field, scenario.x_start, scenario.profile.breakpoints, limit)


def ilc_actions(name, count):
    env = gym.make("ilc_steering/ChainedSteering-v0", config=name)
    rollout = run_trials(env, ILCAgent(env.unwrapped.nominal_model), count)
    return Scenario.from_config(load_config(name)), [info["action"] for info in rollout.infos]


def test_tableau_is_consistent():
    assert kernel._A.shape == (kernel.STAGES, kernel.STAGES)
    np.testing.assert_allclose(kernel._A.sum(axis=1), kernel._C, atol=1e-14)
    assert kernel._B.sum() == pytest.approx(1.0, abs=1e-14)
    assert np.all(np.triu(kernel._A) == 0)  # explicit


def test_tableau_has_order_8():
    """The quadrature conditions b . c**(k-1) = 1/k up to k = 8, and the measured order on a
    nonlinear system: halving the step divides the error by about 2**8."""
    A, b, c = dop853.A, dop853.B, dop853.C
    for k in range(1, 9):
        assert b @ c ** (k - 1) == pytest.approx(1 / k, abs=1e-13), k
    assert b @ (A @ c**6) == pytest.approx(1 / 56, abs=1e-13)  # a tall-tree condition of order 8

    def rk(f, y, t1, steps):
        h = t1 / steps
        for _ in range(steps):
            k = np.zeros((len(b), y.size))
            for s in range(len(b)):
                k[s] = f(y + h * (A[s, :s] @ k[:s]))
            y = y + h * (b @ k)
        return y

    def pendulum(y):
        return np.array([y[1], -np.sin(y[0])])

    y0 = np.array([2.0, 0.0])
    exact = solve_ivp(lambda t, y: pendulum(y), (0, 4.0), y0, method="DOP853", rtol=3e-14, atol=1e-14).y[:, -1]
    errors = [np.abs(rk(pendulum, y0, 4.0, steps) - exact).max() for steps in (8, 16)]
    assert np.log2(errors[0] / errors[1]) > 7.5


def test_tableau_equals_scipys_where_it_has_one():
    coefficients = pytest.importorskip("scipy.integrate._ivp.dop853_coefficients")
    stages = coefficients.N_STAGES
    np.testing.assert_array_equal(dop853.A, coefficients.A[:stages, :stages])
    np.testing.assert_array_equal(dop853.B, coefficients.B)
    np.testing.assert_array_equal(dop853.C, coefficients.C[:stages])


@pytest.mark.parametrize("name", ["forward_parking", "parallel_parking"])
def test_car_final_state_within_1e9_of_dop853(name):
    scenario, actions = ilc_actions(name, 3)
    for c in [*actions, scenario.nominal.solve()]:
        final = scenario.run(c[None]).final[0]
        np.testing.assert_allclose(final, reference(scenario, c), rtol=0, atol=1e-9)


def test_car_with_the_steering_limit_engaged_within_1e6_of_an_event_reference():
    scenario, actions = ilc_actions("forward_parking_saturated", 4)
    limit = scenario.plant.steering_limit
    for c in actions:
        trial = scenario.run(c[None], record=True)
        assert np.any(np.abs(trial.states[0, :, 3]) > limit), "the limit must be engaged in this test"
        np.testing.assert_allclose(trial.final[0], reference(scenario, c), rtol=0, atol=1e-6)


def test_steering_limit_clips_the_wheel_angle():
    scenario, actions = ilc_actions("forward_parking_saturated", 1)
    trial = scenario.run(actions[0][None], record=True)
    q = scenario.plant.configuration(trial.states[0])
    assert np.max(np.abs(q[:, 3])) == pytest.approx(scenario.plant.steering_limit, abs=1e-15)


def test_chained_plant_with_gains_matches_the_closed_form():
    """z(T) = V(g1 v1) z0 + W(g1 v1) g2 c2 for the chained plant with true gains g1, g2."""
    rng = np.random.default_rng(5)
    n, g1, g2 = 5, 1.1, 0.9
    profile = PiecewiseProfile((1.0, 2.0, 1.5), (0.7, -0.4), n - 1)
    c = rng.normal(size=(3, n))
    z0 = rng.normal(size=(3, n))
    trials = simulate(ChainedPlant(n, g1, g2), profile, z0, c)
    assert np.all(trials.status == OK)
    scaled = PiecewiseProfile(profile.durations, tuple(g1 * v for v in profile.v1_fixed), n - 1)
    for b in range(3):
        V, W = scaled.transition(g1 * c[b, 0], n)
        np.testing.assert_allclose(trials.final[b, 1:], V @ z0[b, 1:] + W @ (g2 * c[b, 1:]), atol=1e-10)
        assert trials.final[b, 0] == pytest.approx(
            z0[b, 0] + g1 * profile.v1_pieces(c[b, 0]) @ profile.durations, abs=1e-12
        )


def test_nominal_car_is_exactly_the_chained_form():
    config = load_config("parallel_parking")
    plant = {**config.plant.__dict__, "true_wheelbase": 0.2, "true_wheel_radius": 0.02}
    scenario = Scenario.from_config(
        type(config)(config.name, type(config.plant)(**plant), config.task, config.learning)
    )
    c = scenario.nominal.solve() * np.array([1.0, 0.9, 1.1, 1.05])
    z_final = scenario.to_chained(scenario.run(c[None]).final[0])
    np.testing.assert_allclose(z_final, scenario.nominal.final_state(c), atol=1e-9)


def test_batch_equals_single_trials_and_parallel_equals_serial():
    scenario, actions = ilc_actions("forward_parking_saturated", 3)
    c = np.array(actions)
    batch = scenario.run(c).final
    for b in range(3):
        np.testing.assert_array_equal(batch[b], scenario.run(c[b][None]).final[0])
    np.testing.assert_array_equal(scenario.run(c, parallel=True).final, batch)


def test_a_trial_that_leaves_the_chart_stops_with_a_finite_state():
    scenario = Scenario.from_config(load_config("forward_parking"))
    c = scenario.nominal.solve() * np.array([1.0, 300.0, 300.0, 300.0])
    trial = scenario.run(c[None], record=True)
    assert trial.status[0] == LEFT_CHART
    assert np.all(np.isfinite(trial.final))
    assert abs(trial.final[0, 2]) < np.pi / 2 - kernel.CHART_MARGIN
    np.testing.assert_array_equal(trial.states[0, -1], trial.final[0])
    assert trial.times.shape == (trial.states.shape[1],) and trial.times[-1] == pytest.approx(5.0)


SERVOS = [
    {"steering_offset": 0.02},
    {"steering_offset": -0.03, "steering_limit": None},
    {"steering_lag": 0.05},
    {"speed_lag": 0.1},
    {"steering_offset": 0.02, "steering_lag": 0.05, "speed_lag": 0.1},
]


@pytest.mark.parametrize("name", ["forward_parking", "forward_parking_saturated"])
@pytest.mark.parametrize("servo", SERVOS, ids=lambda s: "+".join(s))
@pytest.mark.slow  # tight solve_ivp references, and the lab kernel's compilation
def test_the_servo_perturbations_within_1e9_of_a_tight_solve_ivp(name, servo):
    import dataclasses

    from ilc_steering.core.reference import trial as car_trial

    config = load_config(name)
    config = dataclasses.replace(config, plant=dataclasses.replace(config.plant, **servo))
    scenario = Scenario.from_config(config)
    assert scenario.plant.state_dim == 12  # the lab robot's kernel, its play and encoders off
    c = scenario.nominal.solve()
    trial = scenario.run(c[None])
    assert trial.status[0] == OK
    reference = car_trial(scenario.plant, scenario.profile, scenario.x_start, c)
    np.testing.assert_allclose(trial.final[0], reference, atol=1e-9)
    # each perturbation moves the final configuration by centimetres: it is not a no-op
    plain = Scenario.from_config(load_config(name)).run(c[None]).final[0]
    assert np.abs(scenario.plant.configuration(trial.final[0])[:2] - plain[:2]).max() > 1e-3


def test_a_lagging_drive_starts_from_rest_and_a_lagging_wheel_trails_the_command():
    import dataclasses

    config = load_config("forward_parking")
    config = dataclasses.replace(config, plant=dataclasses.replace(config.plant, steering_lag=0.2, speed_lag=0.2))
    scenario = Scenario.from_config(config)
    trial = scenario.run(scenario.nominal.solve()[None], record=True)
    states = trial.states[0]
    assert states[0, 5] == 0.0 and states[1, 5] > 0.0  # omega rises from rest
    t = trial.times
    u1 = scenario.nominal.profile.evaluate(scenario.nominal.solve(), t)[0] / (0.02 * np.cos(states[:, 2]))
    gap = np.abs(states[:, 5] - u1) / np.abs(u1)
    # far behind u1 at first, then within the lag of a ramping command after 5 time constants
    assert gap[1] > 0.5 and gap[np.searchsorted(t, 1.0)] < 0.1
    assert np.abs(states[:, 4] - states[:, 3]).max() > 1e-3  # phi_w trails phi_c


# The batched car kernel (core/tangent.py): the same ODE in (x, y, tan theta, sigma) coordinates.


def perturbed(scenario, count, seed=0, scale=0.1):
    c = scenario.nominal.solve()
    return c * (1.0 + scale * np.random.default_rng(seed).standard_normal((count, c.size)))


def angle_kernel(scenario, c):
    from ilc_steering.core.grid import steps_per_span

    profile = scenario.profile
    spans = np.asarray(profile.spans, dtype=np.float64)
    v1, v2 = profile.polynomials(c)
    _, params = scenario.plant.kernel()
    x0 = np.broadcast_to(scenario.x_start, (c.shape[0], scenario.x_start.size))
    steps = steps_per_span(spans, scenario.max_step)
    return integrate(ANGLE_KERNEL, params, x0, spans, steps, v1, v2)


@pytest.mark.parametrize(
    "name", ["forward_parking", "forward_parking_saturated", "parallel_parking", "cyclic_home_goal"]
)
@pytest.mark.slow  # thousands of tight solve_ivp trials
def test_the_batched_kernel_agrees_with_the_angle_kernel_and_a_tight_reference(name):
    """On the learner's trials both kernels are within 1e-9 of the reference (the tests above); on
    trials with every coefficient 10 % off, some of which turn the car to 85 degrees, where
    ``tan(theta)`` is stiff, within 1e-8 (the angle kernel: 2e-9; benchmarks/throughput.py)."""
    scenario = Scenario.from_config(load_config(name))
    c = perturbed(scenario, 40)  # more than two blocks of lanes, the last one partial
    trials = scenario.run(c)
    final, status, _ = angle_kernel(scenario, c)
    np.testing.assert_array_equal(trials.status, status)
    np.testing.assert_allclose(trials.final, final, rtol=0, atol=1e-8)
    for b in range(3):
        np.testing.assert_allclose(trials.final[b], reference(scenario, c[b]), rtol=0, atol=1e-8)


def test_the_batched_kernel_lanes_do_not_interact():
    """A trial's result is the same bit for bit alone, in a block with others, and on all cores."""
    scenario = Scenario.from_config(load_config("forward_parking_saturated"))
    c = perturbed(scenario, 37, seed=3)
    batch = scenario.run(c).final
    np.testing.assert_array_equal(scenario.run(c, parallel=True).final, batch)
    for b in (0, 15, 16, 36):
        np.testing.assert_array_equal(scenario.run(c[b][None]).final[0], batch[b])
    recorded = scenario.run(c[:20], record=True)
    np.testing.assert_array_equal(recorded.final, batch[:20])
    np.testing.assert_array_equal(recorded.states[:, -1], batch[:20])


@pytest.mark.parametrize("name", ["forward_parking_saturated", "unicycle_parking", "trailer_bay", "parallel_parking"])
@pytest.mark.slow
def test_a_batch_of_different_plants_equals_each_plant_alone(name):
    """One kernel call with a plant per trial (each its own true parameters) gives what each plant
    gives on its own: the robustness sweep's grid is one call."""
    scenario = Scenario.from_config(load_config(name))
    factors = np.exp(0.2 * np.random.default_rng(1).standard_normal((20, 2)))
    plants = [scenario.plant.with_true_factors(f) for f in factors]
    c = np.tile(scenario.nominal.solve(), (20, 1))
    together = scenario.run(c, plant=plants)
    for b in (0, 7, 19):
        alone = scenario.run(c[b][None], plant=plants[b])
        np.testing.assert_array_equal(together.final[b], alone.final[0])
    assert np.ptp(together.final[:, 0]) > 1e-3  # the plants differ


def test_a_batch_of_plants_must_be_one_per_trial_of_one_kind():
    scenario = Scenario.from_config(load_config("forward_parking"))
    c = np.tile(scenario.nominal.solve(), (3, 1))
    with pytest.raises(ValueError, match="one per trial"):
        scenario.run(c, plant=[scenario.plant] * 2)
    with pytest.raises(ValueError, match="one kind"):
        scenario.run(c, plant=[scenario.plant, scenario.plant, ChainedPlant(4)])


def test_a_simulator_s_compilation_is_announced_once_per_process(tmp_path, capsys, monkeypatch):
    """Two entry points of one simulator (its serial and its batched runners) compiling in one process
    say so once, not once each; another simulator says so too."""
    from ilc_steering.core import stepper

    monkeypatch.setattr(stepper, "_READY", set())
    monkeypatch.setattr(stepper, "_ANNOUNCED", set())
    source = tmp_path / "robot_kernel.py"  # no numba cache beside it
    source.write_text("def f(): pass\n")
    code = compile(source.read_text(), str(source), "exec")

    class EntryPoint:  # what announce_compile reads of a numba dispatcher
        def __init__(self):
            namespace = {}
            exec(code, namespace)
            self.py_func, self.overloads = namespace["f"], {}

    def entry_point(_):
        return EntryPoint()

    for function, name in ((entry_point(1), "car"), (entry_point(2), "car"), (entry_point(3), "unicycle")):
        stepper.announce_compile(function, name)
    lines = capsys.readouterr().err.splitlines()
    assert [line.split(" simulator")[0] for line in lines] == [
        "ilc-steering: compiling the car",
        "ilc-steering: compiling the unicycle",
    ]
