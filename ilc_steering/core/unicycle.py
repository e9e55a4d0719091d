r"""The unicycle (a differential-drive robot) and its chained form, ``n = 3``.

Configuration ``q = (x, y, theta)``: the axle midpoint [m] and the heading [rad]. Inputs: the
forward speed ``v`` [m/s] and the turn rate ``omega`` [rad/s],

.. math::

    \dot x = v \cos\theta, \quad \dot y = v \sin\theta, \quad \dot\theta = \omega.

The change of coordinates :math:`z = \alpha(q) = (x, \tan\theta, y)` and the input transformation

.. math::

    v = \frac{v_1}{\cos\theta}, \qquad \omega = v_2 \cos^2\theta

give :math:`\dot z_1 = v_1`, :math:`\dot z_2 = \dot\theta / \cos^2\theta = v_2` and
:math:`\dot z_3 = v \sin\theta = z_2 v_1`: the chained form of eq. 1 with ``n = 3``. The map is
defined for ``|theta| < pi/2``; other headings are handled by rotating the frame, as for the car.

The robot is a differential drive: wheels of radius ``rho`` on an axle of width ``b``. Its drive
turns the commanded ``(v, omega)`` into wheel speeds ``(v +- b omega / 2) / rho`` with the
*nominal* geometry, so the true robot, with ``rho~`` and ``b~``, moves at

.. math::

    v^{\mathrm{true}} = \frac{\tilde\rho}{\rho} v, \qquad
    \omega^{\mathrm{true}} = \frac{\tilde\rho}{\rho} \frac{b}{\tilde b} \omega.

The transformation itself needs no geometry; the perturbation is in the drive
(:class:`~ilc_steering.core.plants.UnicyclePlant`).
"""

from __future__ import annotations

from dataclasses import dataclass
from math import pi
from typing import Any

import numpy as np
import numpy.typing as npt

from ilc_steering.core.checks import require_positive

__all__ = ["UnicycleModel", "check_unicycle_chart", "unicycle_velocity"]

Array = npt.NDArray[np.float64]


def unicycle_velocity(theta: Any, v: Any, omega: Any) -> tuple[Any, Any, Any]:
    """``(dx, dy, dtheta)`` [m/s, m/s, rad/s] of a unicycle at heading ``theta`` under ``(v, omega)``."""
    return np.cos(theta) * v, np.sin(theta) * v, omega


def check_unicycle_chart(q: Array) -> None:
    """``ValueError`` where the chained-form map is undefined (``|theta| >= pi/2``)."""
    q = np.asarray(q, dtype=np.float64)
    if q.shape[-1] != 3:
        raise ValueError(f"a unicycle configuration is (x, y, theta); got shape {q.shape}")
    if not np.all(np.isfinite(q)):
        raise ValueError(f"configuration must be finite, got {q.tolist()}")
    if np.any(np.abs(q[..., 2]) >= pi / 2):
        raise ValueError(
            f"theta = {np.asarray(q[..., 2]).tolist()} rad: the chained form needs |theta| < pi/2 "
            "in the task frame (z2 = tan(theta)); rotate the frame"
        )


@dataclass(frozen=True)
class UnicycleModel:
    """A differential drive's geometry: ``wheel_radius`` ``rho`` [m] and ``axle_width`` ``b`` [m]."""

    wheel_radius: float
    axle_width: float

    def __post_init__(self) -> None:
        for name in ("wheel_radius", "axle_width"):
            require_positive(name, getattr(self, name), "m")

    def to_chained(self, q: Array) -> Array:
        """``z = (x, tan(theta), y)`` for ``q`` of shape ``(..., 3)``."""
        q = np.asarray(q, dtype=np.float64)
        check_unicycle_chart(q)
        return np.stack([q[..., 0], np.tan(q[..., 2]), q[..., 1]], axis=-1)

    def from_chained(self, z: Array) -> Array:
        """``q = (z1, z3, arctan(z2))``."""
        z = np.asarray(z, dtype=np.float64)
        return np.stack([z[..., 0], z[..., 2], np.arctan(z[..., 1])], axis=-1)

    def inputs(self, q: Array, v1: Array | float, v2: Array | float) -> tuple[Array, Array]:
        """``(v, omega)`` [m/s, rad/s] that realise chained inputs ``(v1, v2)`` at ``q``."""
        c = np.cos(np.asarray(q, dtype=np.float64)[..., 2])
        return np.asarray(np.asarray(v1) / c), np.asarray(np.asarray(v2) * c * c)
