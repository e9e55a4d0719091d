"""The actuators' families (``agents/actuator_families.py``) and the controller's odometry in them: the
simulated lab robot is a member of its family at its true parameters, the families grow one actuator
at a time, and the simplest family that explains the trials about as well as any is kept."""

import dataclasses

import numpy as np
import pytest

from ilc_steering.agents.actuator_families import (
    ACTUATOR_FAMILIES,
    EXPLAINED,
    FAR_BETTER,
    RICHER_GAIN,
    ActuatorFamilies,
    misfit,
    spread,
    squared,
)
from ilc_steering.agents.identifier import FIT_TOLERANCE
from ilc_steering.config import load_config
from ilc_steering.core.family import ModelFamily
from ilc_steering.core.simulate import simulate
from ilc_steering.envs.scenario import Scenario


@pytest.fixture(scope="module")
def lab():
    """Experiment 2's scenario: the calibrated MARIO, its heading dead-reckoned from 40 pulses a turn."""
    return Scenario.from_config(load_config("experiment_parallel"))


def test_the_nominal_model_carries_the_controllers_odometry_and_nothing_of_the_plant(lab):
    model = lab.nominals[0]
    assert lab.plant.encoder_pulses == 40 and model.encoder_pulses == 40
    forward = Scenario.from_config(load_config("forward_parking")).nominals[0]
    assert forward.encoder_pulses == 0  # a car that measures its heading


def test_the_lab_robot_is_its_family_at_its_true_parameters(lab):
    """The plant's final configurations, to the integrator's 1e-9, from the family of the offset,
    the play and the drive's lag at the plant's values (its steering lag is 0): the hypotheses count
    the controller's pulses as the robot does. Without the odometry they miss by centimetres."""
    plant, model = lab.plant, lab.nominals[0]
    names = ("steering_offset", "steering_backlash", "speed_lag")
    assert names in ACTUATOR_FAMILIES and plant.steering_lag == 0.0
    family = ModelFamily(model, actuators=names)
    ratio = np.log(plant.true.wheel_radius / plant.nominal.wheel_radius)
    theta = np.array([0.0, ratio, plant.steering_offset, plant.steering_backlash, plant.speed_lag])
    c0 = model.solve()
    c = np.array([np.concatenate([c0[:1], s * c0[1:]]) for s in (1.0, 0.9, 1.1)])
    x0 = np.broadcast_to(plant.initial_state(family.to_configuration(model.z_start)), (3, plant.state_dim))
    measured = plant.configuration(simulate(plant, model.profile, np.ascontiguousarray(x0), c, lab.max_step).final)
    q, ok = family.configurations(theta, c)
    assert ok.all()
    np.testing.assert_allclose(q, measured, atol=1e-9)
    blind = ModelFamily(dataclasses.replace(model, encoder_pulses=0), actuators=names)
    assert np.max(np.abs(blind.configurations(theta, c)[0] - measured)) > 1e-2


def test_each_later_family_grows_from_its_richest_subfamilies(lab):
    families = ActuatorFamilies(lab.nominals[0])
    assert len(families.families) == 1 + len(ACTUATOR_FAMILIES)
    names = [set(family.names) for family in families.families]
    for k in range(1, len(names)):
        parents = families._parents(k)
        assert all(names[j] < names[k] for j in parents)
        assert not any(names[j] < names[i] for i in parents for j in parents)  # none within another
    # a lag-free servo is reached without the steering lag (stiff near 0): the lag comes last, all
    # four grown from the lag's family and from the play and the drive's
    everything = families.families[-1]
    assert everything.names[-1] == "steering_lag"
    assert [families.families[j].names[2:] for j in families._parents(len(names) - 1)] == [
        ("steering_offset", "steering_lag"),
        ("steering_offset", "steering_backlash", "speed_lag"),
    ]
    grown = families._grown(np.array([0.1, -0.1, 0.01, 0.1]), 2, len(names) - 1)
    assert grown.shape == (5 * 6, everything.size)
    np.testing.assert_array_equal(grown[:, [0, 1, 2, 5]], np.tile([0.1, -0.1, 0.01, 0.1], (30, 1)))


def _fit(family, squared_misfit):
    """A fit of ``family`` whose trials' residuals have this squared sum (one number carries it)."""
    r = np.zeros(8 + family.size)
    r[0] = np.sqrt(squared_misfit)
    return family, np.zeros(family.size), r


def test_a_richer_family_is_kept_only_if_it_explains_the_trials_clearly_better(lab):
    families = ActuatorFamilies(lab.nominals[0])
    geometry, offset, lag = families.families[:3]
    simpler = _fit(geometry, 1e-4)
    barely = _fit(offset, 1e-4 / RICHER_GAIN * 1.01)
    assert families.simplest([simpler, barely], 12, FIT_TOLERANCE) is simpler
    clearly = _fit(lag, 1e-4 / RICHER_GAIN * 0.99)
    assert families.simplest([simpler, barely, clearly], 12, FIT_TOLERANCE) is clearly
    # a family that does not explain the trials (to EXPLAINED, root mean square) caricatures them
    caricature = _fit(lag, 8 * (1.01 * EXPLAINED) ** 2 + 1e-12)  # spread just above EXPLAINED
    far = _fit(geometry, 10 * squared(caricature))
    assert spread(caricature) > EXPLAINED and squared(caricature) < squared(far) / RICHER_GAIN
    assert families.simplest([far, caricature], 12, FIT_TOLERANCE) is far
    # unless it is far better: the right family whose fit has not converged yet
    wild = _fit(geometry, 1.0)
    converging = _fit(lag, 0.99 / FAR_BETTER)
    assert spread(converging) > EXPLAINED
    assert families.simplest([wild, converging], 12, FIT_TOLERANCE) is converging


def test_a_family_the_trials_do_not_determine_is_not_kept(lab):
    """One trial's four numbers: the offset's family (three parameters with the geometry) is
    overdetermined; the lag's (four) only if its fit is exact; the drive's (five) never."""
    families = ActuatorFamilies(lab.nominals[0])
    geometry, offset, lag = families.families[:3]
    drive = families.families[4]  # the offset, the play and the drive's lag: five parameters
    simpler = _fit(geometry, 1e-2)
    assert families.simplest([simpler, _fit(offset, 1e-6)], 4, FIT_TOLERANCE)[0] is offset
    near = _fit(lag, (0.5 * EXPLAINED) ** 2)  # explains to the noise, but a square system always has fits
    assert families.simplest([simpler, near], 4, FIT_TOLERANCE) is simpler
    exact = _fit(lag, (0.1 * FIT_TOLERANCE) ** 2)
    assert misfit(exact) < FIT_TOLERANCE
    assert families.simplest([simpler, exact], 4, FIT_TOLERANCE) is exact
    assert families.simplest([simpler, _fit(drive, 0.0)], 4, FIT_TOLERANCE) is simpler
    assert families.simplest([simpler, _fit(drive, 0.0)], 8, FIT_TOLERANCE)[0] is drive


def test_a_robot_without_actuators_has_the_geometrys_family_alone():
    unicycle = Scenario.from_config(load_config("unicycle_parking")).nominals[0]
    assert len(ActuatorFamilies(unicycle).families) == 1


def test_odometry_on_a_robot_that_has_none_is_refused_naming_the_robot():
    import dataclasses as dc

    from ilc_steering.errors import BadInput

    unicycle = Scenario.from_config(load_config("unicycle_parking")).nominals[0]
    with pytest.raises(BadInput, match=r"counts 40 encoder pulses a turn, but the unicycle robot's plant"):
        ModelFamily(dc.replace(unicycle, encoder_pulses=40))
