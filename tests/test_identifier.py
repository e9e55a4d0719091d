"""The identifier (``agents/identifier.py``) alone: trials of a known perturbed plant of a family, and
the family's parameters it fits to them, globally (``robust_ilc``'s) and locally (``newton_ilc``'s)."""

import numpy as np
import pytest

from ilc_steering.agents.identifier import FIT_TOLERANCE, Identifier, carried_family, local_fit
from ilc_steering.agents.trial import Trial
from ilc_steering.config import load_config
from ilc_steering.envs.scenario import Scenario

TRUE = np.array([np.log(1.25), np.log(0.8)])
"""The plant's log-ratios to the nominal wheelbase and wheel radius: 25 % long, 20 % short."""


@pytest.fixture(scope="module")
def identifier():
    return Identifier(Scenario.from_config(load_config("forward_parking")).nominal)


def trials_of(identifier, theta, scales):
    """Trials of the plant ``theta`` of the geometry's family: the nominal solution with its ``v2``
    coefficients scaled by each of ``scales``, measured exactly."""
    family = identifier.families[0]
    c0 = identifier.model.solve()
    c = np.array([np.concatenate([c0[:1], s * c0[1:]]) for s in scales])
    q, ok = family.configurations(theta, c)
    assert ok.all()
    goal_q = identifier.goal_q
    return [Trial(ci, family.to_chained(qi), qi, float(np.linalg.norm(qi - goal_q))) for ci, qi in zip(c, q)]


def test_it_identifies_a_perturbed_plant_of_its_family(identifier):
    identifier.reset()
    trials = trials_of(identifier, TRUE, [1.0, 1.1])
    assert not identifier.explains(trials, None)  # the nominal parameters do not explain them
    identifier.refit(trials, None, thorough=True)
    assert identifier.family is identifier.families[0]
    np.testing.assert_allclose(identifier.theta, TRUE, atol=1e-6)
    assert identifier.explains(trials, None)
    r = identifier.residuals(identifier.theta[None], trials)[0]
    assert identifier.misfit(r) < FIT_TOLERANCE
    # What it carries to the next goal is read back as the same estimate.
    carried = carried_family(identifier.families, {"robust_ilc": identifier.transfer()})
    assert carried.family is identifier.family and np.array_equal(carried.theta, identifier.theta)


def test_the_local_fit_identifies_it_from_nearby(identifier):
    trials = trials_of(identifier, TRUE, [1.0])
    theta = local_fit(identifier.families[0], trials, np.zeros(2))
    np.testing.assert_allclose(theta, TRUE, atol=1e-5)


def test_on_the_nominal_plant_the_estimate_stays_nominal(identifier):
    identifier.reset()
    trials = trials_of(identifier, np.zeros(2), [1.0, 0.9])
    assert identifier.explains(trials, None)
    identifier.refit(trials, None, thorough=True)
    assert np.array_equal(identifier.theta, np.zeros(2))
