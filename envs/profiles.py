"""Input profiles: the map from a coefficient vector ``c`` to the inputs ``v1(t)``, ``v2(t)``.

A profile hands the integrator piecewise polynomials (one per piece, in the piece's local time)
and hands the learner the transition matrices ``V`` and ``W`` of its ``v1``. Any profile with
the same methods can replace :class:`PiecewiseProfile`.
"""

from __future__ import annotations

from dataclasses import dataclass
from math import isfinite

import numpy as np
import numpy.typing as npt

from ilc_steering.envs.chained_form import transition

__all__ = ["PiecewiseProfile"]

Array = npt.NDArray[np.float64]


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
        if len(self.durations) == 0:
            raise ValueError("pieces: need at least one piece duration")
        if not all(isfinite(d) and d > 0 for d in self.durations):
            raise ValueError(f"pieces: every duration must be finite and > 0 s, got {list(self.durations)}")
        if len(self.v1_fixed) != len(self.durations) - 1:
            raise ValueError(
                f"v1_fixed: need one value per piece after the first ({len(self.durations) - 1}), "
                f"got {len(self.v1_fixed)}"
            )
        if not all(isfinite(v) for v in self.v1_fixed):
            raise ValueError(f"v1_fixed: values must be finite, got {list(self.v1_fixed)}")
        if self.v2_terms < 1:
            raise ValueError(f"v2_terms: need q >= 1, got {self.v2_terms}")

    @property
    def num_pieces(self) -> int:
        return len(self.durations)

    @property
    def num_coefficients(self) -> int:
        """Length of ``c``: one learned ``v1`` value and ``q`` coefficients of ``v2``."""
        return 1 + self.v2_terms

    @property
    def duration(self) -> float:
        """``T`` [s]."""
        return float(sum(self.durations))

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
        v2 = np.einsum("bj,pjd->bpd", c[:, 1:], self.bases())
        return v1, v2

    def evaluate(self, c: Array, t: Array) -> tuple[Array, Array]:
        """``v1(t)`` and ``v2(t)`` of one coefficient vector at times ``t`` [s] in ``[0, T]``."""
        t = np.asarray(t, dtype=np.float64)
        piece = np.clip(np.searchsorted(self.breakpoints, t, side="right") - 1, 0, self.num_pieces - 1)
        tau = t - self.breakpoints[piece]
        v1 = self.v1_pieces(float(c[0]))[piece]
        powers = tau[..., None] ** np.arange(self.v2_terms)
        v2 = np.einsum("...d,...jd,j->...", powers, self.bases()[piece], c[1:])
        return v1, v2
