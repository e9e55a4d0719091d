r"""The two-input chained form and its exact transition under piecewise-constant ``v1``.

The one-chain system of dimension ``n`` (eq. 1),

.. math::

    \dot z_1 = v_1, \quad \dot z_2 = v_2, \quad \dot z_i = z_{i-1} v_1 \; (i = 3, \dots, n),

splits into the integrator :math:`z_a = z_1` (eq. 12) and the linear time-varying system
:math:`\dot z_b = A(v_1) z_b + B v_2` with :math:`z_b = (z_2, \dots, z_n)` (eqs. 13-14).
On a piece of duration :math:`\Delta` where ``v1`` is constant, ``A`` is nilpotent, so the
transition matrices of eqs. 21-22 have closed forms: for rows ``r`` and columns ``c`` of
:math:`z_b` (counted from 0),

.. math::

    V_i[r, c] = \frac{(v_1 \Delta)^{r-c}}{(r-c)!} \quad (r \ge c),

and for a basis function that is the polynomial :math:`\sum_m a_m \tau^m` in the local time
:math:`\tau \in [0, \Delta)` of the piece,

.. math::

    W_i[r, j] = \sum_m a_{jm} \, v_1^r \, \Delta^{r+m+1} \frac{m!}{(r+m+1)!},

from :math:`\int_0^\Delta (\Delta-\tau)^r \tau^m d\tau = \Delta^{r+m+1} r!\, m! / (r+m+1)!`.
Eqs. 24-25 chain the pieces into ``V`` and ``W`` with :math:`z_b(T) = V z_b(0) + W c_2`.
"""

from __future__ import annotations

from dataclasses import dataclass
from math import factorial
from typing import ClassVar

import numpy as np
import numpy.typing as npt

__all__ = ["ChainedForm", "chained_rhs", "drift_matrix", "piece_transition", "transition"]

Array = npt.NDArray[np.float64]


def chained_rhs(z: Array, v1: float, v2: float) -> Array:
    """Eq. (1): the velocity of the chained form at ``z`` under inputs ``v1``, ``v2``."""
    dz = np.empty_like(z)
    dz[0] = v1
    dz[1] = v2
    dz[2:] = z[1:-1] * v1
    return dz


def drift_matrix(v1: float, dimension: int) -> Array:
    """Eq. (14): the ``(n-1) x (n-1)`` matrix ``A`` with ``v1`` on its first subdiagonal."""
    return np.diag(np.full(dimension - 2, float(v1)), k=-1)


def piece_transition(v1: float, duration: float, dimension: int, basis: Array) -> tuple[Array, Array]:
    """Eqs. (21)-(22): ``V_i`` and ``W_i`` of one piece with constant ``v1``.

    Parameters
    ----------
    v1
        The constant value of ``v1`` on the piece [m/s for the car].
    duration
        The piece length ``Delta_i`` [s].
    dimension
        The chained-form dimension ``n`` (``z_b`` has ``n - 1`` entries).
    basis
        ``(q, D)`` array: row ``j`` holds the coefficients of ``lambda_j`` as a polynomial in
        the local time of the piece, lowest degree first.
    """
    nb = dimension - 1
    V = np.zeros((nb, nb))
    for r in range(nb):
        for c in range(r + 1):
            V[r, c] = (v1 * duration) ** (r - c) / factorial(r - c)
    degrees = basis.shape[1]
    # K[r, m] is the response of row r at the end of the piece to the input tau**m.
    K = np.array(
        [
            [v1**r * duration ** (r + m + 1) * factorial(m) / factorial(r + m + 1) for m in range(degrees)]
            for r in range(nb)
        ]
    )
    return V, K @ basis.T


def transition(v1: Array, durations: Array, dimension: int, bases: Array) -> tuple[Array, Array]:
    """Eqs. (24)-(25): ``V`` and ``W`` over all pieces, ``z_b(T) = V z_b(0) + W c_2``.

    ``v1`` and ``durations`` have one entry per piece; ``bases`` is ``(p, q, D)``, the basis
    polynomials of each piece (see :func:`piece_transition`).
    """
    nb = dimension - 1
    V = np.eye(nb)
    W = np.zeros((nb, bases.shape[1]))
    for v1_i, delta_i, basis_i in zip(v1, durations, bases):
        V_i, W_i = piece_transition(float(v1_i), float(delta_i), dimension, basis_i)
        V = V_i @ V
        W = V_i @ W + W_i
    return V, W


@dataclass(frozen=True)
class ChainedForm:
    """The map of a system that is itself in chained form (eq. 1): the identity, ``v = u``.

    A :class:`~ilc_steering.core.nominal.ChainedMap` like a robot's, so that every task has a map
    and nothing has to ask whether it is there. Its plant is registered as ``chained``.
    """

    dimension: int
    robot: ClassVar[str] = "chained"
    has_pose: ClassVar[bool] = False

    def to_chained(self, q: Array) -> Array:
        """``z = q``."""
        return np.array(q, dtype=np.float64)

    def from_chained(self, z: Array) -> Array:
        """``q = z``."""
        return np.array(z, dtype=np.float64)

    def inputs(self, q: Array, v1: Array | float, v2: Array | float) -> tuple[Array, Array]:
        """``(v1, v2)`` themselves."""
        shape = np.shape(np.asarray(q))[:-1]
        return np.broadcast_to(np.asarray(v1, dtype=np.float64), shape), np.broadcast_to(
            np.asarray(v2, dtype=np.float64), shape
        )

    def outline(self, q: Array) -> list[tuple[Array, bool]]:
        """No outline: a chained system is drawn as a point of the plane ``(z1, zn)``."""
        return []

    def curvature_cost(self, q: Array, dt: Array) -> Array:
        """``int v2^2 dt`` of recorded trials ``q`` ``(B, S, n)`` with steps ``dt`` ``(S - 1,)`` [s], from
        ``z2``'s change: the chained form's stand-in for the energy of bending the path."""
        v2 = np.diff(q[..., 1], axis=1) / dt
        return np.asarray(np.sum(v2**2 * dt, axis=1), dtype=np.float64)
