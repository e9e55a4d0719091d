"""The scatter's band of the model-based learners (``agents/scatter_band.py``'s ``ScatterBand``), alone
on synthetic trials: the trials before its entry count, and the last estimate stands in while the
trials give none."""

import gymnasium as gym
import numpy as np
import pytest

import ilc_steering  # noqa: F401  (registers the envs)
from ilc_steering.agents.scatter_band import BAND, ScatterBand
from ilc_steering.agents.trial import Trial
from ilc_steering.config import load_config
from ilc_steering.core.family import ModelFamily

SIGMA = 1e-3
"""[m, rad] the synthetic trials' scatter per coordinate."""


@pytest.fixture(scope="module")
def plant():
    env = gym.make("ilc_steering/ChainedSteering-v0", config=load_config("forward_parking"))
    model = env.unwrapped.nominal_model
    family = ModelFamily(model)
    return model, family, family.to_configuration(model.z_goal), model.solve()


def trial(model, family, c, q):
    z = family.to_chained(q)
    return Trial(c, z, q, float(np.linalg.norm(q - family.to_configuration(model.z_goal))))


def draws(plant, offsets):
    """Trials of the nominal solution (on the nominal model: it lands on the goal) whose measured
    configuration is the goal plus each row of ``offsets``."""
    model, family, goal_q, c = plant
    return [trial(model, family, c.copy(), goal_q + o) for o in offsets]


def test_a_band_begins_with_the_near_trials_before_it(plant):
    model, family, goal_q, _ = plant
    rng = np.random.default_rng(3)
    far = np.full(goal_q.size, 200 * SIGMA)  # a first trial far off: not a draw of the scatter
    trials = draws(plant, [far, *rng.normal(0.0, SIGMA, (5, goal_q.size))])
    band = ScatterBand(model, goal_q)
    inside = band.update(family, np.zeros(family.size), trials, trials[-1])
    scatter = band.scatter
    assert scatter is not None and inside
    assert np.all(scatter > SIGMA / 3) and np.all(scatter < 3 * SIGMA)
    assert [id(t) for t in band.trials] == [id(t) for t in trials[1:]]  # the five near trials, not the far one


def test_a_trial_beyond_twice_the_band_is_not_counted_into_it(plant):
    model, family, goal_q, _ = plant
    rng = np.random.default_rng(3)
    offsets = rng.normal(0.0, SIGMA, (6, goal_q.size))
    offsets[2] = 2.5 * BAND * 5 * SIGMA  # well beyond twice the band of any estimate of these draws
    trials = draws(plant, offsets)
    band = ScatterBand(model, goal_q)
    inside = band.update(family, np.zeros(family.size), trials, trials[-1])
    assert inside and [id(t) for t in band.trials] == [id(t) for t in trials[3:]]


def test_the_last_estimate_stands_in_while_the_band_lasts(plant):
    model, family, goal_q, _ = plant
    trials = draws(plant, [np.full(goal_q.size, SIGMA), np.full(goal_q.size, -SIGMA)])  # too few to estimate
    last = np.array([SIGMA, SIGMA])
    band = ScatterBand(model, goal_q)
    band.scatter, band.trials = last, [trials[0]]
    inside = band.update(family, np.zeros(family.size), trials, trials[1])
    assert inside and band.scatter is last and len(band.trials) == 2
    # Without a band, no estimate means no band: the last estimate does not start one.
    band.scatter, band.trials = last, []
    inside = band.update(family, np.zeros(family.size), trials, trials[1])
    assert band.scatter is None and not inside and band.trials == []


def test_a_trial_at_another_action_is_not_counted_into_it(plant):
    """A trial whose action the model says lands far from the entry trial's (outside the family its
    offset is another one) does not begin the band, though it measured near the goal."""
    model, family, goal_q, c = plant
    rng = np.random.default_rng(3)
    trials = draws(plant, rng.normal(0.0, SIGMA, (6, goal_q.size)))
    moved = c + 0.05 * model.action_scale()
    q_moved, ok = family.configurations(np.zeros(family.size), np.array([c, moved]))
    assert ok.all() and np.linalg.norm(q_moved[1] - q_moved[0]) > 50 * SIGMA  # the model moves it far
    trials[3] = trial(model, family, moved, trials[3].q)
    band = ScatterBand(model, goal_q)
    inside = band.update(family, np.zeros(family.size), trials, trials[-1])
    assert inside and [id(t) for t in band.trials] == [id(t) for t in trials[4:]]


def test_the_band_averages_the_draws_of_its_trials(plant):
    """The offset the learner corrects in the band is the mean of its trials' draws, not the last draw."""
    model, family, goal_q, _ = plant
    rng = np.random.default_rng(4)
    trials = draws(plant, rng.normal(0.0, SIGMA, (6, goal_q.size)))
    band = ScatterBand(model, goal_q)
    assert band.update(family, np.zeros(family.size), trials, trials[-1])
    assert len(band.trials) >= 4
    q_model, ok = family.configurations(np.zeros(family.size), band.actions())
    predicted = family.to_chained(q_model)  # the nominal model at the nominal solution: the goal
    offset = band.offset(predicted, ok)
    mean = np.mean([t.z - model.z_goal for t in band.trials], axis=0)
    np.testing.assert_allclose(offset, mean, rtol=0, atol=1e-9)
    assert np.linalg.norm(offset - (band.trials[-1].z - model.z_goal)) > SIGMA / 10
