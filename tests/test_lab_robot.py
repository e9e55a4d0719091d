"""Section 5's lab robot (MARIO): play in the steering linkage and a dead-reckoned heading from
quantized wheel encoders, against an independent event-driven ``solve_ivp`` reference."""

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

from ilc_steering.config import load_config
from ilc_steering.core.integrate import OK
from ilc_steering.core.reference import lab_car_trial
from ilc_steering.core.robots.car_lab_lanes import LAB_KERNEL
from ilc_steering.core.robots.car_lab_step import lab_substeps
from ilc_steering.core.simulate import steps_per_span
from ilc_steering.envs.scenario import Scenario
from ilc_steering.errors import ConfigError

LAB = [
    {"encoder_pulses": 40},
    {"steering_backlash": 0.02},
    {"steering_backlash": 0.02, "encoder_pulses": 40},
    {"steering_backlash": 0.02, "encoder_pulses": 40, "steering_lag": 0.05, "speed_lag": 0.1, "steering_offset": 0.01},
]
OFF = {"steering_offset": 0.0, "steering_lag": 0.0, "speed_lag": 0.0, "steering_backlash": 0.0, "encoder_pulses": 0}


def scenario_with(name, **plant):
    config = load_config(name)
    return Scenario.from_config(dataclasses.replace(config, plant=dataclasses.replace(config.plant, **plant)))


def comparable(scenario, x):
    """The kernel's final state in the reference's terms: the wheel angle behind the play in place
    of the play's anchor, the wheel's total rotation in place of the rotation since the last pulse."""
    plant, x = scenario.plant, np.array(x)
    limit = np.inf if plant.steering_limit is None else plant.steering_limit
    phi_s = x[4] if plant.steering_lag else np.clip(x[3], -limit, limit)
    half = plant.steering_backlash / 2
    x[6] = np.clip(x[6], phi_s - half, phi_s + half)
    if plant.encoder_pulses:
        x[7] += x[11] * 2 * np.pi / plant.encoder_pulses
    return x


@pytest.mark.parametrize("name", ["forward_parking", "forward_parking_saturated", "experiment_forward"])
@pytest.mark.parametrize("lab", LAB, ids=lambda s: "+".join(s))
@pytest.mark.slow  # event-driven solve_ivp references
def test_the_lab_robot_within_1e9_of_an_event_driven_solve_ivp(name, lab):
    scenario = scenario_with(name, **{**OFF, **lab})
    assert scenario.plant.kernel()[0] is LAB_KERNEL and scenario.plant.state_dim == 12
    c = scenario.nominal.solve()
    trial = scenario.run(c[None])
    assert trial.status[0] == OK
    reference = lab_car_trial(scenario.plant, scenario.profile, scenario.x_start, c)
    np.testing.assert_allclose(comparable(scenario, trial.final[0]), reference, atol=1e-9)
    if "encoder_pulses" in lab:
        assert reference[11] > 100  # hundreds of pulses, each located and counted the same


def test_without_imperfections_the_lab_kernel_is_the_plain_car():
    plain = scenario_with("forward_parking_saturated")
    c = plain.nominal.solve()
    expected = plain.run(c[None]).final[0]
    # a play of 1e-300 rad switches the lab kernel on and changes nothing
    lab = scenario_with("forward_parking_saturated", steering_backlash=1e-300)
    got = lab.run(c[None]).final[0]
    np.testing.assert_allclose(got[:4], expected, atol=1e-12)


@pytest.mark.parametrize("lag", [0.0, 0.05])
@pytest.mark.slow  # compiles the one-by-one step (half a minute cold)
def test_a_play_under_the_rounding_costs_no_more_runge_kutta_steps_than_a_real_one(lag):
    # A play of 1e-300 rad rounds to none beside phi_s: its engaging event was fired at every substep
    # and located in vain (60 Runge-Kutta steps of the locator, about 50 a step, 16 times the cost).
    counts = {}
    for play in (1e-300, 1e-3):
        scenario = scenario_with("forward_parking_saturated", steering_lag=lag, steering_backlash=play)
        c = scenario.nominal.solve()[None]
        spans = np.asarray(scenario.profile.spans, dtype=np.float64)
        steps = steps_per_span(spans, scenario.max_step)
        v1, v2 = scenario.profile.polynomials(c)
        params = scenario.plant.kernel()[1]
        counts[play] = lab_substeps(params, scenario.x_start[None], spans, steps, v1, v2)[0] / steps.sum()
    assert 1.0 <= counts[1e-300] <= 1.05 * counts[1e-3] + 0.1 and counts[1e-3] < 2.5, counts


@pytest.mark.slow
def test_dead_reckoning_lags_with_coarse_encoders_and_vanishes_with_fine_ones():
    exact = scenario_with("forward_parking")
    c = exact.nominal.solve()
    true_final = exact.run(c[None]).final[0]
    lag, moved = {}, {}
    for pulses in (40, 4000, 100_000):
        trial = scenario_with("forward_parking", encoder_pulses=pulses).run(c[None], record=True)
        states = trial.states[0]
        lag[pulses] = np.abs(states[:, 10] - states[:, 2]).max()  # the estimate trails by up to a pitch
        moved[pulses] = np.abs(trial.final[0][:3] - true_final[:3]).max()
    # the estimated heading's error falls as the pitch (1/N), the final pose's change faster
    assert lag[40] > 1e-3 and lag[4000] < lag[40] / 50 and lag[100_000] < 1e-5
    assert moved[40] > 1e-5 and moved[4000] < moved[40] / 1000 and moved[100_000] < 1e-10


