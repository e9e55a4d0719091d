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

from collections.abc import Callable
from dataclasses import asdict, dataclass, replace
from math import pi
from typing import Any, ClassVar, Literal

import numpy as np
import numpy.typing as npt

from ilc_steering.core.checks import check_factors, renamed, require_length
from ilc_steering.core.plants import (
    CHART_MARGIN,
    Kernel,
    PlantKind,
    check_steered,
    check_steering_limit,
    heading_curvature_cost,
)
from ilc_steering.core.robots.car import CarModel
from ilc_steering.core.robots.car_model import wheel_ratios
from ilc_steering.core.robots.car_trailer_fields import KERNEL, LANES_KERNEL, LAYOUT, trailer_inputs, trailer_velocity
from ilc_steering.core.robots.outline import WHEEL_HALF_LENGTH, box, direction, segment
from ilc_steering.errors import BadInput

__all__ = [
    "CAR_TRAILER",
    "KERNEL",
    "LANES_KERNEL",
    "TrailerModel",
    "TrailerPlant",
    "TrailerPlantConfig",
    "car_position",
    "check_trailer_chart",
    "trailer_inputs",
    "trailer_velocity",
]

Array = npt.NDArray[np.float64]


def check_trailer_chart(q: Array) -> None:
    """``ValueError`` where the chained-form map is undefined: ``|theta1|``, ``|phi|`` or the hitch
    angle ``|delta|`` at or past ``pi/2`` (the last is the jackknife)."""
    q = np.asarray(q, dtype=np.float64)
    if q.shape[-1] != 5:
        raise BadInput(f"a car-trailer configuration is (x1, y1, theta1, phi, delta); got shape {q.shape}")
    if not np.all(np.isfinite(q)):
        raise BadInput(f"configuration must be finite, got {q.tolist()}")
    for index, name, needs in _CHART:
        angle = np.asarray(q[..., index])
        if np.any(np.abs(angle) >= pi / 2):
            raise BadInput(f"{name} = {angle.tolist()} rad: {needs}")


_CHART = (
    (4, "delta", "the trailer is jackknifed (|hitch angle| >= pi/2), where the chained form is undefined "
     "(z3 = tan(delta) / (d cos^3 theta1))"),
    (2, "theta1", "the chained form needs the trailer's |theta1| < pi/2 in the task frame (z4 = tan(theta1)); "
     "rotate the frame"),
    (3, "phi", "the chained form needs |phi| < pi/2"),
)  # fmt: skip
"""The angles of the chart, in the order they are checked: ``(index in q, name, what is needed)``."""


def car_position(q: Array, hitch_length: float) -> tuple[Array, Array]:
    """The car's rear-axle midpoint ``(..., 2)`` [m] and heading [rad] of configurations ``q``."""
    q = np.asarray(q, dtype=np.float64)
    theta1 = q[..., 2]
    rear = q[..., :2] + hitch_length * np.stack([np.cos(theta1), np.sin(theta1)], axis=-1)
    return rear, theta1 + q[..., 4]


CAR_TRAILER = PlantKind(
    "car_trailer", True, ("x1 [m]", "y1 [m]", "θ1 [rad]", "φ [rad]", "δ [rad]"), ("u1 [rad/s]", "u2 [rad/s]")
)


@dataclass(frozen=True)
class TrailerModel:
    """The geometry of a car and its trailer: ``wheelbase`` ``ell``, ``wheel_radius`` ``rho`` and
    ``hitch_length`` ``d`` (from the car's rear axle to the trailer's axle) [m]."""

    wheelbase: float
    wheel_radius: float
    hitch_length: float
    robot: ClassVar[str] = "car_trailer"
    has_pose: ClassVar[bool] = True

    def __post_init__(self) -> None:
        for name in ("wheelbase", "wheel_radius", "hitch_length"):
            require_length(name, getattr(self, name))

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

    def outline(self, q: Array) -> list[tuple[Array, bool]]:
        """The car at the hitch, the trailer's body and axle at ``(x1, y1)`` and the drawbar [m]; for
        configurations ``(..., 5)``, polylines ``(..., k, 2)``."""
        q = np.asarray(q, dtype=np.float64)
        rear, theta0 = car_position(q[..., :5], self.hitch_length)
        car_q = np.concatenate([rear, theta0[..., None], q[..., 3:4]], axis=-1)
        car = CarModel(self.wheelbase, self.wheel_radius).outline(car_q)
        axle = q[..., :2]
        heading, normal = direction(q[..., 2])
        size = self.wheelbase
        body = box(axle, heading, normal, size, -0.35, 0.45)
        wheel = segment(axle, WHEEL_HALF_LENGTH * size * heading)
        return [*car, (body, False), (np.stack([axle, rear], axis=-2), False), (wheel, True)]

    def curvature_cost(self, q: Array, dt: Array) -> Array:
        """``int kappa^2 ds`` [1/m] of the trailer axle's path, from its heading's turn."""
        return heading_curvature_cost(q)


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


