"""The unicycle and the car towing a trailer (issue 17): their chained forms against complex-step
derivatives, the compiled kernel against solve_ivp, the nominal plant against eq. 23, learning
under a 10 % perturbation, and the configurations outside the chart refused by name."""

import dataclasses

import gymnasium as gym
import numpy as np
import pytest
from scipy.integrate import solve_ivp

import ilc_steering  # noqa: F401  (registers the envs)
from ilc_steering.agents import ILCAgent
from ilc_steering.config import load_config
from ilc_steering.core.family import ModelFamily
from ilc_steering.core.integrate import LEFT_CHART, OK
from ilc_steering.core.reference import trial
from ilc_steering.core.robots.car_trailer import TrailerModel, TrailerPlant, _to_chained, trailer_velocity
from ilc_steering.core.robots.unicycle import UnicycleModel, UnicyclePlant, unicycle_velocity
from ilc_steering.core.simulate import simulate
from ilc_steering.envs.scenario import Scenario
from ilc_steering.errors import ConfigError
from ilc_steering.loop import run_trials
from ilc_steering.runner import run_ilc

TRAILER = TrailerModel(0.2, 0.02, 0.3)
UNICYCLE = UnicycleModel(0.03, 0.3)


def random_configurations(rng, size, count, span=1.3):
    q = rng.normal(size=(count, size))
    q[:, 2:] = rng.uniform(-span, span, size=(count, size - 2))
    return q


def chained_field(z, v1, v2):
    return np.array([v1, v2, *(z[1:-1] * v1)])


def complex_step_jacobian(f, q, h=1e-30):
    """``df/dq`` to rounding: ``Im f(q + i h e_k) / h`` needs no difference of nearby values."""
    return np.array([np.imag(f(q + 1j * h * np.eye(q.size)[k])) / h for k in range(q.size)]).T


@pytest.mark.parametrize("robot", ["unicycle", "car_trailer"])
def test_the_transformed_field_is_the_chained_form_to_1e_12(robot):
    """``J_alpha(q) f(q, beta(q) v)`` is eq. 1's field, with ``J_alpha`` by complex-step derivatives of
    the map as written: the derivation of ``beta`` is checked by nothing it computes itself."""
    rng = np.random.default_rng(7)
    worst = 0.0
    for q in random_configurations(rng, 3 if robot == "unicycle" else 5, 200):
        v1, v2 = rng.normal(size=2)
        if robot == "unicycle":
            v, omega = UNICYCLE.inputs(q, v1, v2)
            qdot = np.array(unicycle_velocity(q[2], v, omega))
            J = complex_step_jacobian(lambda p: np.stack([p[0], np.tan(p[2]), p[1]]), q)
            z = UNICYCLE.to_chained(q)
        else:
            u1, u2 = TRAILER.inputs(q, v1, v2)
            qdot = np.array(trailer_velocity(q[2], q[3], q[4], u1, u2, *dataclasses.astuple(TRAILER)))
            J = complex_step_jacobian(lambda p: _to_chained(p, TRAILER.wheelbase, TRAILER.hitch_length), q)
            z = TRAILER.to_chained(q)
        expected = chained_field(z, v1, v2)
        scale = np.maximum(1.0, np.abs(J) @ np.abs(qdot))  # the size of the terms J @ qdot sums, its rounding
        worst = max(worst, float(np.max(np.abs(J @ qdot - expected) / scale)))
    assert worst < 1e-12


@pytest.mark.parametrize("robot", [UNICYCLE, TRAILER])
def test_alpha_and_its_inverse_round_trip(robot):
    rng = np.random.default_rng(8)
    q = random_configurations(rng, 3 if robot is UNICYCLE else 5, 500)
    np.testing.assert_allclose(robot.from_chained(robot.to_chained(q)), q, rtol=0, atol=1e-12)
    z = robot.to_chained(q)
    np.testing.assert_allclose(robot.to_chained(robot.from_chained(z)), z, rtol=1e-11, atol=1e-11)


@pytest.mark.parametrize(
    ("q", "message"),
    [
        ([0.0, 0.0, 0.0, 0.0, np.pi / 2], r"jackknifed \(\|hitch angle\| >= pi/2\)"),
        ([0.0, 0.0, 0.0, 0.0, -2.0], "jackknifed"),
        ([0.0, 0.0, 1.6, 0.0, 0.0], r"trailer's \|theta1\| < pi/2"),
        ([0.0, 0.0, 0.0, 1.6, 0.0], r"\|phi\| < pi/2"),
        ([0.0, 0.0, 0.0, 0.0], r"\(x1, y1, theta1, phi, delta\)"),
    ],
)
def test_the_trailer_map_refuses_configurations_outside_its_chart(q, message):
    with pytest.raises(ValueError, match=message):
        TRAILER.to_chained(np.array(q))


def test_a_jackknifed_goal_is_a_config_error_naming_the_key():
    config = load_config("trailer_bay")
    task = dataclasses.replace(config.task, goal=(-1.5, 0.6, 0.5, 0.0, 1.6))
    with pytest.raises(ConfigError, match=r"task\.goal: .*jackknifed"):
        dataclasses.replace(config, task=task)
    task = dataclasses.replace(config.task, goal=(-1.5, 0.6, 0.5, 0.0, 1.5705))
    with pytest.raises(ConfigError, match=r"task\.goal: .*hitch angle \|delta\| must stay 0\.001 rad inside"):
        dataclasses.replace(config, task=task)


