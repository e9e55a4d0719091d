r"""The car of eq. 3 towing one trailer, and its chained form (``n = 5``), after Sørdalen (1993).

The car: rear-axle midpoint :math:`P_0`, heading :math:`\theta_0`, steering angle :math:`\phi`,
wheelbase :math:`\ell`, driving wheel of radius :math:`\rho` turning at ``u1`` [rad/s] (so the
rear axle moves at :math:`v = \rho u_1`), steering rate ``u2`` [rad/s]. The trailer is hitched at
:math:`P_0`; its axle midpoint :math:`P_1 = P_0 - d (\cos\theta_1, \sin\theta_1)` trails at the
hitch length ``d`` [m]. With the hitch angle :math:`\delta = \theta_0 - \theta_1`,

.. math::

    \dot\theta_1 = \frac{v}{d} \sin\delta, \qquad
    \dot P_1 = \dot P_0 - d\,\dot\theta_1 (-\sin\theta_1, \cos\theta_1)
             = v \cos\delta\,(\cos\theta_1, \sin\theta_1), \qquad
    \dot\delta = v \Big(\frac{\tan\phi}{\ell} - \frac{\sin\delta}{d}\Big), \qquad \dot\phi = u_2.

Configuration ``q = (x1, y1, theta1, phi, delta)``: the trailer's pose (its axle midpoint and
heading, the output that is steered), the car's steering angle and the hitch angle.

**Chained form** (the trailer's axle midpoint is a flat output). Take :math:`z_1 = x_1`,
:math:`z_5 = y_1` and let each :math:`z_{i-1} = dz_i/dz_1` along the motion, so that
:math:`\dot z_i = z_{i-1} v_1` with :math:`v_1 = \dot x_1`. With :math:`C = \cos\theta_1`,
:math:`S = \sin\theta_1`, :math:`E = \tan\phi / \ell - \sin\delta / d`:

.. math::

    z_4 &= \frac{dy_1}{dx_1} = \tan\theta_1, \\
    z_3 &= \frac{\dot z_4}{\dot x_1} = \frac{\dot\theta_1}{C^2 \dot x_1}
         = \frac{\tan\delta}{d\,C^3}, \\
    z_2 &= \frac{\dot z_3}{\dot x_1}
         = \frac{3 \tan^2\!\delta\, S}{d^2 C^5} + \frac{E}{d \cos^3\!\delta\, C^4},

using :math:`\dot\theta_1 / \dot x_1 = \tan\delta / (d C)` and
:math:`\dot\delta / \dot x_1 = E / (\cos\delta\, C)`. Then :math:`\dot z_2 = a(q) v_1 + b(q) u_2`
with

.. math::

    a &= \frac{1}{\cos\delta\, C}\Big(\frac{\partial z_2}{\partial\theta_1}\frac{\sin\delta}{d}
         + \frac{\partial z_2}{\partial\delta} E\Big), \qquad
    b = \frac{\partial z_2}{\partial\phi} = \frac{1}{\ell d \cos^2\!\phi \cos^3\!\delta\, C^4}, \\
    \frac{\partial z_2}{\partial\theta_1} &= \frac{3 \tan^2\!\delta\,(C^2 + 5 S^2)}{d^2 C^6}
         + \frac{4 E S}{d \cos^3\!\delta\, C^5}, \qquad
    \frac{\partial z_2}{\partial\delta} = \frac{6 \tan\delta\, S}{d^2 \cos^2\!\delta\, C^5}
         + \frac{1}{d C^4}\Big(\frac{3 E \sin\delta}{\cos^4\!\delta} - \frac{1}{d \cos^2\!\delta}\Big),

so the input transformation :math:`u = \beta(q) v` is

.. math::

    u_1 = \frac{v_1}{\rho \cos\delta \cos\theta_1}, \qquad u_2 = \frac{v_2 - a(q) v_1}{b(q)}.

``tests/test_trailer.py`` checks that :math:`J_\alpha(q) f(q, \beta(q) v)` equals the chained
field to 1e-12 with the Jacobian by complex-step differentiation (no formula above is reused).

**Chart**: the map is defined for :math:`|\theta_1| < \pi/2` (:math:`z_4`), :math:`|\delta| <
\pi/2` (:math:`z_3`; at :math:`|\delta| = \pi/2` the trailer is jackknifed, perpendicular to the
car, and :math:`v_1 = v \cos\delta \cos\theta_1` no longer moves it) and :math:`|\phi| < \pi/2`.
"""

