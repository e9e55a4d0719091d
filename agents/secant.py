"""What the trials teach about a refit model beyond its family: the secant corrections.

``robust_ilc`` corrects its refit model :math:`F` near an anchor trial :math:`c_a` by a gain per
chained coordinate and a Jacobian correction, fitted to the anchor and the trials beside it
(:class:`Secant`, :func:`fit_secant`, :func:`secant_about`; the derivation is in ``docs/learners.md``,
``robust_ilc``'s step 2); ``newton_ilc`` keeps a Broyden Jacobian of its offset
(:func:`broyden_update`). Both see only the refit model and the measured trials.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from ilc_steering.agents.trial import Trial, final_chained
from ilc_steering.core.family import ModelFamily
from ilc_steering.core.nominal import NominalModel

__all__ = [
    "GAIN_PRIOR",
    "MAX_GAIN",
    "SECANT_CURVATURE",
    "SECANT_PRIOR",
    "SECANT_SCATTER",
    "SECANT_TRIALS",
    "Secant",
    "broyden_update",
    "chained_scatter",
    "fit_secant",
    "secant_about",
]

Array = npt.NDArray[np.float64]

SECANT_TRIALS = 6
"""The trials beside the anchor that the secant correction is fitted to."""
SECANT_SCATTER = (2e-3, 4e-3)
"""[m, rad] the scatter of a measured final configuration the secant assumes: a pose's x and y, its
angles (for a robot without a pose, the first for every coordinate)."""
SECANT_CURVATURE = 0.2
"""[chained units per action scale squared] a step's linearization error over its length squared (1.0
before: the simulated lab robot's first trials, 270 and 160 mm off, then taught the secant too little;
its fifth trial is within the tolerance on 18 of seeds 0-19 from 0.15 to 0.2, 17 at 0.25, 12 at 0.3)."""
SECANT_PRIOR = 1.0
"""[chained units per action scale] the prior size of an entry of the Jacobian's correction ``D`` (3.0
before: where the first trials' steps say little, the refit model's Jacobian is kept; with these two
and ``solver.SHRINK`` the lab robot's fifth trial lands 3 mm off, median of seeds 0-19, not 10)."""
GAIN_PRIOR = 1.0
"""The prior size of ``A - 1``, the correction of the refit model's gain per chained coordinate."""
MAX_GAIN = 4.0
"""The gains ``A`` stay within this factor of 1."""


@dataclass(frozen=True)
class Secant:
    """What the trials teach about the refit model ``F`` near a trial ``c_a``: the measured outcome
    is ``z_a + A * (F(c) - F(c_a)) + D (c - c_a)``, ``A`` a gain per chained coordinate, ``D`` a
    correction of the Jacobian, ``z_a`` the anchor's outcome as the fit smooths it (None: as
    measured)."""

    A: Array
    D: Array
    z: Array | None = None

    @staticmethod
    def none(n: int, p: int, z: Array | None = None) -> Secant:
        """No correction (``n`` chained coordinates, ``p`` coefficients)."""
        return Secant(np.ones(n), np.zeros((n, p)), z)

    def part(self, s: float) -> Secant:
        """The fraction ``s`` of the correction (the homotopy's)."""
        return Secant(1.0 + s * (self.A - 1.0), s * self.D, self.z)


def fit_secant(F: Array, z: Array, S: Array, sigma: Array) -> Secant:
    """The :class:`Secant` about trial 0 from trials ``(m,)``: the refit model's outcomes ``F`` and
    the measured ones ``z`` ``(m, n)``, the steps ``S`` ``(m, p)`` from trial 0 (in action scales,
    ``S[0] = 0``) and the assumed scatter ``sigma`` ``(n,)`` of each chained coordinate. ``D`` is in
    chained units per action scale.

    Per chained coordinate ``j``, a weighted ridge regression of what the model leaves,
    ``z - F = b + (A - 1) (F - F_0) + D s``: ``b`` free (it smooths the anchor's scatter: every
    trial near it counts), ``A - 1`` and ``D`` pulled to 0 by :data:`GAIN_PRIOR` and
    :data:`SECANT_PRIOR`. A trial's equation has the scatter's error and the linearization's,
    which grows as the step's square: weight ``1 / sqrt(sigma^2 + (SECANT_CURVATURE |s|^2)^2)``, so
    the near trials set the Jacobian the next step needs and steps within the scatter set nothing.
    """
    m, n = F.shape
    p = S.shape[1]
    curvature = SECANT_CURVATURE * np.sum(S**2, axis=1)
    weights = 1.0 / np.hypot(sigma[None, :], curvature[:, None])  # (m, n)
    prior = np.diag([0.0, GAIN_PRIOR**-2, *([SECANT_PRIOR**-2] * p)])
    A, D, b = np.ones(n), np.zeros((n, p)), np.zeros(n)
    for j in range(n):
        X = np.column_stack([np.ones(m), F[:, j] - F[0, j], S]) * weights[:, j : j + 1]
        beta = np.linalg.solve(X.T @ X + prior, X.T @ ((z[:, j] - F[:, j]) * weights[:, j]))
        b[j], A[j], D[j] = beta[0], 1.0 + beta[1], beta[2:]
    return Secant(np.clip(A, 1.0 / MAX_GAIN, MAX_GAIN), D, F[0] + b)


def secant_about(
    anchor: Trial, trials: list[Trial], family: ModelFamily, theta: Array, scale: Array, sigma: Array
) -> Secant:
    """The secant correction of the refit model ``theta`` of ``family`` about ``anchor`` (:func:`fit_secant`)
    from the anchor and the last :data:`SECANT_TRIALS` other in-chart trials of ``trials``; ``scale`` is the
    action scale of each coefficient [its units], ``sigma`` the assumed scatter (:func:`chained_scatter`)."""
    n, p = family.model.dimension, scale.size
    others = [t for t in trials[-SECANT_TRIALS - 1 :] if t.ok and t is not anchor][-SECANT_TRIALS:]
    if not anchor.ok:
        return Secant.none(n, p)
    c = np.array([anchor.c, *[t.c for t in others]])
    F, ok = final_chained(family, np.tile(theta, (c.shape[0], 1)), c)
    if not np.all(ok):
        return Secant.none(n, p, anchor.z)
    found = fit_secant(F, np.array([anchor.z, *[t.z for t in others]]), (c - c[0]) / scale, sigma)
    return Secant(found.A, found.D / scale, found.z)


def chained_scatter(family: ModelFamily, goal_q: Array, model: NominalModel) -> Array:
    """[chained units] the scatter of each chained coordinate that :func:`fit_secant` assumes:
    :data:`SECANT_SCATTER` of the configuration through the nominal map's Jacobian at the goal."""
    h = 1e-7
    z0 = family.to_chained(goal_q)
    J = np.array([(family.to_chained(goal_q + h * e) - z0) / h for e in np.eye(goal_q.size)]).T
    if getattr(model.chained_map, "has_pose", False):
        sigma_q = np.array([SECANT_SCATTER[0] if k < 2 else SECANT_SCATTER[1] for k in range(goal_q.size)])
    else:
        sigma_q = np.full(goal_q.size, SECANT_SCATTER[0])
    return np.asarray(np.sqrt((J**2) @ sigma_q**2))


def broyden_update(D: Array, s: Array, r: Array) -> None:
    """Broyden's rank-one update of the secant ``D`` in place: after a step ``s`` that changed the
    residual by ``r``, ``D <- D + (r - D s) s^T / s^T s`` (the least change with ``D s = r``)."""
    D += np.outer(r - D @ s, s) / (s @ s)
