r"""A system that is itself in chained form (eq. 1), with true input gains: ``plant.model: chained``.

The true plant is :math:`\dot z_1 = g_1 v_1`, :math:`\dot z_2 = g_2 v_2`,
:math:`\dot z_i = z_{i-1} g_1 v_1`, a perturbation of the form of eq. 37; the controller's map is
the identity (:class:`~ilc_steering.core.chained_form.ChainedForm`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from math import isfinite
from typing import Any, ClassVar, Literal

import numpy as np
import numpy.typing as npt
from numba import njit

from ilc_steering.core.chained_form import ChainedForm
from ilc_steering.core.checks import check_factors, require
from ilc_steering.core.kernels import trial_kernel
from ilc_steering.core.plants import ConfigurationState, FactorFamily, Kernel, KernelLayout, PlantKind, check_magnitude

__all__ = ["CHAINED", "KERNEL", "MAX_DIMENSION", "ChainedPlant", "ChainedPlantConfig"]

Array = npt.NDArray[np.float64]

CHAINED = PlantKind("chained", False, (), ("v1", "v2"))
MAX_DIMENSION = 12
"""The largest chained-form dimension ``n`` of a chained plant."""
MAX_GAIN = 1e3
"""The largest ``|v1_gain|``, ``|v2_gain|``: a gain past it makes ``z`` overflow within a trial."""
LAYOUT = KernelLayout((), ("v1_gain", "v2_gain", "dimension"))
_G1, _G2 = LAYOUT.index("v1_gain"), LAYOUT.index("v2_gain")


@njit(cache=True, inline="always")
def _field(params, x, v1, v2, out):  # type: ignore[no-untyped-def]
    w1 = params[_G1] * v1
    out[0] = w1
    out[1] = params[_G2] * v2
    for i in range(2, x.shape[0]):
        out[i] = x[i - 1] * w1


KERNEL = trial_kernel("chained-form", LAYOUT, __name__, _field)


@dataclass(frozen=True)
class ChainedPlant(ConfigurationState, FactorFamily):
    """The chained form of eq. (1) with true input gains: ``v1_gain * v1`` drives every
    ``v1`` term and ``v2_gain * v2`` drives ``z2`` (a perturbation of the form of eq. 37)."""

    kind: ClassVar[PlantKind] = CHAINED
    factor_names: ClassVar[tuple[str, str]] = ("v1_gain", "v2_gain")
    dimension: int
    v1_gain: float = 1.0
    v2_gain: float = 1.0
    steering_limit: ClassVar[None] = None

    def __post_init__(self) -> None:
        require(
            3 <= self.dimension <= MAX_DIMENSION, "dimension", f"must be in [3, {MAX_DIMENSION}], got {self.dimension}"
        )
        for name in ("v1_gain", "v2_gain"):
            value = getattr(self, name)
            require(
                isfinite(value) and value != 0 and abs(value) <= MAX_GAIN,
                name,
                f"must be nonzero and within +-{MAX_GAIN:g}, got {value}",
            )

    @classmethod
    def nominal_plant(cls, chained_map: Any, dimension: int, steering_limit: float | None) -> ChainedPlant:
        """The plant the controller assumes: unit gains."""
        return cls(dimension)

    @property
    def state_dim(self) -> int:
        return self.dimension

    def check_configuration(self, q: Array) -> None:
        q = np.asarray(q, dtype=np.float64)
        require(q.shape[-1] == self.dimension, "z", f"needs {self.dimension} values, got shape {q.shape}")
        require(bool(np.all(np.isfinite(q))), "z", f"must be finite, got {q.tolist()}")
        check_magnitude(q)

    def true_factors(self) -> Array:
        return np.array([self.v1_gain, self.v2_gain])

    def with_true_factors(self, factors: Array) -> ChainedPlant:
        f = check_factors(factors, self.factor_names)  # the user's own ratio named, not the product
        return replace(self, v1_gain=self.v1_gain * f[0], v2_gain=self.v2_gain * f[1])

    def kernel(self) -> tuple[Kernel, Array]:
        return KERNEL, LAYOUT.row(v1_gain=self.v1_gain, v2_gain=self.v2_gain, dimension=self.dimension)

    def reference_field(self, profile: Any, c: Array) -> tuple[Callable[[float, Array], Array], float, Any]:
        """Eq. 1 with the gains, as written."""

        def field(t: float, z: Array) -> Array:
            v1, v2 = profile.evaluate(c, np.array(t))
            w1 = self.v1_gain * float(v1)
            return np.concatenate([[w1, self.v2_gain * float(v2)], z[1:-1] * w1])

        return field, np.inf, None


@dataclass(frozen=True)
class ChainedPlantConfig:
    model: Literal["chained"]
    dimension: int  # n, the chained-form dimension (>= 3)
    v1_gain: float = 1.0  # true gain on v1 [-]; 1.0 unperturbed
    v2_gain: float = 1.0  # true gain on v2 [-]; 1.0 unperturbed

    kind: ClassVar[PlantKind] = CHAINED
    plant_class: ClassVar[type[ChainedPlant]] = ChainedPlant
    steering_limit: ClassVar[None] = None

    def __post_init__(self) -> None:
        self.plant()

    def nominal_map(self) -> ChainedForm:
        """The identity: the plant is in chained form."""
        return ChainedForm(self.dimension)

    def plant(self) -> ChainedPlant:
        return ChainedPlant(self.dimension, self.v1_gain, self.v2_gain)

    def check_task(self, max_step: float, cyclic: bool) -> None:
        """Nothing beyond the keys' own ranges."""