from __future__ import annotations

from dataclasses import dataclass
from math import pi
from typing import Any

import numpy as np
import numpy.typing as npt

from ilc_steering.core.checks import require_positive

__all__ = ["TrailerModel", "car_position", "check_trailer_chart", "trailer_inputs", "trailer_velocity"]

Array = npt.NDArray[np.float64]


def trailer_velocity(
    theta1: Any, phi: Any, delta: Any, u1: Any, u2: Any, wheelbase: float, wheel_radius: float, hitch_length: float
) -> tuple[Any, Any, Any, Any, Any]:
    """``(dx1, dy1, dtheta1, dphi, ddelta)`` of the car and trailer under inputs ``u1``, ``u2`` [rad/s]."""
    v = wheel_radius * u1
    ahead = v * np.cos(delta)
    turn = v * np.sin(delta) / hitch_length
    return ahead * np.cos(theta1), ahead * np.sin(theta1), turn, u2, v * np.tan(phi) / wheelbase - turn


def trailer_inputs(
    theta1: Any, phi: Any, delta: Any, v1: Any, v2: Any, wheelbase: float, wheel_radius: float, hitch_length: float
) -> tuple[Any, Any]:
    """``u = beta(q) v``: ``(u1, u2)`` [rad/s] that realise chained inputs ``(v1, v2)`` at ``q``.

    Plain arithmetic and numpy ufuncs, so that the compiled simulator compiles this very function.
    """
    d = hitch_length
    c, s = np.cos(theta1), np.sin(theta1)
    cd, sd = np.cos(delta), np.sin(delta)
    td = sd / cd
    e = np.tan(phi) / wheelbase - sd / d
    c4 = c * c * c * c
    cd3 = cd * cd * cd
    dz2_dtheta = 3.0 * td * td * (c * c + 5.0 * s * s) / (d * d * c4 * c * c) + 4.0 * e * s / (d * cd3 * c4 * c)
    dz2_ddelta = 6.0 * td * s / (d * d * cd * cd * c4 * c) + (3.0 * e * sd / (cd3 * cd) - 1.0 / (d * cd * cd)) / (
        d * c4
    )
    a = (dz2_dtheta * sd / d + dz2_ddelta * e) / (cd * c)
    c_phi = np.cos(phi)
    u1 = v1 / (wheel_radius * cd * c)
    u2 = (v2 - a * v1) * wheelbase * d * c_phi * c_phi * cd3 * c4
    return u1, u2


def check_trailer_chart(q: Array) -> None:
    """``ValueError`` where the chained-form map is undefined: ``|theta1|``, ``|phi|`` or the hitch
    angle ``|delta|`` at or past ``pi/2`` (the last is the jackknife)."""
    q = np.asarray(q, dtype=np.float64)
    if q.shape[-1] != 5:
        raise ValueError(f"a car-trailer configuration is (x1, y1, theta1, phi, delta); got shape {q.shape}")
    if not np.all(np.isfinite(q)):
        raise ValueError(f"configuration must be finite, got {q.tolist()}")
    theta, phi, delta = q[..., 2], q[..., 3], q[..., 4]
    if np.any(np.abs(delta) >= pi / 2):
        raise ValueError(
            f"delta = {np.asarray(delta).tolist()} rad: the trailer is jackknifed (|hitch angle| >= pi/2), "
            "where the chained form is undefined (z3 = tan(delta) / (d cos^3 theta1))"
        )
    if np.any(np.abs(theta) >= pi / 2):
        raise ValueError(
            f"theta1 = {np.asarray(theta).tolist()} rad: the chained form needs the trailer's |theta1| < pi/2 "
            "in the task frame (z4 = tan(theta1)); rotate the frame"
        )
    if np.any(np.abs(phi) >= pi / 2):
        raise ValueError(f"phi = {np.asarray(phi).tolist()} rad: the chained form needs |phi| < pi/2")


