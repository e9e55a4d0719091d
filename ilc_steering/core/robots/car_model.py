r"""The car-like robot's kinematics: eq. 3, its chained form (eq. 4) and the inputs that realise it (eq. 5).

Configuration ``q = (x, y, theta, phi)``: rear-axle midpoint [m], body orientation [rad] and
steering angle [rad]. Inputs: ``u1`` the driving-wheel angular velocity [rad/s], ``u2`` the
steering rate [rad/s]. The change of coordinates :math:`z = \alpha(q)`,

.. math::

    z_1 = x, \quad z_2 = \frac{\tan\phi}{\ell \cos^3\theta}, \quad z_3 = \tan\theta, \quad z_4 = y,

and the input transformation :math:`u = \beta(q) v` (eqs. 4-5) put the car in the chained form of
eq. 1 when they use the car's true wheelbase ``ell`` and wheel radius ``rho``. The controller
only knows *nominal* values; the plant (:class:`~ilc_steering.core.robots.car.CarPlant`,
``plant.model: car``) uses the true ones.

Plain numpy: the controller's side (:func:`chained_inputs`: what a robot's own program computes
from the chained inputs a trial sends, ``docs/your_robot.md``), the plant's
(:mod:`ilc_steering.core.robots.car`) and the drawing all use them.

The map is defined for ``|theta| < pi/2`` and ``|phi| < pi/2``. A task whose orientations do not
fit is handled by rotating the x-y frame (the remark at the end of section 4): see
:func:`~ilc_steering.core.robots.chart.frame_angle`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
import numpy.typing as npt

from ilc_steering.core.checks import require_length
from ilc_steering.core.robots.chart import check_chart
from ilc_steering.core.robots.outline import car_outline

__all__ = ["CarModel", "car_velocity", "chained_inputs", "wheel_ratios"]

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
    r"""Eqs. (4)-(5): the car's inputs ``(u1, u2)`` that realise the chained inputs ``(v1, v2)``.

    What a car's own program computes from its state at each instant of a trial, to steer by the
    chained inputs the trial sends (``docs/your_robot.md``; the map is written out on
    ``docs/modelling.md``), with the geometry it believes (the nominal one):

    .. math::

        u_1 = \frac{v_1}{\rho \cos\theta}, \qquad
        u_2 = -\frac{3 \sin\theta \sin^2\phi}{\ell \cos^2\theta}\, v_1 + \ell \cos^3\theta \cos^2\phi\, v_2.

    Driven so, the car of eq. 3 with this very geometry moves its chained coordinates
    :math:`z = \alpha(q)` (:meth:`CarModel.to_chained`) by eq. 1: :math:`\dot z_1 = v_1`,
    :math:`\dot z_2 = v_2`, :math:`\dot z_3 = z_2 v_1`, :math:`\dot z_4 = z_3 v_1`.
    ``CarModel(wheelbase, wheel_radius).inputs(q, v1, v2)`` is this function at ``q``'s angles.

    Parameters
    ----------
    theta, phi
        The body's heading and the steering angle [rad] in the task frame: scalars or arrays of one
        shape, within the chart ``|theta| < pi/2``, ``|phi| < pi/2`` (at its edge ``u1`` and ``u2``
        grow without bound; nothing is checked here, so that a compiled or per-sample caller pays
        nothing: :func:`~ilc_steering.core.robots.chart.check_chart` checks a configuration).
    v1, v2
        The chained inputs: ``v1`` [m/s] (the speed of ``z1 = x``) and ``v2`` [1/(m s)] (that of
        ``z2 = tan(phi) / (ell cos^3 theta)``), broadcast against the angles.
    wheelbase, wheel_radius
        ``ell`` and ``rho`` [m].

    Returns
    -------
    u1, u2
        The driving wheel's angular velocity and the steering rate [rad/s].
    """
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
    robot: ClassVar[str] = "car"
    has_pose: ClassVar[bool] = True

    def __post_init__(self) -> None:
        for name in ("wheelbase", "wheel_radius"):
            require_length(name, getattr(self, name))

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

    def outline(self, q: Array) -> list[tuple[Array, bool]]:
        """The bicycle model of Fig. 1 [m]: the body, the rear wheel at ``(x, y)`` and the front wheel
        one wheelbase ahead, turned by ``phi`` (the wheels drawn thick); for configurations
        ``(..., 4)``, polylines ``(..., k, 2)``."""
        body, rear, front = car_outline(q, self.wheelbase)
        return [(body, False), (rear, True), (front, True)]

    def curvature_cost(self, q: Array, dt: Array) -> Array:
        """``int kappa^2 ds`` [1/m] of the rear axle's path, ``kappa = tan(phi) / ell`` at each step's middle."""
        ds = np.linalg.norm(np.diff(q[..., :2], axis=1), axis=-1)
        kappa = np.tan(0.5 * (q[:, 1:, 3] + q[:, :-1, 3])) / self.wheelbase
        return np.asarray(np.sum(kappa**2 * ds, axis=1), dtype=np.float64)


def wheel_ratios(true: Any, nominal: Any) -> Array:
    """A car's true factors: its true wheelbase and wheel radius over the nominal ones (of a
    :class:`CarModel`, or any model of a car that has them, a car with a trailer's)."""
    return np.array([true.wheelbase / nominal.wheelbase, true.wheel_radius / nominal.wheel_radius])
