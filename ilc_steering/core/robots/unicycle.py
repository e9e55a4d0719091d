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
(:class:`UnicyclePlant`), ``plant.model: unicycle``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from math import pi
from typing import Any, ClassVar, Literal

import numpy as np
import numpy.typing as npt
from numba import njit

from ilc_steering.core.checks import check_factors, renamed, require_length
from ilc_steering.core.kernels import lane_kernel
from ilc_steering.core.plants import (
    CHART_MARGIN,
    ConfigurationState,
    FactorFamily,
    Kernel,
    KernelLayout,
    PlantKind,
    check_angles,
    check_magnitude,
    heading_curvature_cost,
)
from ilc_steering.core.robots.outline import direction, segment
from ilc_steering.core.stepper import CHART_LIMIT
from ilc_steering.errors import BadInput

__all__ = [
    "KERNEL",
    "UNICYCLE",
    "UnicycleModel",
    "UnicyclePlant",
    "UnicyclePlantConfig",
    "check_unicycle_chart",
    "unicycle_inputs",
    "unicycle_velocity",
]

Array = npt.NDArray[np.float64]


def unicycle_velocity(theta: Any, v: Any, omega: Any) -> tuple[Any, Any, Any]:
    """``(dx, dy, dtheta)`` [m/s, m/s, rad/s] of a unicycle at heading ``theta`` under ``(v, omega)``."""
    return np.cos(theta) * v, np.sin(theta) * v, omega


def unicycle_inputs(theta: Any, v1: Any, v2: Any) -> tuple[Any, Any]:
    r"""The unicycle's inputs ``(v, omega)`` that realise the chained inputs ``(v1, v2)``: its
    equivalent of the car's eqs. 4-5 (the module docstring derives it).

    What a differential drive's own program computes from its heading at each instant of a trial,
    to steer by the chained inputs the trial sends (``docs/your_robot.md``, ``docs/modelling.md``):

    .. math::

        v = \frac{v_1}{\cos\theta}, \qquad \omega = v_2 \cos^2\theta.

    Driven so, the unicycle moves its chained coordinates :math:`z = (x, \tan\theta, y)`
    (:meth:`UnicycleModel.to_chained`) by eq. 1 with ``n = 3``: :math:`\dot z_1 = v_1`,
    :math:`\dot z_2 = v_2`, :math:`\dot z_3 = z_2 v_1`. No geometry enters: the drive turns
    ``(v, omega)`` into wheel speeds ``(v +- b omega / 2) / rho``. ``UnicycleModel.inputs(q, v1,
    v2)`` is this function at ``q``'s heading.

    Parameters
    ----------
    theta
        The heading [rad] in the task frame: a scalar or an array, within the chart ``|theta| <
        pi/2`` (at its edge ``v`` grows without bound; nothing is checked here:
        :func:`check_unicycle_chart` checks a configuration).
    v1, v2
        The chained inputs: ``v1`` [m/s] (the speed of ``z1 = x``) and ``v2`` [1/s] (that of
        ``z2 = tan(theta)``), broadcast against ``theta``.

    Returns
    -------
    v, omega
        The forward speed [m/s] and the turn rate [rad/s].
    """
    c = np.cos(theta)
    return v1 / c, v2 * c * c


def check_unicycle_chart(q: Array) -> None:
    """``ValueError`` where the chained-form map is undefined (``|theta| >= pi/2``)."""
    q = np.asarray(q, dtype=np.float64)
    if q.shape[-1] != 3:
        raise BadInput(f"a unicycle configuration is (x, y, theta); got shape {q.shape}")
    if not np.all(np.isfinite(q)):
        raise BadInput(f"configuration must be finite, got {q.tolist()}")
    if np.any(np.abs(q[..., 2]) >= pi / 2):
        raise BadInput(
            f"theta = {np.asarray(q[..., 2]).tolist()} rad: the chained form needs |theta| < pi/2 "
            "in the task frame (z2 = tan(theta)); rotate the frame"
        )


UNICYCLE = PlantKind("unicycle", True, ("x [m]", "y [m]", "θ [rad]"), ("v [m/s]", "ω [rad/s]"))


