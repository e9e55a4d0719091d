r"""Section 5's input profile: ``v1`` a succession of trapezoids, so the wheel speed is continuous.

On piece ``i`` of duration :math:`\Delta_i`, ``v1`` ramps linearly from 0 to its plateau
:math:`\bar v_i` over the fixed ramp time ``r``, holds it, and ramps back to 0 over the last ``r``
(``r < Delta_i / 2``). The first plateau is the learned coefficient ``c11``, the others are fixed
(``v1_fixed``); ``v2`` is as in eqs. 15-17, polynomials in the piece's local time. The area of a
piece is :math:`\bar v_i (\Delta_i - r)`, so eq. 12 holds with ``learned_area = Delta_1 - r``.

**V and W exactly.** With :math:`A(t) = v_1(t) N` (eq. 14, ``N`` the fixed shift with ones on
its subdiagonal), ``A`` commutes with itself at all times, so the transition matrix is

.. math::

    \Phi(t, s) = \exp\big(N (S(t) - S(s))\big) = \sum_{k=0}^{n-2} \frac{(S(t) - S(s))^k}{k!} N^k,
    \qquad S(t) = \int_0^t v_1,

a polynomial in the integral because ``N`` is nilpotent. Each piece splits into three *spans*
(ramp up, plateau, ramp down) on which :math:`S` is a polynomial of degree 2, 1 and 2 in the
span's local time :math:`\tau`: :math:`\bar v \tau^2 / 2r`, :math:`\bar v \tau` and
:math:`\bar v (\tau - \tau^2 / 2r)`. On a span of area :math:`a` and length :math:`d`,

.. math::

    V_s = \exp(N a), \qquad W_s[k, j] = \int_0^d \frac{(a - S_s(\tau))^k}{k!} \lambda_j(\tau) \, d\tau,

since :math:`N^k e_1 = e_{k+1}` and ``v2`` drives :math:`z_2`, the first entry of :math:`z_b`.
The integrand is a polynomial of degree at most :math:`2(n-2) + q - 1`, which Gauss-Legendre
quadrature with :math:`n - 1 + \lceil q/2 \rceil` nodes integrates exactly (to rounding).
The spans chain as eqs. 24-25 do: :math:`V \leftarrow V_s V`, :math:`W \leftarrow V_s W + W_s`.
``tests/test_trapezoid.py`` checks V and W against adaptive quadrature of the linear system, and
the learning law's contraction by exactly :math:`1 - \nu_b` (eq. 36) on the chained plant.
"""

from __future__ import annotations

from dataclasses import dataclass
from math import comb, factorial, isfinite

import numpy as np
import numpy.typing as npt

from ilc_steering.core.checks import require
from ilc_steering.core.profiles import PiecewiseProfile

__all__ = ["TrapezoidProfile"]

Array = npt.NDArray[np.float64]


