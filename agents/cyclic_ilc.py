r"""The cyclic learning controller of section 6 (eqs. 38-41), applied to the chained form.

Derivation. Segment ``l`` runs from the *measured* state :math:`z_{l-1}` (never reset) to
waypoint :math:`z^d_l`. For the linear system of eq. 18 the paper splits the coefficients into a
learned term and a feedforward that cancels the start (eq. 39),
:math:`c_l = \hat c_l - \tilde W_l^{-1} \tilde V_l x_{l-1}`, so that :math:`x_l = \tilde W_l \hat c_l`
(eq. 41), and learns :math:`\hat c_l \leftarrow \hat c_l + \nu \tilde W_l^{-1} \varepsilon_l` (eq. 40 with
:math:`F_l = \nu W_l^{-1}`).

For the chained form two things differ, as in section 3.2. First, ``z_1`` is the integrator of
eq. 12, :math:`z_{a,l} = z_{a,l-1} + c_{11}\Delta_1 + \sum_{i \ge 2} c_{1i}\Delta_i`. Second,
:math:`V_l` and :math:`W_l` depend on ``v1``, hence on ``c11``, which now changes from cycle to cycle
with the measured start. A learned coefficient :math:`\hat c_l` would meet a different :math:`W_l`
every cycle. So the learned term is kept in state space: :math:`\hat y_l = W_l \hat c_l`, the end
state the segment reaches nominally. Then

.. math::

    c_{11} &= (\hat y_{a,l} - z_{a,l-1} - \textstyle\sum_{i \ge 2} c_{1i}\Delta_i) / \Delta_1, \\
    c_{2} &= W_l(c_{11})^{-1}\,\big(\hat y_{b,l} - V_l(c_{11})\, z_{b,l-1}\big),

the chained-form eq. 39: on the nominal system :math:`z_l = \hat y_l` whatever the start and
whatever ``c11``. This is the same cancellation as the feedforward of eq. 34. The learning law
(eq. 40) becomes

.. math::

    \hat y_{a,l} \leftarrow \hat y_{a,l} + \nu_a \varepsilon_{a,l}, \qquad
    \hat y_{b,l} \leftarrow \hat y_{b,l} + \nu_b \varepsilon_{b,l},

so :math:`\varepsilon_l^{[k+1]} = z^d_l - \hat y_l^{[k+1]} = (1 - \nu)\,\varepsilon_l^{[k]}` at every
waypoint, whatever the start: eq. 41's error dynamics, decoupled between the segments and
between ``z_a`` and ``z_b``.

Start, by the zero iteration of section 4: a fictitious cycle with null inputs ends every segment
where it began, so :math:`\hat y_l^{[0]} = z^d_{l-1}` and
:math:`\hat y_l^{[1]} = z^d_{l-1} + \nu (z^d_l - z^d_{l-1})`.
With :math:`\nu = 1`, the first cycle is the nominal open-loop solution from each measured start.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import numpy.typing as npt

from ilc_steering.core.checks import check_gains
from ilc_steering.core.nominal import NominalModel
from ilc_steering.errors import BadInput

__all__ = ["CyclicILCAgent"]

Array = npt.NDArray[np.float64]


class CyclicILCAgent:
    """Cyclic iterative learning control (eqs. 39-40) on the nominal chained form.

    Parameters
    ----------
    models
        One nominal model per segment, e.g. ``env.unwrapped.nominal_models``.
    nu_a, nu_b
        Gains in ``(0, 2)`` on the ``z1`` and ``z_b`` waypoint errors; each contracts by
        ``1 - nu`` per cycle on the nominal system.

    The loop is ``action = agent.act(observation)`` (the measured start and the segment index,
    as ``CyclicSteeringEnv`` observes them), run the segment, ``agent.learn(info)``.
    """

    def __init__(self, models: Sequence[NominalModel], nu_a: float = 1.0, nu_b: float = 1.0) -> None:
        check_gains(nu_a, nu_b)
        if len(models) < 2:
            raise BadInput(f"a cycle needs at least 2 segments, got {len(models)}")
        self.models = list(models)
        self.nu = np.array([nu_a] + [nu_b] * (self.models[0].dimension - 1))
        self.reset()

    def reset(self) -> None:
        """Back to the zero iteration: every segment aims at ``nu`` of the way to its waypoint."""
        self._targets = [m.z_start + self.nu * (m.z_goal - m.z_start) for m in self.models]

    def act(self, observation: Array) -> Array:
        """The coefficients for the segment in ``observation`` from the start measured there (eq. 39)."""
        n = self.models[0].dimension
        observation = np.asarray(observation, dtype=np.float64)
        if observation.shape != (n + len(self.models),):
            raise BadInput(f"observation must have shape {(n + len(self.models),)}, got {observation.shape}")
        segment = int(np.argmax(observation[n:]))
        # Eq. 39 is the nominal open-loop solution from the measured start to the learned target.
        return self.models[segment].solve(z_start=observation[:n], z_goal=self._targets[segment])

    def learn(self, info: Mapping[str, Any]) -> None:
        """Eq. (40) in state space: move the segment's target by ``nu`` times its waypoint error."""
        segment = int(info["segment"])
        self._targets[segment] = self._targets[segment] + self.nu * np.asarray(info["waypoint_error"], dtype=np.float64)
