"""``robust_ilc`` on the maps' edges: an identified model whose continuation folds is searched again
from other starts (:meth:`~ilc_steering.agents.identifier.Identifier.restarts`)."""

import dataclasses

import numpy as np
import pytest

from ilc_steering.agents.base import LearnerContext
from ilc_steering.agents.identifier import RESTART_FACTORS
from ilc_steering.agents.robust_ilc import make_robust_ilc
from ilc_steering.config import load_config
from ilc_steering.envs.scenario import Scenario
from ilc_steering.envs.steering_vector_env import ChainedSteeringVectorEnv
from ilc_steering.oracle import final_errors, solve_plants
from ilc_steering.sweep.rows import lockstep


def learn(name, trials, **keys):
    """Trials to the tolerance of ``robust_ilc`` on the config's plant with ``keys`` (0: none), the
    last trial's true error norm and the learner."""
    config = load_config(name)
    envs = ChainedSteeringVectorEnv(1, config, true_plants=[dataclasses.replace(config.plant, **keys).plant()])
    learner = make_robust_ilc(LearnerContext.from_env(envs))
    result = lockstep(envs, [learner], trials, config.learning.tolerance)
    return int(result["trials_to"][0]), float(result["error"][0]), learner


@pytest.mark.slow  # over 2.5 s: the README's test command stays under 5 min
def test_the_short_car_with_a_trailer_has_a_solution_on_another_branch():
    # The car-trailer at half the nominal wheelbase (the family's bound): from the nominal solution
    # and from the trials, the plant's own Levenberg-Marquardt ends 16 mm off the goal; the
    # nominal solution's v2 scaled by 2 reaches it (the oracle found it by continuation along the map).
    config = load_config("trailer_bay")
    scenario = Scenario.from_config(config)
    plant = dataclasses.replace(config.plant, true_hitch_length=0.3, true_wheelbase=0.1).plant()
    nominal = scenario.nominal.solve()
    starts = np.array([nominal, np.concatenate([nominal[:1], 2.0 * nominal[1:]])])
    _, error = solve_plants(scenario, [plant, plant], starts)
    assert error[0] > 1e-3  # the nominal solution's basin: a local minimum
    assert 2.0 in RESTART_FACTORS
    # robust_ilc identifies the plant in one trial, then searches its model from the restarts
    trials, last, learner = learn("trailer_bay", 6, true_hitch_length=0.3, true_wheelbase=0.1)
    assert 0 < trials <= 3, trials
    assert last < 1e-5
    assert np.allclose(list(learner.family.parameters(learner.theta).values()), [0.5, 1.1, 1.0], atol=1e-6)
    assert final_errors(scenario, [plant], learner.act()[None])[0] < 1e-5


@pytest.mark.slow  # over 2.5 s: the README's test command stays under 5 min
def test_restarts_run_once_per_estimate_and_only_where_it_explains_the_trials():
    trials, _, learner = learn("trailer_bay", 2, true_hitch_length=0.3, true_wheelbase=0.1)
    identifier = learner.identifier
    identifier.restarted = None
    goal = learner.model.z_goal

    def restarts():
        return identifier.restarts(goal, learner.trials, learner.best, thorough=True)

    assert restarts().shape == (len(RESTART_FACTORS), learner.start.size)
    assert restarts().shape[0] == 0  # the same estimate: searched already
    identifier.restarted = None
    identifier.theta = identifier.theta + 0.1  # an estimate that does not explain the trials
    assert restarts().shape[0] == 0


@pytest.mark.slow  # about 10 s: the servo kernel
@pytest.mark.parametrize(
    ("name", "keys"),
    [
        ("parallel_parking_servo", {"steering_offset": 0.03, "true_wheel_radius": 0.02}),
        ("parallel_parking_lag", {"steering_lag": 0.05, "steering_offset": 0.03}),
    ],
)
def test_the_servo_car_at_the_largest_offset_is_parked(name, keys):
    # Identified exactly (geometry, offset and lag) by trial 2, its continuation ended 6 mm (servo)
    # and 33 mm (lag) off the goal and the trials repeated; the restarts find the solution.
    trials, last, _ = learn(name, 8, **keys)
    assert 0 < trials <= 4, trials
    assert last < 1e-6


@pytest.mark.slow  # about 5 s: the servo kernel
def test_the_servo_car_at_half_the_wheel_radius_is_identified_from_its_first_trial():
    # The first trial ends 1.2 m off the goal; the servo family's fits from the best 3 grid points
    # (the geometry at its own fit and at the nominal) found no fit of it and, counted as failures
    # with one in-chart trial, the servo families were never tried again (lost for 30 trials).
    # With the geometry grid's best points and 8 starts the plant is identified and parked.
    trials, last, learner = learn("parallel_parking_servo", 6, steering_offset=0.0225, true_wheel_radius=0.01)
    assert 0 < trials <= 4, trials
    assert learner.family.names[-1] == "steering_lag"
    found = learner.family.parameters(learner.theta)
    assert abs(found["wheel_radius_ratio"] - 0.5) < 1e-6 and abs(found["steering_offset"] - 0.0225) < 1e-6


@pytest.mark.slow  # about 10 s: the servo kernel
def test_the_servo_car_whose_nominal_plan_ends_near_the_chart_s_edge_is_parked():
    # Offset 0.0075 rad, wheel radius 0.03 m: the nominal plan ends 5 m off the goal at 76 degrees of
    # heading, where halving the step moves the end by metres. Fitted with that trial, the servo's
    # families never explained the trials; its neighbours left the chart and the learner sent it
    # again for 25 trials; the residuals of a family that cannot explain a plant read as a scatter
    # of 3 cm, and the learner averaged its way off. Now the wild trial leaves the fit once two
    # others stayed in the chart: the servo's family explains the trials, and no scatter is seen.
    trials, last, learner = learn("parallel_parking_servo", 30, steering_offset=0.0075, true_wheel_radius=0.03)
    assert 0 < trials <= 8, trials
    assert last < 5e-4
    assert learner.scatter is None and learner.family.names[-1] == "steering_lag"


@pytest.mark.slow  # about 10 s: the servo kernel
def test_the_servo_car_at_the_map_s_corner_is_parked():
    # Offset -0.03 rad, wheel radius 0.01 m: its plans from the first trial left the chart 15 times
    # in 17 trials (a trust region of twice the failed step), and the run was then called "converged
    # to the plant's floor" on a plant that repeats itself. A step that leaves the chart now halves
    # the region, and one from a trial farther off than the start aims nearer the start.
    trials, last, _ = learn("parallel_parking_servo", 30, steering_offset=-0.03, true_wheel_radius=0.01)
    assert 0 < trials <= 10, trials
    assert last < 5e-4