@dataclass(frozen=True)
class UnicycleModel:
    """A differential drive's geometry: ``wheel_radius`` ``rho`` [m] and ``axle_width`` ``b`` [m]."""

    wheel_radius: float
    axle_width: float
    robot: ClassVar[str] = "unicycle"
    has_pose: ClassVar[bool] = True

    def __post_init__(self) -> None:
        for name in ("wheel_radius", "axle_width"):
            require_length(name, getattr(self, name))

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
        """``(v, omega)`` [m/s, rad/s] that realise chained inputs ``(v1, v2)`` at ``q``: :func:`unicycle_inputs`."""
        v, omega = unicycle_inputs(np.asarray(q, dtype=np.float64)[..., 2], np.asarray(v1), np.asarray(v2))
        return np.asarray(v), np.asarray(omega)

    def outline(self, q: Array) -> list[tuple[Array, bool]]:
        """A round body on its axle [m], a heading mark and the two wheels (drawn thick); for
        configurations ``(..., 3)``, polylines ``(..., k, 2)``."""
        q = np.asarray(q, dtype=np.float64)
        centre, b, rho = q[..., :2], self.axle_width, self.wheel_radius
        heading, normal = direction(q[..., 2])
        angles = np.linspace(0.0, 2.0 * np.pi, 33)
        body = centre[..., None, :] + 0.6 * b * np.stack([np.cos(angles), np.sin(angles)], axis=-1)
        wheels = [segment(c, rho * heading) for c in (centre + 0.5 * b * normal, centre - 0.5 * b * normal)]
        mark = np.stack([centre, centre + 0.6 * b * heading], axis=-2)
        return [(body, False), (mark, False), *((w, True) for w in wheels)]

    def curvature_cost(self, q: Array, dt: Array) -> Array:
        """``int kappa^2 ds`` [1/m] of the axle midpoint's path, from the heading's turn."""
        return heading_curvature_cost(q)


LAYOUT = KernelLayout(("x", "y", "theta"), ("wheel_radius", "axle_width", "true_wheel_radius", "true_axle_width"))
_RHO, _B, _TRUE_RHO, _TRUE_B = (LAYOUT.index(name) for name in LAYOUT.params)


# The closed loop in (x, y, s) with s = tan(theta) is linear: with k = rho~/rho, g = k b / b~,
#     x' = k v1,   y' = k v1 s,   s' = theta' / cos^2(theta) = g v2,
# no trigonometry, so the Runge-Kutta step vectorizes across trials (a lane kernel), as the car's
# batched kernel does (ilc_steering.core.tangent). The chart |theta| < pi/2 - CHART_MARGIN is
# |s| < tan(pi/2 - CHART_MARGIN).
_T_CHART = float(np.tan(CHART_LIMIT))


@njit(cache=True, inline="always")
def _lane_field(p, j, x, v1, v2, k):  # type: ignore[no-untyped-def]
    kv = p[0, j] * v1
    k[0, j] = kv
    k[1, j] = kv * x[2, j]
    k[2, j] = p[1, j] * v2


@njit(cache=True, inline="always")
def _load(row, q, p, x, j):  # type: ignore[no-untyped-def]
    k = row[_TRUE_RHO] / row[_RHO]
    p[0, j], p[1, j] = k, k * row[_B] / row[_TRUE_B]
    x[0, j], x[1, j], x[2, j] = q[0], q[1], np.tan(q[2])


@njit(cache=True, inline="always")
def _lane_chart(x, j):  # type: ignore[no-untyped-def]
    return np.isfinite(x[0, j]) and np.isfinite(x[1, j]) and abs(x[2, j]) < _T_CHART


@njit(cache=True, inline="always")
def _store(x, j, dst):  # type: ignore[no-untyped-def]
    dst[0], dst[1], dst[2] = x[0, j], x[1, j], np.arctan(x[2, j])


KERNEL = lane_kernel("unicycle", LAYOUT, __name__, (_load, _lane_field, _lane_chart, _store), (3, 2))


