r"""The car-like robot (eq. 3) and its chained form (eqs. 4-5).

Configuration ``q = (x, y, theta, phi)``: rear-axle midpoint [m], body orientation [rad] and
steering angle [rad]. Inputs: ``u1`` the driving-wheel angular velocity [rad/s], ``u2`` the
steering rate [rad/s]. The change of coordinates :math:`z = \alpha(q)`,

.. math::

    z_1 = x, \quad z_2 = \frac{\tan\phi}{\ell \cos^3\theta}, \quad z_3 = \tan\theta, \quad z_4 = y,

and the input transformation :math:`u = \beta(q) v` (eqs. 4-5) put the car in the chained form of
eq. 1 when they use the car's true wheelbase ``ell`` and wheel radius ``rho``. The controller
only knows *nominal* values; the plant in :mod:`ilc_steering.core.plants` uses the true ones.

Everything here is plain numpy, so a learner that needs the map pays for no compiler; the
simulator compiles the same formulas (:mod:`ilc_steering.core.integrate`).

The map is defined for ``|theta| < pi/2`` and ``|phi| < pi/2``. A task whose orientations do not
fit is handled by rotating the x-y frame (the remark at the end of section 4): see
:func:`frame_angle`.
"""

from __future__ import annotations

from dataclasses import dataclass
from math import pi
from typing import Any

import numpy as np
import numpy.typing as npt

from ilc_steering.core.checks import require_positive

__all__ = ["CarModel", "car_velocity", "chained_inputs", "check_chart", "frame_angle", "rotate"]

Array = npt.NDArray[np.float64]


def car_velocity(
    theta: Any, phi: Any, u1: Any, u2: Any, wheelbase: float, wheel_radius: float
) -> tuple[Any, Any, Any, Any]:
    """Eq. (3): ``(dx, dy, dtheta, dphi)`` of a rear-wheel-drive car [m/s, m/s, rad/s, rad/s].

    ``theta``, ``phi`` [rad], ``u1`` [rad/s] and ``u2`` [rad/s] are scalars or arrays of one shape.
    """
    speed = wheel_radius * u1
    return np.cos(theta) * speed, np.sin(theta) * speed, np.tan(phi) * speed / wheelbase, u2


def chained_inputs(theta: Any, phi: Any, v1: Any, v2: Any, wheelbase: float, wheel_radius: float) -> tuple[Any, Any]:
    """Eqs. (4)-(5): the car inputs ``(u1, u2)`` [rad/s] that realise chained inputs ``(v1, v2)`` at ``q``."""
    c = np.cos(theta)
    s_phi = np.sin(phi)
    c_phi = np.cos(phi)
    u1 = v1 / (wheel_radius * c)
    u2 = -3.0 / wheelbase * np.sin(theta) / c**2 * s_phi**2 * v1 + wheelbase * c**3 * c_phi**2 * v2
    return u1, u2


@dataclass(frozen=True)
class CarModel:
    """A car-like robot's geometry: ``wheelbase`` ``ell`` [m] and ``wheel_radius`` ``rho`` [m]."""

    wheelbase: float
    wheel_radius: float

    def __post_init__(self) -> None:
        for name in ("wheelbase", "wheel_radius"):
            require_positive(name, getattr(self, name), "m")

    def to_chained(self, q: Array) -> Array:
        """The change of coordinates ``z = alpha(q)`` of section 2.1, for ``q`` of shape ``(..., 4)``."""
        q = np.asarray(q, dtype=np.float64)
        check_chart(q)
        z = np.empty(q.shape)
        z[..., 0] = q[..., 0]
        z[..., 1] = np.tan(q[..., 3]) / (self.wheelbase * np.cos(q[..., 2]) ** 3)
        z[..., 2] = np.tan(q[..., 2])
        z[..., 3] = q[..., 1]
        return z

    def from_chained(self, z: Array) -> Array:
        """The inverse map ``q = alpha^{-1}(z)``, for ``z`` of shape ``(..., 4)``."""
        z = np.asarray(z, dtype=np.float64)
        z1, z2, z3, z4 = np.moveaxis(z, -1, 0)
        theta = np.arctan(z3)
        phi = np.arctan(z2 * self.wheelbase * np.cos(theta) ** 3)
        return np.stack([z1, z4, theta, phi], axis=-1)

    def inputs(self, q: Array, v1: Array | float, v2: Array | float) -> tuple[Array, Array]:
        """``u = beta(q) v`` (eqs. 4-5): wheel speed ``u1`` [rad/s] and steering rate ``u2`` [rad/s]."""
        q = np.asarray(q, dtype=np.float64)
        u1, u2 = chained_inputs(q[..., 2], q[..., 3], np.asarray(v1), np.asarray(v2), self.wheelbase, self.wheel_radius)
        return np.asarray(u1), np.asarray(u2)


def check_chart(q: Array) -> None:
    """Raise ``ValueError`` where the chained-form map of eq. 4 is undefined (``|theta|`` or ``|phi| >= pi/2``)."""
    q = np.asarray(q, dtype=np.float64)
    if q.shape[-1] != 4:
        raise ValueError(f"a car configuration is (x, y, theta, phi); got shape {q.shape}")
    if q.size and float(np.abs(q[..., 2:]).max()) < pi / 2 and np.isfinite(q[..., :2]).all():
        return  # the common case, in one pass; the checks below say what is wrong
    if not np.all(np.isfinite(q)):
        raise ValueError(f"configuration must be finite, got {q.tolist()}")
    theta, phi = q[..., 2], q[..., 3]
    if np.any(np.abs(theta) >= pi / 2):
        raise ValueError(
            f"theta = {np.asarray(theta).tolist()} rad: the chained form needs |theta| < pi/2 "
            "in the task frame (z3 = tan(theta)); rotate the frame with frame_angle()"
        )
    if np.any(np.abs(phi) >= pi / 2):
        raise ValueError(f"phi = {np.asarray(phi).tolist()} rad: the chained form needs |phi| < pi/2")


def frame_angle(*thetas: float) -> float:
    """The rotation [rad] of the x-y frame that puts all orientations ``thetas`` in ``(-pi/2, pi/2)``.

    Zero when they already are (so the paper's tasks keep their coordinates); otherwise the middle
    of their range, which works whenever the range is below ``pi`` (end of section 4). Raises
    ``ValueError`` otherwise, suggesting the intermediate configuration the paper prescribes.
    """
    low, high = min(thetas), max(thetas)
    if high - low >= pi:
        middle = 0.5 * (low + high)
        raise ValueError(
            f"orientations {low:.6g} and {high:.6g} rad are pi or more apart: no frame puts both in the "
            f"chained-form chart. Split the task at an intermediate configuration with theta = {middle:.6g} rad "
            "(section 4), or write one orientation 2*pi apart if the same heading by the shorter turn is meant."
        )
    if all(abs(t) < pi / 2 for t in thetas):
        return 0.0
    return 0.5 * (low + high)


def rotate(q: Array, angle: float) -> Array:
    """Express configurations ``q`` (``(..., 4)``) in a frame rotated by ``angle`` [rad]."""
    q = np.asarray(q, dtype=np.float64)
    c, s = np.cos(angle), np.sin(angle)
    out = q.copy()
    out[..., 0] = c * q[..., 0] + s * q[..., 1]
    out[..., 1] = -s * q[..., 0] + c * q[..., 1]
    out[..., 2] = q[..., 2] - angle
    return out