def test_a_unicycle_heading_outside_the_chart_is_refused():
    with pytest.raises(ValueError, match=r"\|theta\| < pi/2"):
        UNICYCLE.to_chained(np.array([0.0, 0.0, 1.7]))
    with pytest.raises(ValueError, match=r"\(x, y, theta\)"):
        UNICYCLE.to_chained(np.zeros(4))


def perturbed_plants():
    """The packaged tasks' plants, and the trailer with a steering limit it reaches."""
    for name in ("unicycle_parking", "trailer_bay"):
        yield name, load_config(name)
    config = load_config("trailer_bay")
    yield (
        "trailer_bay, 34 degree stop",
        dataclasses.replace(config, plant=dataclasses.replace(config.plant, steering_limit=0.6)),
    )


@pytest.mark.parametrize(("name", "config"), list(perturbed_plants()))
@pytest.mark.slow  # tight solve_ivp references
def test_the_kernel_matches_solve_ivp_within_1e_9(name, config):
    """The learner's first three trials on each plant (the nominal solution and two updates)."""
    scenario = Scenario.from_config(config)
    env = gym.make("ilc_steering/ChainedSteering-v0", config=config)
    rollout = run_trials(env, ILCAgent(env.unwrapped.nominal_model), 3)
    actions = np.array([info["action"] for info in rollout.infos])
    final = scenario.run(actions).final
    for c, x in zip(actions, final):
        expected = trial(scenario.plant, scenario.profile, scenario.x_start, c)
        np.testing.assert_allclose(x, expected, rtol=0, atol=1e-9)
    if "stop" in name:  # the limit is reached, so its crossings were located
        states = scenario.run(actions, record=True).states
        assert np.all(np.max(np.abs(states[:, :, 3]), axis=1) > scenario.plant.steering_limit)


@pytest.mark.parametrize("name", ["unicycle_parking", "trailer_bay"])
def test_the_nominal_plant_ends_where_eq_23_says(name):
    """With the true geometry the nominal one, the closed loop is eq. 1 exactly: the kernel's final
    state equals the closed form ``V z0 + W c`` at random coefficients."""
    scenario = Scenario.from_config(load_config(name))
    model = scenario.nominal
    family = ModelFamily(model)
    rng = np.random.default_rng(2)
    c = model.solve() * (1 + 0.02 * rng.standard_normal((6, model.profile.num_coefficients)))
    q, inside = family.configurations(np.zeros(family.size), c)
    assert inside.all()
    z = family.to_chained(q)
    expected = np.array([model.final_state(ci) for ci in c])
    np.testing.assert_allclose(z, expected, rtol=0, atol=1e-9)


@pytest.mark.parametrize(("name", "trials"), [("unicycle_parking", 8), ("trailer_bay", 4)])
def test_ilc_converges_under_a_10_percent_perturbation(name, trials):
    result = run_ilc(name, trials=12)
    assert result.converged_at == trials
    last = result.trials[-1]
    assert last.cartesian_error < 1e-5 and last.orientation_error < 1e-5


@pytest.mark.parametrize("ratio", [0.5, 0.3])
def test_the_trailer_leaving_its_chart_halts_the_trial(ratio):
    """A true hitch shorter than the nominal one jackknifes the trailer under the nominal solution:
    the trial stops at its last valid configuration, the last step before ``solve_ivp`` (on the
    robot's own field, with the chart as a terminal event) leaves the chart, not with a NaN.

    (Coefficients 100 times the nominal ones, which this test once used, swing the trailer near its
    edge with rates no fixed step of 1/32 s resolves; the reference stays 5 mrad inside there.)"""
    data = dataclasses.asdict(load_config("trailer_bay"))
    data["plant"]["true_hitch_length"] = ratio * data["plant"]["hitch_length"]
    config = load_config(data)
    scenario = Scenario.from_config(config)
    c = scenario.nominal.solve()
    c[1:] *= 3.0
    field, _, chart = scenario.plant.reference_field(scenario.profile, c)
    chart.terminal = True
    end = scenario.profile.breakpoints[-1]
    exit_time = solve_ivp(field, (0, end), scenario.x_start, method="DOP853", rtol=1e-11, atol=1e-11, events=[chart])
    (t_exit,) = exit_time.t_events[0]
    trials = scenario.run(c[None], record=True)
    assert trials.status[0] == LEFT_CHART
    last = int(np.searchsorted(trials.times, t_exit)) - 1  # the last step that ends inside
    np.testing.assert_array_equal(trials.final[0], trials.states[0, last])
    assert np.all(trials.states[0, last:] == trials.final[0]) and np.all(np.isfinite(trials.final[0]))
    assert np.any(trials.states[0, last - 1] != trials.final[0])  # it moved until then
    assert scenario.measure(trials.final, trials.status)["left_chart"][0]


@pytest.mark.parametrize("plant_class", [UnicyclePlant, TrailerPlant])
def test_jitter_and_the_family_scale_the_named_parameters(plant_class):
    config = load_config("unicycle_parking" if plant_class is UnicyclePlant else "trailer_bay")
    plant = config.plant.plant()
    scaled = plant.with_true_factors(np.array([1.5, 0.5]))
    names = [name.removesuffix("_ratio") for name in plant_class.factor_names]
    for name, factor in zip(names, (1.5, 0.5)):
        assert getattr(scaled.true, name) == pytest.approx(factor * getattr(plant.true, name))
    assert scaled.nominal == plant.nominal
    x0 = plant.initial_state(np.asarray(config.task.start))
    assert simulate(plant, config.task.profile(), x0[None], np.zeros((1, 1 + config.task.v2_terms))).status[0] == OK
