r"""The car-like robot (eq. 3) and its chained form (eqs. 4-5).

Configuration ``q = (x, y, theta, phi)``: rear-axle midpoint [m], body orientation [rad] and
steering angle [rad]. Inputs: ``u1`` the driving-wheel angular velocity [rad/s], ``u2`` the
steering rate [rad/s]. The change of coordinates :math:`z = \alpha(q)`,

.. math::

    z_1 = x, \quad z_2 = \frac{\tan\phi}{\ell \cos^3\theta}, \quad z_3 = \tan\theta, \quad z_4 = y,

and the input transformation :math:`u = \beta(q) v` (eqs. 4-5) put the car in the chained form of
eq. 1 when they use the car's true wheelbase ``ell`` and wheel radius ``rho``. The controller
only knows *nominal* values; the plant in :mod:`ilc_steering.envs.plants` uses the true ones.

The map is defined for ``|theta| < pi/2`` and ``|phi| < pi/2``. A task whose orientations do not
fit is handled by rotating the x-y frame (the remark at the end of section 4): see
:func:`frame_angle`.
"""

from __future__ import annotations

from dataclasses import dataclass
from math import isfinite, pi

import numpy as np
import numpy.typing as npt
from numba import njit

__all__ = ["CarModel", "car_velocity", "chained_inputs", "closed_loop_velocity", "frame_angle", "rotate"]

Array = npt.NDArray[np.float64]


@njit(cache=True)
def car_velocity(theta, phi, u1, u2, wheelbase, wheel_radius):  # type: ignore[no-untyped-def]
    """Eq. (3): ``(dx, dy, dtheta, dphi)`` of a rear-wheel-drive car [m/s, m/s, rad/s, rad/s]."""
    speed = wheel_radius * u1
    return np.cos(theta) * speed, np.sin(theta) * speed, np.tan(phi) * speed / wheelbase, u2


@njit(cache=True)
def chained_inputs(theta, phi, v1, v2, wheelbase, wheel_radius):  # type: ignore[no-untyped-def]
    """Eqs. (4)-(5): the car inputs ``(u1, u2)`` that realise chained inputs ``(v1, v2)`` at ``q``."""
    c = np.cos(theta)
    s_phi = np.sin(phi)
    c_phi = np.cos(phi)
    u1 = v1 / (wheel_radius * c)
    u2 = -3.0 / wheelbase * np.sin(theta) / c**2 * s_phi**2 * v1 + wheelbase * c**3 * c_phi**2 * v2
    return u1, u2


@njit(cache=True, inline="always")
def closed_loop_velocity(theta, phi, v1, v2, wheelbase, wheel_radius, true_wheelbase, true_wheel_radius):  # type: ignore[no-untyped-def]
    """Eq. (3) of a car with the true geometry, driven by eqs. (4)-(5) with the nominal one [m].

    Equals ``car_velocity(theta, phi, *chained_inputs(theta, phi, v1, v2, wheelbase,
    wheel_radius), true_wheelbase, true_wheel_radius)`` with each sine and cosine evaluated
    once: this is the integrator's inner loop.
    """
    s, c = np.sin(theta), np.cos(theta)
    s_phi, c_phi = np.sin(phi), np.cos(phi)
    speed = true_wheel_radius / wheel_radius * v1 / c  # true rho times the commanded u1
    dphi = -3.0 / wheelbase * s / (c * c) * s_phi * s_phi * v1 + wheelbase * c * c * c * c_phi * c_phi * v2
    return c * speed, s * speed, s_phi / c_phi * speed / true_wheelbase, dphi


@dataclass(frozen=True)
class CarModel:
    """A car-like robot's geometry: ``wheelbase`` ``ell`` [m] and ``wheel_radius`` ``rho`` [m]."""

    wheelbase: float
    wheel_radius: float

    def __post_init__(self) -> None:
        for name in ("wheelbase", "wheel_radius"):
            value = getattr(self, name)
            if not (isfinite(value) and value > 0):
                raise ValueError(f"{name} must be finite and > 0 m, got {value}")

    def to_chained(self, q: Array) -> Array:
        """The change of coordinates ``z = alpha(q)`` of section 2.1, for ``q`` of shape ``(..., 4)``."""
        q = np.asarray(q, dtype=np.float64)
        check_chart(q)
        x, y, theta, phi = np.moveaxis(q, -1, 0)
        z2 = np.tan(phi) / (self.wheelbase * np.cos(theta) ** 3)
        return np.stack([x, z2, np.tan(theta), y], axis=-1)

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
        u1, u2 = chained_inputs(q[..., 2], q[..., 3], v1, v2, self.wheelbase, self.wheel_radius)
        return np.asarray(u1), np.asarray(u2)


def check_chart(q: Array) -> None:
    """Raise ``ValueError`` where the chained-form map of eq. 4 is undefined (``|theta|`` or ``|phi| >= pi/2``)."""
    q = np.asarray(q, dtype=np.float64)
    if q.shape[-1] != 4:
        raise ValueError(f"a car configuration is (x, y, theta, phi); got shape {q.shape}")
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