@dataclass(frozen=True)
class TrapezoidProfile(PiecewiseProfile):
    """Section 5: trapezoidal ``v1`` (ramps of ``ramp`` s at both ends of every piece), ``v2`` as in
    eqs. 15-17. Parameters as :class:`~ilc_steering.core.profiles.PiecewiseProfile`, plus ``ramp`` [s];
    what is not redefined here (the pieces, their count, the coefficients) is the same."""

    ramp: float

    def __post_init__(self) -> None:
        super().__post_init__()
        shortest = min(self.durations)
        require(
            isfinite(self.ramp) and 0 < self.ramp < shortest / 2,
            "ramp",
            f"must be > 0 s and less than half the shortest piece ({shortest / 2:g} s), got {self.ramp}",
        )

    @property
    def spans(self) -> tuple[float, ...]:
        """Ramp up, plateau and ramp down of each piece."""
        r = self.ramp
        return tuple(d for delta in self.durations for d in (r, delta - 2 * r, r))

    @property
    def breakpoints(self) -> Array:
        return np.concatenate([[0.0], np.cumsum(self.spans)])

    @property
    def learned_area(self) -> float:
        """``Delta_1 - ramp`` [s]: the area of the first trapezoid per unit of its plateau."""
        return self.durations[0] - self.ramp

    @property
    def fixed_displacement(self) -> float:
        return float(sum(v * (d - self.ramp) for v, d in zip(self.v1_fixed, self.durations[1:])))

    def _offsets(self) -> Array:
        """The start of each span in its piece's local time [s]."""
        r = self.ramp
        return np.array([o for delta in self.durations for o in (0.0, r, delta - r)])

    def bases(self) -> Array:
        """``(3p, q, q)``: ``lambda_j(tau + o) = sum_d C(j, d) o**(j-d) tau**d`` on a span starting at ``o``."""
        q = self.v2_terms
        out = np.zeros((3 * self.num_pieces, q, q))
        for s, offset in enumerate(self._offsets()):
            for j in range(q):
                for d in range(j + 1):
                    out[s, j, d] = comb(j, d) * offset ** (j - d)
        return out

    def _v1_spans(self, plateaus: Array) -> Array:
        """``(..., 3p, 2)``: ``v1`` on each span as ``a + b tau``."""
        level = np.repeat(plateaus, 3, axis=-1)
        slope = np.tile([1.0, 0.0, -1.0], self.num_pieces) / self.ramp
        start = np.tile([0.0, 1.0, 1.0], self.num_pieces)
        return np.stack([level * start, level * slope], axis=-1)

    def transition(self, c11: float, dimension: int) -> tuple[Array, Array]:
        """``V`` and ``W`` of ``z_b`` exactly (see the module docstring)."""
        nb, q = dimension - 1, self.v2_terms
        nodes, weights = np.polynomial.legendre.leggauss(nb + (q + 1) // 2)
        V, W = np.eye(nb), np.zeros((nb, q))
        v1 = self._v1_spans(self.v1_pieces(float(c11)))
        bases = self.bases()
        powers = np.arange(nb)
        for (a0, a1), d, basis in zip(v1, self.spans, bases):
            area = a0 * d + a1 * d * d / 2
            V_s = np.zeros((nb, nb))
            for k in range(nb):
                V_s += np.diag(np.full(nb - k, area**k / factorial(k)), -k)
            tau = 0.5 * d * (nodes + 1)
            remaining = area - (a0 * tau + a1 * tau * tau / 2)  # (a - S_s(tau)) at the nodes
            rows = remaining[None, :] ** powers[:, None] / np.array([factorial(k) for k in powers])[:, None]
            columns = basis @ tau[None, :] ** np.arange(q)[:, None]  # lambda_j at the nodes
            W_s = (rows * (0.5 * d * weights)) @ columns.T
            V, W = V_s @ V, V_s @ W + W_s
        return V, W

    def polynomials(self, c: Array) -> tuple[Array, Array]:
        batch = c.shape[0]
        plateaus = np.empty((batch, self.num_pieces))
        plateaus[:, 0] = c[:, 0]
        plateaus[:, 1:] = self.v1_fixed
        v2 = np.einsum("bj,sjd->bsd", c[:, 1:], self.bases())
        return np.ascontiguousarray(self._v1_spans(plateaus)), v2

    def evaluate(self, c: Array, t: Array) -> tuple[Array, Array]:
        t = np.asarray(t, dtype=np.float64)
        span = np.clip(np.searchsorted(self.breakpoints, t, side="right") - 1, 0, 3 * self.num_pieces - 1)
        tau = t - self.breakpoints[span]
        v1_spans = self._v1_spans(self.v1_pieces(float(c[0])))
        v1 = v1_spans[span, 0] + v1_spans[span, 1] * tau
        powers = tau[..., None] ** np.arange(self.v2_terms)
        v2 = np.einsum("...d,...jd,j->...", powers, self.bases()[span], c[1:])
        return v1, v2
