"""``robust_ilc``'s secant correction (:func:`~ilc_steering.agents.secant.fit_secant`) against
closed forms, and the simulated lab robot's experiment 2 over the seeds ``reproduce`` reports."""

import statistics

import numpy as np
import pytest

from ilc_steering.agents.secant import SECANT_PRIOR, fit_secant
from ilc_steering.runner import run_ilc

RNG = np.random.default_rng(7)
J_MODEL = RNG.normal(size=(4, 4)) * 20  # the refit model's Jacobian [chained units per action scale]
SIGMA = np.full(4, 1e-3)


def trials(J_true, z0, steps, noise=0.0):
    """Outcomes of an affine model and an affine plant at ``steps`` (row 0 the anchor's, zero)."""
    F = 0.3 + steps @ J_MODEL.T
    z = z0 + steps @ J_true.T + noise * RNG.normal(size=F.shape)
    return F, z


def test_where_the_model_explains_the_trials_there_is_no_correction():
    steps = np.vstack([np.zeros(4), RNG.normal(size=(5, 4)) * 0.05])
    F, _ = trials(J_MODEL, 0.3, steps)
    found = fit_secant(F, F.copy(), steps, SIGMA)
    assert np.array_equal(found.A, np.ones(4))
    assert np.array_equal(found.D, np.zeros((4, 4)))
    assert np.array_equal(found.z, F[0])


def test_an_affine_plant_is_learned_from_as_many_near_steps_as_coefficients():
    # gains and a rest a third of the prior's size
    J_true = J_MODEL * np.array([0.6, 0.7, 1.1, 1.3])[:, None] + RNG.normal(size=(4, 4)) * SECANT_PRIOR / 3
    z0 = np.array([0.01, -0.02, 0.03, 0.005])
    steps = np.vstack([np.zeros(4), np.eye(4) * 0.02])
    F, z = trials(J_true, z0, steps)
    found = fit_secant(F, z, steps, SIGMA)
    learned = found.A[:, None] * J_MODEL + found.D
    assert np.max(np.abs(learned - J_true)) < 1e-2 * np.max(np.abs(J_true))
    assert np.max(np.abs(found.z - z0)) < 0.1 * SIGMA[0]  # the priors pull it by less than a tenth of the scatter


def test_steps_within_the_scatter_teach_only_a_small_correction():
    steps = np.vstack([np.zeros(4), RNG.normal(size=(6, 4)) * 1e-6])  # moves far below the scatter's
    F, z = trials(J_MODEL, 0.3, steps, noise=1e-3)
    found = fit_secant(F, z, steps, SIGMA)
    # Least squares alone would fit the draws: a correction of about 1e-3 / 1e-6 per action scale.
    assert np.max(np.abs(found.D)) < 0.1 * SECANT_PRIOR
    assert np.max(np.abs(found.A - 1.0)) < 0.1
    # The anchor's outcome is smoothed by its neighbours: nearer the plant's than its own draw.
    assert np.linalg.norm(found.z - 0.3) < np.linalg.norm(z[0] - 0.3)


@pytest.mark.slow  # 20 runs of the lab robot, about 3 min
def test_the_calibrated_lab_robot_parks_and_goes_forward_in_two_trials():
    # results/reproduce/reproduce.txt: 2 [2, 3] on both (eqs. 33-34 take 5 and 4); the family holds the
    # controller's odometry and the car's actuators, identified from the first two trials
    parallel = [run_ilc("experiment_parallel", learner="robust_ilc", seed=seed).converged_at for seed in range(10)]
    forward = [run_ilc("experiment_forward", learner="robust_ilc", seed=seed).converged_at for seed in range(10)]
    assert None not in parallel and None not in forward
    assert statistics.median(parallel) <= 2 and max(parallel) <= 3
    assert statistics.median(forward) <= 2 and max(forward) <= 3
