r"""A robot defined outside the package: the worked example of ``docs/robots.md``.

A "skate": a unicycle driven directly in the chained form's terms, whose speed and turning gains
are off. Configuration ``q = (x, y, theta)``, the chained map ``z = (x, tan(theta), y)`` (as the
unicycle's), inputs ``(v, omega) = (v1 / cos(theta), v2 cos^2(theta))``, and the true skate moves
at ``speed_gain * v`` and turns at ``turn_gain * omega``:

.. math::

    \dot x = g_s v_1, \quad \dot y = g_s v_1 \tan\theta, \quad \dot\theta = g_t v_2 \cos^2\theta.

Everything a robot needs is here: the map, the compiled field and its chart test (one call of
:func:`~ilc_steering.core.kernels.trial_kernel` makes the kernel), the plant, the config keys and
the drawing. ``tests/test_robot_plugin.py`` registers it with one line and runs it through the
env, the vector env, ``ilc-steering run``, ``sweep`` and ``compare``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any, ClassVar, Literal

import numpy as np
import numpy.typing as npt
from numba import njit

from ilc_steering.core import plants
from ilc_steering.core.checks import check_factors, require, require_positive
from ilc_steering.core.kernels import trial_kernel
from ilc_steering.core.stepper import CHART_LIMIT

Array = npt.NDArray[np.float64]

SKATE = plants.PlantKind("skate", True, ("x [m]", "y [m]", "θ [rad]"), ("v [m/s]", "ω [rad/s]"))


@dataclass(frozen=True)
class SkateMap:
    """The chained form of the skate (the nominal map: it needs no geometry)."""

    robot: ClassVar[str] = "skate"
    has_pose: ClassVar[bool] = True

    def to_chained(self, q: Array) -> Array:
        q = np.asarray(q, dtype=np.float64)
        require(bool(np.all(np.abs(q[..., 2]) < np.pi / 2)), "theta", "the chained form needs |theta| < pi/2")
        return np.stack([q[..., 0], np.tan(q[..., 2]), q[..., 1]], axis=-1)

    def from_chained(self, z: Array) -> Array:
        z = np.asarray(z, dtype=np.float64)
        return np.stack([z[..., 0], z[..., 2], np.arctan(z[..., 1])], axis=-1)

    def inputs(self, q: Array, v1: Any, v2: Any) -> tuple[Array, Array]:
        c = np.cos(np.asarray(q, dtype=np.float64)[..., 2])
        return np.asarray(np.asarray(v1) / c), np.asarray(np.asarray(v2) * c * c)

    def outline(self, q: Array) -> list[tuple[Array, bool]]:
        """A triangle pointing along the heading [m]: for configurations ``(..., 3)`` (one, or a batch
        of them: rendering draws a trial's snapshots at once), polylines ``(..., 4, 2)``."""
        q = np.asarray(q, dtype=np.float64)
        theta = q[..., 2]
        ahead = np.stack([np.cos(theta), np.sin(theta)], axis=-1)
        side = np.stack([-np.sin(theta), np.cos(theta)], axis=-1)
        centre = q[..., :2]
        tip, left, right = (
            centre + 0.1 * ahead,
            centre - 0.05 * ahead + 0.05 * side,
            centre - 0.05 * ahead - 0.05 * side,
        )
        return [(np.stack([tip, left, right, tip], axis=-2), False)]

    def curvature_cost(self, q: Array, dt: Array) -> Array:
        return plants.heading_curvature_cost(q)


LAYOUT = plants.KernelLayout(("x", "y", "theta"), ("speed_gain", "turn_gain"))
_SPEED, _TURN = LAYOUT.index("speed_gain"), LAYOUT.index("turn_gain")


@njit(cache=True, inline="always")
def _field(params, x, v1, v2, out):  # type: ignore[no-untyped-def]
    c = np.cos(x[2])
    out[0] = params[_SPEED] * v1
    out[1] = params[_SPEED] * v1 * np.tan(x[2])
    out[2] = params[_TURN] * v2 * c * c


@njit(cache=True, inline="always")
def _chart(params, x):  # type: ignore[no-untyped-def]
    return abs(x[2]) < CHART_LIMIT


KERNEL = trial_kernel("skate", LAYOUT, __name__, _field, _chart)


@dataclass(frozen=True)
class SkatePlant(plants.ConfigurationState, plants.FactorFamily):
    kind: ClassVar[plants.PlantKind] = SKATE
    factor_names: ClassVar[tuple[str, str]] = ("speed_gain", "turn_gain")
    steering_limit: ClassVar[None] = None
    speed_gain: float = 1.0
    turn_gain: float = 1.0

    @classmethod
    def nominal_plant(cls, chained_map: Any, dimension: int, steering_limit: float | None) -> SkatePlant:
        return cls()

    @property
    def state_dim(self) -> int:
        return 3

    def check_configuration(self, q: Array) -> None:
        require(bool(np.all(np.isfinite(q))), "configuration", "must be finite")
        plants.check_magnitude(q)
        plants.check_angles(q, "|theta|")

    def true_factors(self) -> Array:
        return np.array([self.speed_gain, self.turn_gain])

    def with_true_factors(self, factors: Array) -> SkatePlant:
        f = check_factors(factors, self.factor_names)  # each ratio in FACTOR_RANGE, named with its value
        return replace(self, speed_gain=self.speed_gain * f[0], turn_gain=self.turn_gain * f[1])

    def kernel(self) -> tuple[plants.Kernel, Array]:
        return KERNEL, LAYOUT.row(speed_gain=self.speed_gain, turn_gain=self.turn_gain)

    def reference_field(self, profile: Any, c: Array) -> tuple[Callable[[float, Array], Array], float, Any]:
        def field(t: float, q: Array) -> Array:
            v1, v2 = profile.evaluate(c, np.array(t))
            v, omega = SkateMap().inputs(q, float(v1), float(v2))
            speed, turn = self.speed_gain * v, self.turn_gain * omega
            return np.array([speed * np.cos(q[2]), speed * np.sin(q[2]), turn])

        def chart(t: float, x: Array) -> float:
            return float(np.pi / 2 - plants.CHART_MARGIN - abs(x[2]))

        return field, np.inf, chart


@dataclass(frozen=True)
class SkatePlantConfig:
    model: Literal["skate"]
    true_speed_gain: float = 1.0  # [-] the true skate's speed over the commanded one
    true_turn_gain: float = 1.0  # [-] the true skate's turn rate over the commanded one

    kind: ClassVar[plants.PlantKind] = SKATE
    plant_class: ClassVar[type[SkatePlant]] = SkatePlant
    dimension: ClassVar[int] = 3
    steering_limit: ClassVar[None] = None

    def __post_init__(self) -> None:
        require_positive("true_speed_gain", self.true_speed_gain, "")
        require_positive("true_turn_gain", self.true_turn_gain, "")

    def nominal_map(self) -> SkateMap:
        return SkateMap()

    def plant(self) -> SkatePlant:
        return SkatePlant(self.true_speed_gain, self.true_turn_gain)

    def check_task(self, max_step: float, cyclic: bool) -> None:
        """Nothing beyond the keys' own ranges."""


CONFIG = """\
name: skate_parking
plant:
  model: skate
  true_speed_gain: 1.1  # [-]
  true_turn_gain: 0.9  # [-]
task:
  start: [0.0, 0.0, 0.0]
  goal: [1.0, 0.4, 0.3]
  pieces: [4.0]
  v1_fixed: []
  v2_terms: 2
learning:
  nu_a: 1.0
  nu_b: 1.0
  trials: 10
  tolerance: {cartesian: 1.0e-4, orientation: 1.0e-4}
"""