@dataclass(frozen=True)
class UnicyclePlant(ConfigurationState, FactorFamily):
    """A differential-drive robot with its true wheel radius and axle width, its commanded forward
    speed and turn rate turned into wheel speeds with the nominal ones. The state is the
    configuration ``(x, y, theta)``."""

    kind: ClassVar[PlantKind] = UNICYCLE
    factor_names: ClassVar[tuple[str, str]] = ("wheel_radius_ratio", "axle_width_ratio")
    true: UnicycleModel
    nominal: UnicycleModel
    steering_limit: ClassVar[None] = None

    @classmethod
    def nominal_plant(cls, chained_map: Any, dimension: int, steering_limit: float | None) -> UnicyclePlant:
        """The robot the controller assumes: its true geometry the nominal one."""
        return cls(chained_map, chained_map)

    @property
    def state_dim(self) -> int:
        return 3

    def check_configuration(self, q: Array) -> None:
        """The chart (``|theta| < pi/2`` in the task frame)."""
        check_unicycle_chart(q)
        check_magnitude(q)
        check_angles(q, "|theta|")

    def true_factors(self) -> Array:
        return np.array(
            [self.true.wheel_radius / self.nominal.wheel_radius, self.true.axle_width / self.nominal.axle_width]
        )

    def with_true_factors(self, factors: Array) -> UnicyclePlant:
        f = check_factors(factors, self.factor_names)  # the user's own ratio named, not the product
        true = UnicycleModel(self.true.wheel_radius * f[0], self.true.axle_width * f[1])
        return replace(self, true=true)

    def kernel(self) -> tuple[Kernel, Array]:
        nominal, true = self.nominal, self.true
        row = LAYOUT.row(
            wheel_radius=nominal.wheel_radius,
            axle_width=nominal.axle_width,
            true_wheel_radius=true.wheel_radius,
            true_axle_width=true.axle_width,
        )
        return KERNEL, row

    def reference_field(self, profile: Any, c: Array) -> tuple[Callable[[float, Array], Array], float, Any]:
        """The nominal map's ``(v, omega)`` turned into wheel speeds with the nominal geometry, the
        wheels moving the true robot (its own wheel radius and axle width)."""
        nominal, true = self.nominal, self.true

        def field(t: float, q: Array) -> Array:
            v1, v2 = profile.evaluate(c, np.array(t))
            v, omega = nominal.inputs(q, float(v1), float(v2))
            right = (v + 0.5 * nominal.axle_width * omega) / nominal.wheel_radius
            left = (v - 0.5 * nominal.axle_width * omega) / nominal.wheel_radius
            speed = 0.5 * true.wheel_radius * (right + left)
            turn = true.wheel_radius * (right - left) / true.axle_width
            return np.array(unicycle_velocity(q[2], speed, turn), dtype=np.float64)

        def chart(t: float, x: Array) -> float:
            return float(np.pi / 2 - CHART_MARGIN - abs(x[2]))

        return field, np.inf, chart


@dataclass(frozen=True)
class UnicyclePlantConfig:
    model: Literal["unicycle"]
    wheel_radius: float  # nominal rho [m] of the differential drive, known to the controller
    axle_width: float  # nominal b [m], the distance between the two driven wheels
    true_wheel_radius: float  # the simulated robot's rho [m]
    true_axle_width: float  # the simulated robot's b [m]

    kind: ClassVar[PlantKind] = UNICYCLE
    plant_class: ClassVar[type[UnicyclePlant]] = UnicyclePlant
    dimension: ClassVar[int] = 3
    steering_limit: ClassVar[None] = None

    def __post_init__(self) -> None:
        self.plant()

    def nominal_map(self) -> UnicycleModel:
        """The geometry the drive assumes."""
        return UnicycleModel(self.wheel_radius, self.axle_width)

    def plant(self) -> UnicyclePlant:
        """The simulated differential drive: true geometry, driven with the nominal one."""
        nominal = self.nominal_map()
        with renamed({"wheel_radius": "true_wheel_radius", "axle_width": "true_axle_width"}):
            true = UnicycleModel(self.true_wheel_radius, self.true_axle_width)
        return UnicyclePlant(true, nominal)

    def check_task(self, max_step: float, cyclic: bool) -> None:
        """Nothing beyond the keys' own ranges."""
