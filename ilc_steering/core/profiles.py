"""Input profiles: the map from a coefficient vector ``c`` to the inputs ``v1(t)``, ``v2(t)``.

A profile hands the integrator piecewise polynomials (one per *span*, in the span's local time,
with no jump or kink of the inputs inside a span) and hands the learner what eqs. 12 and 23-25
need: how ``z1`` moves with the learned coefficient ``c11``, and the transition matrices ``V``
and ``W`` of its ``v1``. :class:`InputProfile` is that contract; :class:`PiecewiseProfile` is the
paper's profile of eqs. 15-17, and ``tests/test_protocols.py`` checks any implementation.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from math import isfinite
from typing import Protocol, runtime_checkable

import numpy as np
import numpy.typing as npt

from ilc_steering.core.chained_form import transition
from ilc_steering.core.checks import DURATION_RANGE, require

__all__ = ["MAX_V2_TERMS", "InputProfile", "PiecewiseProfile"]

MAX_V2_TERMS = 12
"""The most coefficients of ``v2``: the monomial basis ``tau**(j-1)`` is ill-conditioned well before."""

Array = npt.NDArray[np.float64]


@runtime_checkable
class InputProfile(Protocol):
    """What a parameterization of ``v1``, ``v2`` by ``c = (c11, c21..c2q)`` provides.

    ``c11`` is the one learned coefficient of ``v1`` (eq. 33 acts on it); the rest of ``v1`` is
    fixed. ``c2 = (c21..c2q)`` enters ``v2`` linearly (eq. 34 acts on it). The contract, checked by
    ``tests/test_protocols.py``:

    - ``z1(T) - z1(0) = learned_area * c11 + fixed_displacement`` (eq. 12);
    - ``transition(c11, n)`` gives ``V`` and ``W`` with ``z_b(T) = V z_b(0) + W c2`` (eqs. 24-25);
    - ``polynomials(c)`` and ``evaluate(c, t)`` describe the same inputs, the former as
      polynomials on the ``spans`` that the integrator steps through.
    """

    @property
    def durations(self) -> tuple[float, ...]:
        """The pieces ``Delta_1..Delta_p`` [s] of the profile; ``T`` is their sum."""
        ...

    @property
    def v1_fixed(self) -> tuple[float, ...]:
        """``c12..c1p``: the fixed level of ``v1`` on pieces ``2..p``."""
        ...

    @property
    def v2_terms(self) -> int:
        """``q``, the number of coefficients of ``v2``."""
        ...

    @property
    def num_coefficients(self) -> int:
        """Length of ``c``."""
        ...

    @property
    def spans(self) -> tuple[float, ...]:
        """Durations [s] of the polynomial spans, in order; they add up to ``T``."""
        ...

    @property
    def breakpoints(self) -> Array:
        """``0, t_1, ..., T`` [s]: the ends of the spans."""
        ...

    @property
    def learned_area(self) -> float:
        """``d z1(T) / d c11`` [s]: the area of ``v1`` per unit of the learned coefficient."""
        ...

    @property
    def fixed_displacement(self) -> float:
        """The change of ``z1`` over the trial due to the fixed part of ``v1``."""
        ...

    def transition(self, c11: float, dimension: int) -> tuple[Array, Array]:
        """Eqs. (24)-(25): ``V`` and ``W`` of ``z_b`` with learned coefficient ``c11``."""
        ...

    def polynomials(self, c: Array) -> tuple[Array, Array]:
        """``v1`` ``(B, S, D1)`` and ``v2`` ``(B, S, D2)`` of a batch ``c`` ``(B, 1 + q)`` on the ``S``
        spans, coefficients lowest degree first in the span's local time."""
        ...

    def evaluate(self, c: Array, t: Array) -> tuple[Array, Array]:
        """``v1(t)`` and ``v2(t)`` of one coefficient vector at times ``t`` [s] in ``[0, T]``."""
        ...