def car_position(q: Array, hitch_length: float) -> tuple[Array, Array]:
    """The car's rear-axle midpoint ``(..., 2)`` [m] and heading [rad] of configurations ``q``."""
    q = np.asarray(q, dtype=np.float64)
    theta1 = q[..., 2]
    rear = q[..., :2] + hitch_length * np.stack([np.cos(theta1), np.sin(theta1)], axis=-1)
    return rear, theta1 + q[..., 4]


@dataclass(frozen=True)
class TrailerModel:
    """The geometry of a car and its trailer: ``wheelbase`` ``ell``, ``wheel_radius`` ``rho`` and
    ``hitch_length`` ``d`` (from the car's rear axle to the trailer's axle) [m]."""

    wheelbase: float
    wheel_radius: float
    hitch_length: float

    def __post_init__(self) -> None:
        for name in ("wheelbase", "wheel_radius", "hitch_length"):
            require_positive(name, getattr(self, name), "m")

    def to_chained(self, q: Array) -> Array:
        """``z = alpha(q)`` (see the module docstring) for ``q`` of shape ``(..., 5)``."""
        q = np.asarray(q, dtype=np.float64)
        check_trailer_chart(q)
        return np.asarray(_to_chained(q, self.wheelbase, self.hitch_length), dtype=np.float64)

    def from_chained(self, z: Array) -> Array:
        """``q = alpha^{-1}(z)``: ``theta1 = arctan z4``, ``delta = arctan(d z3 cos^3 theta1)``, and
        ``tan(phi) / ell`` solved from ``z2``."""
        z = np.asarray(z, dtype=np.float64)
        d = self.hitch_length
        theta = np.arctan(z[..., 3])
        c, s = np.cos(theta), np.sin(theta)
        delta = np.arctan(z[..., 2] * d * c**3)
        cd, td = np.cos(delta), np.tan(delta)
        curvature = np.sin(delta) / d + d * cd**3 * c**4 * (z[..., 1] - 3.0 * td**2 * s / (d**2 * c**5))
        phi = np.arctan(self.wheelbase * curvature)
        return np.stack([z[..., 0], z[..., 4], theta, phi, delta], axis=-1)

    def inputs(self, q: Array, v1: Array | float, v2: Array | float) -> tuple[Array, Array]:
        """``u = beta(q) v``: wheel speed ``u1`` and steering rate ``u2`` [rad/s]."""
        q = np.asarray(q, dtype=np.float64)
        u1, u2 = trailer_inputs(
            q[..., 2],
            q[..., 3],
            q[..., 4],
            np.asarray(v1),
            np.asarray(v2),
            self.wheelbase,
            self.wheel_radius,
            self.hitch_length,
        )
        return np.asarray(u1), np.asarray(u2)


def _to_chained(q: Any, wheelbase: float, d: float) -> Any:
    """The map without its chart check; ``q`` may be complex (complex-step derivatives in the tests)."""
    theta, phi, delta = q[..., 2], q[..., 3], q[..., 4]
    c, s = np.cos(theta), np.sin(theta)
    td = np.tan(delta)
    z3 = td / (d * c**3)
    z2 = 3.0 * td**2 * s / (d**2 * c**5) + (np.tan(phi) / wheelbase - np.sin(delta) / d) / (
        d * np.cos(delta) ** 3 * c**4
    )
    return np.stack([q[..., 0], z2, z3, np.tan(theta), q[..., 1]], axis=-1)