@dataclass(frozen=True)
class TrailerPlant:
    """The car towing one trailer with its true geometry, steered through the nominal chained
    form. ``steering_limit`` bounds ``|phi|`` [rad] as for the car: the state's fourth entry is the
    servo's command, which winds past the stop while the wheel rests there. State ``(x1, y1,
    theta1, phi_c, delta)``."""

    kind: ClassVar[PlantKind] = CAR_TRAILER
    factor_names: ClassVar[tuple[str, str]] = ("wheelbase_ratio", "wheel_radius_ratio")
    true: TrailerModel
    nominal: TrailerModel
    steering_limit: float | None = None

    @classmethod
    def nominal_plant(cls, chained_map: Any, dimension: int, steering_limit: float | None) -> TrailerPlant:
        """The robot the controller assumes: its true geometry the nominal one, with the known steering limit."""
        return cls(chained_map, chained_map, steering_limit)

    def __post_init__(self) -> None:
        check_steering_limit(self.steering_limit)

    @property
    def state_dim(self) -> int:
        return 5

    def initial_state(self, q: Array) -> Array:
        """At rest at ``q``: the commanded steering angle is ``phi``."""
        return np.array(q, dtype=np.float64)

    def configuration(self, x: Array) -> Array:
        """The configurations, the wheel angle the clipped command."""
        q = np.array(x, dtype=np.float64)
        if self.steering_limit is not None:
            q[..., 3] = np.clip(q[..., 3], -self.steering_limit, self.steering_limit)
        return q

    def estimate(self, x: Array) -> Array:
        """The configurations, measured exactly."""
        return self.configuration(x)

    def check_configuration(self, q: Array) -> None:
        """The chart (``|theta1|, |phi|, |delta| < pi/2`` in the task frame; no jackknife) and the steering limit."""
        check_steered(q, check_trailer_chart, "|theta1|, |phi| and the hitch angle |delta|", self.steering_limit)

    def true_factors(self) -> Array:
        return wheel_ratios(self.true, self.nominal)

    def family_names(self) -> tuple[str, ...]:
        """The car's wheelbase and wheel radius, and the hitch: a trailer's length is as uncertain."""
        return (*self.factor_names, "hitch_length_ratio")

    def with_family(self, ratios: Array) -> TrailerPlant:
        t = self.true
        r = check_factors(ratios, self.family_names())
        return replace(self, true=TrailerModel(t.wheelbase * r[0], t.wheel_radius * r[1], t.hitch_length * r[2]))

    def with_true_factors(self, factors: Array) -> TrailerPlant:
        t, f = self.true, check_factors(factors, self.factor_names)
        return replace(self, true=TrailerModel(t.wheelbase * f[0], t.wheel_radius * f[1], t.hitch_length))

    def kernel(self) -> tuple[Kernel, Array]:
        limit = np.inf if self.steering_limit is None else self.steering_limit
        true = {f"true_{name}": value for name, value in asdict(self.true).items()}
        row = LAYOUT.row(**asdict(self.nominal), **true, steering_limit=limit)
        return (KERNEL if self.steering_limit is not None else LANES_KERNEL), row

    def reference_field(self, profile: Any, c: Array) -> tuple[Callable[[float, Array], Array], float, Any]:
        """The nominal ``u = beta(q) v`` at the measured configuration (the wheel at the stop when
        saturated), the car and trailer moving with their true geometry."""
        limit = np.inf if self.steering_limit is None else self.steering_limit
        true = self.true

        def field(t: float, x: Array) -> Array:
            v1, v2 = profile.evaluate(c, np.array(t))
            q = self.configuration(x)
            u1, u2 = self.nominal.inputs(q, float(v1), float(v2))
            velocity = trailer_velocity(q[2], q[3], q[4], u1, u2, true.wheelbase, true.wheel_radius, true.hitch_length)
            return np.array(velocity, dtype=np.float64)

        def chart(t: float, x: Array) -> float:
            return float(np.pi / 2 - CHART_MARGIN - max(abs(x[2]), abs(x[4]), min(abs(x[3]), limit)))

        return field, limit, chart


@dataclass(frozen=True)
class TrailerPlantConfig:
    model: Literal["car_trailer"]
    wheelbase: float  # nominal ell [m] of the car, known to the controller
    wheel_radius: float  # nominal rho [m]
    hitch_length: float  # nominal d [m], from the car's rear axle (the hitch) to the trailer's axle
    true_wheelbase: float  # the simulated robot's ell [m]
    true_wheel_radius: float  # the simulated robot's rho [m]
    true_hitch_length: float  # the simulated robot's d [m]
    steering_limit: float | None = None  # bound on |phi| [rad]; None for none

    kind: ClassVar[PlantKind] = CAR_TRAILER
    plant_class: ClassVar[type[TrailerPlant]] = TrailerPlant
    dimension: ClassVar[int] = 5

    def __post_init__(self) -> None:
        self.plant()

    def nominal_map(self) -> TrailerModel:
        """The geometry the controller assumes."""
        return TrailerModel(self.wheelbase, self.wheel_radius, self.hitch_length)

    def plant(self) -> TrailerPlant:
        """The simulated car and trailer: true geometry, steered with the nominal one."""
        nominal = self.nominal_map()
        names = {
            "wheelbase": "true_wheelbase",
            "wheel_radius": "true_wheel_radius",
            "hitch_length": "true_hitch_length",
        }
        with renamed(names):
            true = TrailerModel(self.true_wheelbase, self.true_wheel_radius, self.true_hitch_length)
        return TrailerPlant(true, nominal, self.steering_limit)

    def check_task(self, max_step: float, cyclic: bool) -> None:
        """Nothing beyond the keys' own ranges."""
