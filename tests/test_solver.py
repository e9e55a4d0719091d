"""The solver (``agents/solver.py``) alone: the refit model brought to the goal by Newton's method or
the continuation, and the trust region's bounds."""

import numpy as np
import pytest

from ilc_steering.agents.secant import Secant
from ilc_steering.agents.solver import LEFT_CHART_SHRINK, SHRINK, Solver, TrustRegion
from ilc_steering.config import load_config
from ilc_steering.core.family import ModelFamily
from ilc_steering.envs.scenario import Scenario

THETA = np.array([np.log(1.25), np.log(0.8)])
"""A refit model 25 % longer and with wheels 20 % smaller than the nominal car."""


@pytest.fixture(scope="module")
def parts():
    model = Scenario.from_config(load_config("forward_parking")).nominal
    scale = model.action_scale()
    low, high = model.solve() - 50 * scale, model.solve() + 50 * scale
    return model, ModelFamily(model), Solver(model, low, high)


def test_the_continuation_lands_the_refit_model_on_the_goal(parts):
    model, family, solver = parts
    c0 = model.solve()
    secant = Secant.none(model.dimension, c0.size)
    c = solver.solve(family, THETA, secant, None, 1.0, True, lambda target: np.empty((0, c0.size)))
    q, ok = family.configurations(THETA, c[None])
    assert ok[0] and np.linalg.norm(q[0] - solver.goal_q) < 1e-8
    q0, _ = family.configurations(THETA, c0[None])
    assert np.linalg.norm(q0[0] - solver.goal_q) > 1e-2  # the nominal solution misses on this model


def test_the_trust_region_bounds_a_step_and_shrinks_after_a_failure():
    scale = np.array([1.0, 2.0])
    region = TrustRegion(scale, np.full(2, -100.0), np.full(2, 100.0))
    origin, far = np.zeros(2), np.array([4.0, 4.0])
    assert np.array_equal(region.within(origin, far), far)  # no bound yet
    region.failed(np.array([1.0, 0.0]), left_chart=False, explains=False)
    assert region.radius == SHRINK * 1.0
    np.testing.assert_allclose(region.within(origin, far), [2.0, 2.0])  # 4 action scales of x pulled back to 2
    region.failed(np.array([0.0, 2.0]), left_chart=True, explains=False)
    assert region.radius == LEFT_CHART_SHRINK * 1.0
    region.improved(np.array([3.0, 0.0]), explains=False)
    assert region.radius == 6.0
    region.improved(None, explains=True)
    assert region.radius == np.inf