def test_the_wheel_stays_within_the_play_and_moves_only_when_pushed():
    half = 0.05
    scenario = scenario_with("forward_parking", steering_backlash=2 * half)
    trial = scenario.run(scenario.nominal.solve()[None], record=True)
    x = trial.states[0]
    phi_s = x[:, 3]
    wheel = np.clip(x[:, 6], phi_s - half, phi_s + half)
    gap = phi_s - wheel
    assert np.all(np.abs(gap) <= half + 1e-12)
    moved = np.abs(np.diff(wheel)) > 1e-12
    # between two records the wheel moves only if the servo pushes it at the edge of the play at
    # the start or the end of the interval
    edge = np.abs(np.abs(gap) - half) < 1e-9
    assert moved.any() and np.all((edge[:-1] | edge[1:])[moved])
    assert (~moved).sum() > 5  # and it rests for a while after each turn of the servo


def _config_path(name):
    from importlib.resources import files

    return files("ilc_steering.configs") / f"{name}.yaml"


def test_a_cyclic_task_refuses_the_lab_robot(tmp_path):
    import yaml

    raw = yaml.safe_load(open(_config_path("cyclic_home_goal")))
    raw["plant"]["encoder_pulses"] = 40
    path = tmp_path / "cyclic.yaml"
    path.write_text(yaml.safe_dump(raw))
    with pytest.raises(ConfigError, match="plant: steering_backlash and encoder_pulses are for one-trial tasks"):
        load_config(path)


REFERENCE = json.loads((Path(__file__).parent / "lab_reference.json").read_text())


@pytest.mark.parametrize("name", ["experiment_forward", "experiment_parallel"])
def test_the_lab_robot_within_1e9_of_its_kernel_before_the_closed_form_pulses(name):
    reference = REFERENCE[name]
    config = load_config(name)  # with the imperfections it had when the reference was recorded
    config = dataclasses.replace(config, plant=dataclasses.replace(config.plant, **reference["plant"]))
    scenario = Scenario.from_config(config)
    c = np.array(reference["c"])
    trials = scenario.run(c)
    assert trials.status.tolist() == reference["status"]
    expected = np.array(reference["final"])
    # The play's anchor (entry 6) was recorded as the wheel angle at the start of the last step; the
    # kernel now reports it at the end: the same wheel, pushed by the servo's output (entry 4, lagging).
    half = 0.5 * scenario.plant.steering_backlash
    expected[:, 6] = np.clip(expected[:, 6], expected[:, 4] - half, expected[:, 4] + half)
    np.testing.assert_allclose(trials.final, expected, rtol=0, atol=1e-9)


@pytest.mark.slow  # an event-driven solve_ivp reference
def test_a_trial_that_rests_at_the_stop_is_integrated_to_its_end():
    # A command that reaches the stop exactly (to the last bit) once fired the stop's event again and
    # again, each time a step under the clock's rounding, until the step gave up 10,000 events later
    # (seconds per step, and the step's remainder lost); this trial of benchmarks/robots.py did so.
    scenario = Scenario.from_config(load_config("experiment_forward"))
    c0 = scenario.nominal.solve()
    c = (c0 * (1 + 0.05 * np.random.default_rng(0).standard_normal((2048, c0.size)))).astype(np.float32)[56]
    c = c.astype(np.float64)
    trial = scenario.run(c[None])
    assert trial.status[0] == OK
    reference = lab_car_trial(scenario.plant, scenario.profile, scenario.x_start, c)
    np.testing.assert_allclose(comparable(scenario, trial.final[0]), reference, atol=1e-9)


@pytest.mark.slow  # compiles the one-by-one kernel (half a minute cold)
def test_the_lanes_kernel_is_the_one_by_one_kernel_recorded_and_off_the_chart():
    # 70 trials: a block of 64 lanes and a partial block of 6; perturbed by 30 %, some leave the chart
    from ilc_steering.core.integrate import integrate
    from ilc_steering.core.robots.car_lab_step import LAB_TRIAL_KERNEL

    scenario = Scenario.from_config(load_config("experiment_parallel"))
    c0 = scenario.nominal.solve()
    c = c0 * (1 + 0.3 * np.random.default_rng(1).standard_normal((70, c0.size)))
    spans = np.asarray(scenario.profile.spans, dtype=np.float64)
    steps = steps_per_span(spans, scenario.max_step)
    v1, v2 = scenario.profile.polynomials(c)
    params, x0 = scenario.plant.kernel()[1], np.repeat(scenario.x_start[None], len(c), 0)
    lanes = integrate(LAB_KERNEL, params, x0, spans, steps, v1, v2, record=True)
    one = integrate(LAB_TRIAL_KERNEL, params, x0, spans, steps, v1, v2, record=True)
    assert 0 < (lanes[1] != OK).sum() < 35 and lanes[1].tolist() == one[1].tolist()
    np.testing.assert_allclose(lanes[0], one[0], rtol=0, atol=1e-12)
    np.testing.assert_allclose(lanes[2], one[2], rtol=0, atol=1e-12)
