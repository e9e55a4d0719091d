r"""Newton steps with the nominal model's Jacobian: the model-based baseline that does not learn.

After a trial with coefficients ``c`` and measured final error :math:`\varepsilon = z^d - z(T)`:

.. math::

    c \leftarrow c + J(c)^{+} \varepsilon, \qquad J(c) = \partial z(T) / \partial c

of the *nominal* model (eqs. 12 and 23): :math:`\partial z_1 / \partial c_{11} = \Delta_1`,
:math:`\partial z_b / \partial c_2 = W(c_{11})`, and :math:`\partial z_b / \partial c_{11}`, the
derivative of :math:`V z_b^0 + W c_2` along ``c11``, by a central difference of the closed forms.
No trial is spent on the Jacobian and nothing is learned about the plant: the step is the
model's alone. Eqs. 33-34 differ in that they invert the nominal model exactly at the next
``c11`` (a secant along ``c11``, where Newton linearizes), with the feedforward of eq. 34.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
import numpy.typing as npt

from ilc_steering.agents.base import LearnerContext
from ilc_steering.core.nominal import NominalModel

__all__ = ["NewtonLearner", "make_newton", "nominal_jacobian"]

Array = npt.NDArray[np.float64]


def nominal_jacobian(model: NominalModel, c: Array) -> Array:
    """``d z(T) / d c`` of the nominal model at coefficients ``c``, ``(n, 1 + q)``."""
    n = model.dimension
    jacobian = np.zeros((n, c.size))
    jacobian[0, 0] = model.profile.learned_area
    h = 1e-6 * max(1.0, abs(float(c[0])))
    z0b = model.z_start[1:]
    (V_plus, W_plus), (V_minus, W_minus) = model.transition(c[0] + h), model.transition(c[0] - h)
    jacobian[1:, 0] = ((V_plus - V_minus) @ z0b + (W_plus - W_minus) @ c[1:]) / (2 * h)
    jacobian[1:, 1:] = model.transition(c[0])[1]
    return jacobian


class NewtonLearner:
    """Newton steps ``c += J(c)^+ error`` with the nominal model's Jacobian, from ``start``."""

    def __init__(self, model: NominalModel, start: Array) -> None:
        self.model = model
        self.start = np.array(start, dtype=np.float64)
        self.reset()

    def reset(self) -> None:
        self._c = self.start.copy()

    def act(self, observation: Any = None) -> Array:
        return self._c.copy()

    def learn(self, info: Mapping[str, Any]) -> None:
        c = np.asarray(info["action"], dtype=np.float64)
        error = np.asarray(info["error"], dtype=np.float64)
        self._c = c + np.linalg.lstsq(nominal_jacobian(self.model, c), error, rcond=None)[0]


def make_newton(context: LearnerContext) -> NewtonLearner:
    """``compare`` method ``newton``, from the context's first trial."""
    return NewtonLearner(context.model, context.first_action())