@dataclass(frozen=True)
class PiecewiseProfile:
    """Eqs. (15)-(17): ``v1`` constant on each of ``p`` pieces, ``v2 = sum_j c2j lambda_j(t)``.

    The coefficient vector is ``c = (c11, c21, ..., c2q)``: ``c11`` is ``v1`` on the first
    piece [m/s for the car]; ``v1`` on pieces ``2..p`` is fixed to ``v1_fixed`` and never
    learned (eq. 17). The basis is ``lambda_j(t) = (t - t_{i-1})**(j-1)`` on piece ``i``,
    restarting at each piece as in the paper's simulations.

    Parameters
    ----------
    durations
        ``Delta_1..Delta_p`` [s]; the trial lasts ``T = sum(durations)``.
    v1_fixed
        ``c12..c1p``, the value of ``v1`` on pieces ``2..p``.
    v2_terms
        ``q``, the number of basis functions of ``v2``.
    """

    durations: tuple[float, ...]
    v1_fixed: tuple[float, ...]
    v2_terms: int

    def __post_init__(self) -> None:
        durations, fixed = list(self.durations), list(self.v1_fixed)
        low, high = DURATION_RANGE
        require(
            len(durations) >= 1 and all(isfinite(d) and low <= d <= high for d in durations),
            "pieces",
            f"durations must be in [{low:g}, {high:g}] s, got {durations}",
        )
        require(
            len(fixed) == len(durations) - 1,
            "v1_fixed",
            f"needs one value per piece after the first ({len(durations) - 1}), got {len(fixed)}",
        )
        require(all(isfinite(v) for v in fixed), "v1_fixed", f"values must be finite, got {fixed}")
        require(1 <= self.v2_terms <= MAX_V2_TERMS, "v2_terms", f"needs 1 <= q <= {MAX_V2_TERMS}, got {self.v2_terms}")

    @property
    def num_pieces(self) -> int:
        return len(self.durations)

    @property
    def num_coefficients(self) -> int:
        """Length of ``c``: one learned ``v1`` value and ``q`` coefficients of ``v2``."""
        return 1 + self.v2_terms

    @property
    def spans(self) -> tuple[float, ...]:
        """The pieces themselves: ``v1`` and ``v2`` are polynomials on each."""
        return self.durations

    @property
    def learned_area(self) -> float:
        """``Delta_1`` [s]: ``c11`` is held over the first piece (eq. 17)."""
        return self.durations[0]

    @property
    def fixed_displacement(self) -> float:
        """``sum_{i >= 2} c1i Delta_i`` (eq. 12)."""
        return float(np.dot(self.v1_fixed, self.durations[1:]))

    @property
    def breakpoints(self) -> Array:
        """``t_0 = 0, t_1, ..., t_p = T`` [s]."""
        return np.concatenate([[0.0], np.cumsum(self.durations)])

    def bases(self) -> Array:
        """``(p, q, q)``: the basis polynomials of each piece; identity, since ``lambda_j = tau**(j-1)``."""
        return np.broadcast_to(np.eye(self.v2_terms), (self.num_pieces, self.v2_terms, self.v2_terms))

    def v1_pieces(self, c11: float) -> Array:
        """Eq. (17): the value of ``v1`` on each piece."""
        return np.array([c11, *self.v1_fixed], dtype=np.float64)

    def transition(self, c11: float, dimension: int) -> tuple[Array, Array]:
        """Eqs. (24)-(25): ``V`` and ``W`` of ``z_b`` for this profile with learned ``c11``."""
        durations = np.asarray(self.durations, dtype=np.float64)
        return transition(self.v1_pieces(c11), durations, dimension, self.bases())

    def polynomials(self, c: Array) -> tuple[Array, Array]:
        """The inputs of a batch of trials as piecewise polynomials in local time.

        ``c`` is ``(B, 1 + q)``. Returns ``v1`` of shape ``(B, p, 1)`` and ``v2`` of shape
        ``(B, p, q)``, lowest degree first.
        """
        batch = c.shape[0]
        v1 = np.empty((batch, self.num_pieces, 1))
        v1[:, 0, 0] = c[:, 0]
        v1[:, 1:, 0] = self.v1_fixed
        shape, matrix = self._v2_matrix
        v2 = (c[:, 1:] @ matrix).reshape(batch, *shape)
        return v1, v2

    @cached_property
    def _v2_matrix(self) -> tuple[tuple[int, ...], Array]:
        """The bases as one matrix ``(q, p * D)`` that maps ``c2`` onto every piece's ``v2`` coefficients,
        and the shape ``(p, D)`` of those: the same for every trial, so built once."""
        bases = self.bases()  # (p, q, D): piece, coefficient, degree
        matrix = np.ascontiguousarray(bases.transpose(1, 0, 2).reshape(bases.shape[1], -1))
        matrix.flags.writeable = False  # shared by every trial, a user's plant's included: nobody writes it
        return bases[:, 0].shape, matrix

    def evaluate(self, c: Array, t: Array) -> tuple[Array, Array]:
        """``v1(t)`` and ``v2(t)`` of one coefficient vector at times ``t`` [s] in ``[0, T]``."""
        t = np.asarray(t, dtype=np.float64)
        piece = np.clip(np.searchsorted(self.breakpoints, t, side="right") - 1, 0, self.num_pieces - 1)
        tau = t - self.breakpoints[piece]
        v1 = self.v1_pieces(float(c[0]))[piece]
        powers = tau[..., None] ** np.arange(self.v2_terms)
        v2 = np.einsum("...d,...jd,j->...", powers, self.bases()[piece], c[1:])
        return v1, v2
