"""V and W (eqs. 21-25) against their integrals, the section 4 closed forms and the chained ODE."""

import numpy as np
import pytest
from scipy.integrate import quad_vec, solve_ivp
from scipy.linalg import expm

from ilc_steering.core.chained_form import chained_rhs, drift_matrix, piece_transition, transition
from ilc_steering.core.profiles import PiecewiseProfile


@pytest.mark.parametrize("n", [3, 4, 6])
@pytest.mark.parametrize("q_extra", [0, 2])
def test_piece_transition_matches_quadrature_of_eq_22(n, q_extra):
    rng = np.random.default_rng(n + q_extra)
    v1, delta = rng.uniform(-1.5, 1.5), rng.uniform(0.5, 3.0)
    q = n - 1 + q_extra
    basis = rng.normal(size=(q, q))  # lambda_j as arbitrary polynomials in the local time
    A = drift_matrix(v1, n)
    B = np.eye(n - 1)[:, 0]

    def integrand(tau):
        lam = basis @ tau ** np.arange(q)
        return np.outer(expm(A * (delta - tau)) @ B, lam)

    W_quad, _ = quad_vec(integrand, 0.0, delta, epsabs=1e-13, epsrel=1e-13)
    V, W = piece_transition(v1, delta, n, basis)
    np.testing.assert_allclose(V, expm(A * delta), rtol=1e-13, atol=1e-13)
    np.testing.assert_allclose(W, W_quad, rtol=1e-10, atol=1e-12)


def test_section_4_closed_forms_for_n4_p1():
    T, c11 = 5.0, 0.37
    V, W = PiecewiseProfile((T,), (), 3).transition(c11, 4)
    # The paper prints 0 in the last diagonal entry of V; V = exp(A T) has 1 there.
    V_paper = np.array([[1, 0, 0], [c11 * T, 1, 0], [c11**2 * T**2 / 2, c11 * T, 1]])
    W_paper = np.array(
        [
            [T, T**2 / 2, T**3 / 3],
            [c11 * T**2 / 2, c11 * T**3 / 6, c11 * T**4 / 12],
            [c11**2 * T**3 / 6, c11**2 * T**4 / 24, c11**2 * T**5 / 60],
        ]
    )
    np.testing.assert_allclose(V, V_paper, rtol=1e-14)
    np.testing.assert_allclose(W, W_paper, rtol=1e-14)


@pytest.mark.parametrize("n, durations, v1_fixed", [(4, (2.5, 2.5), (-0.24,)), (5, (1.0, 2.0, 1.5), (0.7, -0.4))])
def test_transition_predicts_the_chained_ode(n, durations, v1_fixed):
    rng = np.random.default_rng(n)
    profile = PiecewiseProfile(durations, v1_fixed, n - 1)
    c = rng.normal(size=n)
    z0 = rng.normal(size=n)
    z = z0.copy()
    for t0, t1 in zip(profile.breakpoints[:-1], profile.breakpoints[1:]):
        sol = solve_ivp(
            lambda t, y: chained_rhs(y, *map(float, profile.evaluate(c, np.array(t)))),
            (t0, t1),
            z,
            method="DOP853",
            rtol=1e-12,
            atol=1e-12,
        )
        z = sol.y[:, -1]
    V, W = profile.transition(c[0], n)
    np.testing.assert_allclose(z[1:], V @ z0[1:] + W @ c[1:], rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(z[0], z0[0] + profile.v1_pieces(c[0]) @ np.array(durations), atol=1e-12)


def test_transition_chains_pieces_as_eqs_24_25():
    rng = np.random.default_rng(0)
    n, bases = 4, rng.normal(size=(3, 3, 3))
    v1, durations = np.array([0.3, -0.5, 1.1]), np.array([1.0, 0.5, 2.0])
    parts = [piece_transition(a, d, n, b) for a, d, b in zip(v1, durations, bases)]
    (V1, W1), (V2, W2), (V3, W3) = parts
    V, W = transition(v1, durations, n, bases)
    np.testing.assert_allclose(V, V3 @ V2 @ V1, rtol=1e-14)
    np.testing.assert_allclose(W, W3 + V3 @ W2 + V3 @ V2 @ W1, rtol=1e-13)


def test_profile_rejects_bad_pieces():
    with pytest.raises(ValueError, match="pieces"):
        PiecewiseProfile((5.0, -1.0), (0.1,), 3)
    with pytest.raises(ValueError, match="v1_fixed"):
        PiecewiseProfile((2.5, 2.5), (), 3)
    with pytest.raises(ValueError, match="v2_terms"):
        PiecewiseProfile((5.0,), (), 0)
