"""Levenberg-Marquardt from many starts in lockstep (:func:`levenberg_marquardt_many`) equals the
sequential Levenberg-Marquardt from each start alone, bit for bit (issue 52: updates that cost
what they need, results unchanged).

The reference is the sequential loop as it was before the lockstep one replaced it, copied here
verbatim: each start's estimate and residual must equal its bytes, on random least-squares
problems and on ``robust_ilc``'s own residuals (the family's simulations, geometry and servo)."""

import numpy as np
import pytest

from ilc_steering.agents.identifier import FIT_TOLERANCE, HALVINGS, STALL, Identifier
from ilc_steering.agents.levenberg_marquardt import levenberg_marquardt, levenberg_marquardt_many
from ilc_steering.agents.trial import Trial
from ilc_steering.config import load_config
from ilc_steering.envs.scenario import Scenario


def sequential_lm(residuals, theta, low, high, iterations, halvings=8, done=None, stall=0.0):
    """The sequential Levenberg-Marquardt as it was (agents/model_based.py before the lockstep), with
    the stall rule: an iteration that lowers the cost by at most ``stall`` of it is the last."""
    h, damping = 1e-6, 1e-3
    eye = np.eye(theta.size)
    r = residuals(theta[None])[0]
    for _ in range(iterations):
        before = r @ r
        values = residuals(np.concatenate([theta + h * eye, theta - h * eye]))
        J = np.ascontiguousarray((values[: theta.size] - values[theta.size :]).T) / (2 * h)
        gradient, normal = J.T @ r, J.T @ J
        improved = False
        for _ in range(halvings):
            step = -np.linalg.solve(normal + damping * np.diag(np.diag(normal) + 1e-12), gradient)
            candidate = np.clip(theta + step, low, high)
            r_new = residuals(candidate[None])[0]
            if r_new @ r_new < r @ r:
                theta, r, damping, improved = candidate, r_new, damping / 3, True
                break
            damping *= 4
        if not improved or np.max(np.abs(step)) < 1e-12 or (done is not None and done(r)):
            break
        if before - r @ r <= stall * before:
            break
    return theta, r


def same_bits(a, b):
    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    return a.shape == b.shape and a.tobytes() == b.tobytes()


def random_problem(rng):
    """Residuals ``(M, R)`` of a random smooth least-squares problem in ``size`` parameters, one
    hypothesis at a time (so a row cannot depend on its batch), with local minima and a box."""
    size, m = int(rng.integers(1, 5)), int(rng.integers(3, 12))
    A, B = rng.standard_normal((m, size)), rng.standard_normal((m, size))
    b, w = rng.standard_normal(m), rng.uniform(0.5, 2.0, m)

    def residuals(thetas):
        return np.array([np.concatenate([w * np.tanh(A @ t + b) + np.sin(B @ t), 1e-4 * t]) for t in thetas])

    low = -rng.uniform(0.5, 2.0, size)
    return residuals, size, low, -low


@pytest.mark.parametrize("seed", range(12))
def test_lockstep_lm_equals_the_sequential_lm_bit_for_bit_on_random_problems(seed):
    rng = np.random.default_rng(seed)
    residuals, size, low, high = random_problem(rng)
    starts = rng.uniform(low, high, (int(rng.integers(1, 8)), size))
    iterations, halvings = int(rng.integers(2, 25)), int(rng.integers(4, 9))
    tolerance = float(rng.choice([0.0, 1e-3, 1e-1]))
    done = (lambda r: float(np.max(np.abs(r))) < tolerance) if tolerance else None
    stall = float(rng.choice([0.0, 1e-3, 1e-1]))
    thetas, rs = levenberg_marquardt_many(residuals, starts, low, high, iterations, halvings, done, stall)
    assert thetas.shape == starts.shape
    for start, theta, r in zip(starts, thetas, rs):
        theta_alone, r_alone = sequential_lm(residuals, start, low, high, iterations, halvings, done, stall)
        assert same_bits(theta, theta_alone) and same_bits(r, r_alone)
        one = levenberg_marquardt(residuals, start, low, high, iterations, halvings, done, stall)
        assert same_bits(one[0], theta_alone) and same_bits(one[1], r_alone)
    moved = [not same_bits(t, s) for t, s in zip(thetas, starts)]
    assert any(moved)  # the problem is not trivial: some start was improved on


@pytest.mark.parametrize("family_index", [0, 1])
def test_lockstep_lm_equals_the_sequential_lm_on_robust_ilcs_residuals(family_index):
    """The geometry's family and the servo's (offset), fitted to trials of a plant outside both:
    the batch of every start's probes runs on the compiled kernel, each row as alone."""
    identification = Identifier(Scenario.from_config(load_config("experiment_parallel")).nominal)
    family = identification.families[family_index]
    truth = identification.families[2]  # a lagging servo with an offset: neither family explains it
    rng = np.random.default_rng(5)
    solution = family.model.solve()
    c = solution * (1 + 0.05 * rng.standard_normal((5, solution.size)))
    q, ok = truth.configurations(np.array([0.1, -0.05, 0.02, 0.05]), c)
    goal_q = family.to_configuration(family.model.z_goal)
    trials = [
        Trial(ci, family.to_chained(qi), qi, float(np.linalg.norm(qi - goal_q)), bool(oki))
        for ci, qi, oki in zip(c, q, ok)
    ]
    starts = rng.uniform(0.5 * family.low, 0.5 * family.high, (3, family.size))
    fits = identification.fits(family, starts, trials)

    def residuals(thetas):
        return identification.residuals(thetas, trials, family)

    def done(r):
        return float(np.max(np.abs(r[: -family.size]), initial=0.0)) < 1e-3 * FIT_TOLERANCE

    for start, (fitted, theta, r) in zip(starts, fits):
        assert fitted is family
        theta_alone, r_alone = sequential_lm(residuals, start, family.low, family.high, 20, HALVINGS, done, STALL)
        assert same_bits(theta, theta_alone) and same_bits(r, r_alone)
        assert not same_bits(theta, start)
