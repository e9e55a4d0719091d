r"""The iterative learning controller of section 3.2 (eqs. 33-34).

After trial ``k`` with coefficients ``c^[k] = (c11, c2)`` and final error
:math:`\varepsilon^{[k]} = z^d - z^{[k]}(T) = (\varepsilon_a, \varepsilon_b)`:

.. math::

    c_{11}^{[k+1]} &= c_{11}^{[k]} + \nu_a \varepsilon_a^{[k]} / \Delta_1 && (33) \\
    c_2^{[k+1]} &= c_2^{[k]} + (W^{[k+1]})^{-1}\big[\nu_b \varepsilon_b^{[k]}
        - \Delta V^{[k+1]} z_b^0 - \Delta W^{[k+1]} c_2^{[k]}\big] && (34)

where ``V`` and ``W`` (eqs. 24-25) are built from ``v1`` of each trial. The last two terms of
eq. 34 are the feedforward that cancels the change of ``v1`` between trials, so that on the
nominal system :math:`\varepsilon_b^{[k+1]} = (1 - \nu_b)\varepsilon_b^{[k]}` (eq. 36).

By default the first trial follows the fictitious zero iteration of section 4: ``c1`` and ``c2``
entirely null (the fixed pieces of ``v1`` included), so that its error is ``z^d - z^0`` and its
``V`` is the identity. For a task with a fixed ``v1`` piece the first real trial then drives only
that piece, which is what makes the paper's parallel parking take five iterations. Given a
``start`` (the nominal solution ``model.solve()``, say), the first trial applies it instead.

The inverse of ``W`` is the Moore-Penrose pseudo-inverse. It is the inverse when ``W`` is square
and regular; it also covers ``q > n - 1`` coefficients, and the singular ``W`` of a symmetric
forward/backward ``v1`` (the paper's parallel parking converges to ``v1 = (0.24, -0.24)``, where
the restarting basis makes two columns of ``W`` proportional). There the reachable part of the
error is corrected, which for that task is all of it.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Protocol

import numpy as np
import numpy.typing as npt

from ilc_steering.agents.base import LearnerContext
from ilc_steering.core.checks import check_gains
from ilc_steering.core.nominal import NominalModel
from ilc_steering.errors import BadInput

__all__ = ["CostStep", "ILCAgent", "make_ilc", "make_ilc_paper"]

Array = npt.NDArray[np.float64]


class CostStep(Protocol):
    """A descent step of a cost that keeps ``W c2`` (``agents/costs.py``)."""

    def step(self, c: Array, W: Array) -> Array: ...


class ILCAgent:
    """Iterative learning control on the nominal chained form (eqs. 33-34).

    Parameters
    ----------
    model
        The nominal model, e.g. ``env.unwrapped.nominal_model``. The agent never sees the plant.
    nu_a
        Gain of eq. 33 on the ``z1`` error, in ``(0, 2)``.
    nu_b
        Gain of eq. 34 on the ``z_b`` error, in ``(0, 2)``; the nominal error contracts by
        ``1 - nu_b`` per trial.

    start
        The first trial's coefficients; ``None`` (the default) for the paper's fictitious zero
        iteration.
    cost
        Section 7's cost descent (:class:`~ilc_steering.agents.costs.NullSpaceCost`), applied after
        every update within the null space of ``W``, so that the error dynamics are eq. 36's; ``None``
        for none.

    The loop is ``action = agent.act()``, run the trial, ``agent.learn(info)``; ``reset()``
    restarts learning from the first trial.
    """

    def __init__(
        self,
        model: NominalModel,
        nu_a: float = 1.0,
        nu_b: float = 1.0,
        start: Array | None = None,
        cost: CostStep | None = None,
    ) -> None:
        check_gains(nu_a, nu_b)
        self.model = model
        self.cost = cost
        self.nu_a = float(nu_a)
        self.nu_b = float(nu_b)
        self.start = None if start is None else np.array(start, dtype=np.float64)
        if self.start is not None and self.start.shape != (model.profile.num_coefficients,):
            raise BadInput(f"start must have shape ({model.profile.num_coefficients},), got {self.start.shape}")
        self.reset()

    def reset(self) -> None:
        """Back to the first trial: ``start``, or the eq. 33-34 update of the fictitious zero iteration."""
        if self.start is not None:
            self._action = self.start.copy()
            return
        n, q = self.model.dimension, self.model.profile.v2_terms
        c11 = self.nu_a * (self.model.z_goal[0] - self.model.z_start[0]) / self.model.profile.learned_area
        error_b = self.model.z_goal[1:] - self.model.z_start[1:]
        c2 = self._update_c2(c11, np.eye(n - 1), np.zeros((n - 1, q)), np.zeros(q), error_b)
        self._action = np.concatenate([[c11], c2])

    def act(self, observation: Any = None) -> Array:
        """The coefficients ``c = (c11, c21..c2q)`` for the next trial."""
        return self._action.copy()

    def learn(self, info: Mapping[str, Any]) -> None:
        """Update from a finished trial's ``info``: its ``error`` and the ``action`` applied."""
        c = np.asarray(info.get("action", self._action), dtype=np.float64)
        error = np.asarray(info["error"], dtype=np.float64)
        c11 = c[0] + self.nu_a * error[0] / self.model.profile.learned_area  # eq. 33
        V, W = self.model.transition(c[0])
        self._action = np.concatenate([[c11], self._update_c2(c11, V, W, c[1:], error[1:])])
        if self.cost is not None:  # section 7: descend the cost within the null space of the next W
            self._action = self.cost.step(self._action, self.model.transition(c11)[1])

    def _update_c2(self, c11: float, V: Array, W: Array, c2: Array, error_b: Array) -> Array:
        """Eq. (34), given ``V`` and ``W`` of the finished trial and the next ``c11``."""
        V_next, W_next = self.model.transition(c11)
        rhs = self.nu_b * error_b - (V_next - V) @ self.model.z_start[1:] - (W_next - W) @ c2
        return c2 + np.linalg.lstsq(W_next, rhs, rcond=None)[0]


def make_ilc(context: LearnerContext) -> ILCAgent:
    """Eqs. 33-34 with the config's gains from the context's first trial (``compare`` method
    ``ilc``: under ``prior="nominal"`` the nominal solution). The config's cost is attached by
    :func:`ilc_steering.agents.costs.with_cost`."""
    return ILCAgent(context.model, context.nu_a, context.nu_b, start=context.first_action())


def make_ilc_paper(context: LearnerContext) -> ILCAgent:
    """The paper's learner exactly, fictitious zero iteration included, whatever the prior
    (``compare`` method ``ilc_paper``; ``run``'s ``ilc``)."""
    return ILCAgent(context.model, context.nu_a, context.nu_b)
