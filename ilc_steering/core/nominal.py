"""The nominal model: everything a learner may know about the system, and nothing more.

A learner is built from a :class:`NominalModel`: the nominal chained form of dimension ``n``, the
input profile, the start and goal in chained coordinates and, for a robot, the *nominal* map
between its configuration and the chained form. This module imports no plant, simulator or
environment (``tests/test_structure.py`` walks the imports to keep it so): the true plant is
not reachable from here.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar, Protocol, runtime_checkable

import numpy as np
import numpy.typing as npt

from ilc_steering.core.chained_form import ChainedForm
from ilc_steering.core.profiles import InputProfile

__all__ = ["MAX_NOMINAL_MISS", "ChainedMap", "NominalModel"]

MAX_NOMINAL_MISS = 1e-6
"""The largest miss of the nominal model's own exact solution (:meth:`NominalModel.miss`), relative to
the distance from the start to the goal in chained coordinates, of a well-posed task."""

Array = npt.NDArray[np.float64]


@runtime_checkable
class ChainedMap(Protocol):
    """A robot's change of coordinates to the chained form and its input transformation, with the
    geometry the controller assumes (for the car: eqs. 4-5, :class:`~ilc_steering.core.robots.car.CarModel`;
    for a system already in chained form, :class:`~ilc_steering.core.chained_form.ChainedForm`). Each
    robot's module of :mod:`ilc_steering.core.robots` has one."""

    robot: ClassVar[str]
    """The robot's name in the registry (``plant.model``)."""
    has_pose: ClassVar[bool]
    """The configuration starts with a planar pose ``(x [m], y [m], theta [rad])``."""

    def to_chained(self, q: Array) -> Array:
        """``z = alpha(q)`` for configurations ``(..., nq)``."""
        ...

    def from_chained(self, z: Array) -> Array:
        """``q = alpha^{-1}(z)``."""
        ...

    def inputs(self, q: Array, v1: Any, v2: Any) -> tuple[Array, Array]:
        """``u = beta(q) v``: the robot's inputs that realise chained inputs ``v1``, ``v2`` at ``q``."""
        ...

    def outline(self, q: Array) -> list[tuple[Array, bool]]:
        """The polylines ``(k, 2)`` [m] that draw the robot at configuration ``q`` ``(nq,)``, or
        ``(..., k, 2)`` for a batch ``(..., nq)`` (rendering draws a trial's snapshots in one call),
        each with whether it is a wheel (drawn thick); none for a system drawn as a point."""
        ...

    def curvature_cost(self, q: Array, dt: Array) -> Array:
        """``int kappa^2 ds`` [1/m] of the paths of recorded trials ``q`` ``(B, S, nq)`` with steps ``dt``
        ``(S - 1,)`` [s] (section 7's curvature cost)."""
        ...


@dataclass(frozen=True, eq=False)
class NominalModel:
    """What a learner may know: the nominal chained form, the input profile and the task.

    ``z_start`` and ``z_goal`` are the start and goal in chained coordinates (computed with the
    nominal map, in the task frame). ``chained_map`` is the nominal map of the robot (given as
    ``None``: the system is itself in chained form, and the map is
    :class:`~ilc_steering.core.chained_form.ChainedForm`); ``steering_limit`` is the car's steering
    stop and ``encoder_pulses`` the controller's odometry. No true plant parameter is reachable from here.
    """

    dimension: int
    profile: InputProfile
    z_start: Array
    z_goal: Array
    chained_map: ChainedMap = None  # type: ignore[assignment]  # None stands for ChainedForm(dimension)
    steering_limit: float | None = None
    """The robot's bound on ``|phi|`` [rad], a specification the controller knows (``None``: none)."""
    encoder_pulses: int = 0
    """The controller's own odometry: pulses per wheel turn from which it dead-reckons the heading it
    feeds eqs. 4-5 during a trial (0: it measures the heading). Part of the controller, as the steering
    limit is a specification: known to it, and to every learner."""

    def __post_init__(self) -> None:
        if self.chained_map is None:  # None stands for ChainedForm(dimension), the default
            object.__setattr__(self, "chained_map", ChainedForm(self.dimension))

    def transition(self, c11: float) -> tuple[Array, Array]:
        """Eqs. (24)-(25): ``V`` and ``W`` of ``z_b`` when the learned ``v1`` coefficient is ``c11``."""
        return self.profile.transition(c11, self.dimension)

    def z1_change(self, c11: float) -> float:
        """Eq. (12): the change of ``z1`` over a trial whose learned ``v1`` coefficient is ``c11``."""
        return self.profile.learned_area * float(c11) + self.profile.fixed_displacement

    def final_state(self, c: Array, z_start: Array | None = None) -> Array:
        """Eq. (23) with eq. (12): the nominal ``z(T)`` of a trial with coefficients ``c``."""
        z0 = self.z_start if z_start is None else z_start
        V, W = self.transition(c[0])
        return np.concatenate([[z0[0] + self.z1_change(c[0])], V @ z0[1:] + W @ c[1:]])

    def solve(self, z_start: Array | None = None, z_goal: Array | None = None) -> Array:
        """The open-loop coefficients that steer the *nominal* system exactly from ``z_start`` to
        ``z_goal`` (default: the task's), by eq. 12 for ``c11`` and eq. 23 for ``c2`` (section 2.2)."""
        z0 = self.z_start if z_start is None else z_start
        zd = self.z_goal if z_goal is None else z_goal
        p = self.profile
        c11 = (zd[0] - z0[0] - p.fixed_displacement) / p.learned_area
        V, W = self.transition(c11)
        c2 = np.linalg.lstsq(W, zd[1:] - V @ z0[1:], rcond=None)[0]
        return np.concatenate([[c11], c2])

    def miss(self, c: Array) -> float:
        """How far the nominal model's final state from ``c`` is from the goal, relative to the
        distance from the start to it in chained coordinates (``inf`` when not finite): above
        :data:`MAX_NOMINAL_MISS` for :meth:`solve`'s ``c``, ``W`` of eq. 23 is singular there and the
        task ill-posed."""
        distance = float(np.linalg.norm(self.z_goal - self.z_start))
        miss = float(np.linalg.norm(self.final_state(c) - self.z_goal)) / max(distance, 1e-12)
        return miss if np.isfinite(miss) else float("inf")

    def action_scale(self) -> Array:
        """A natural magnitude for each coefficient, never zero: for ``c11`` the largest of the
        nominal solution, the mean speed ``|z1^d - z1^0| / Delta_1`` and the fixed ``v1`` values;
        for ``c2j`` the largest term ``|c2i| Delta**(i-1)`` of the nominal ``v2``, over ``Delta**(j-1)``
        (``Delta`` the longest piece), so every term may reach the peak of the nominal ``v2``."""
        c = self.solve()
        p = self.profile
        c11 = max(abs(c[0]), abs(self.z_goal[0] - self.z_start[0]) / p.learned_area, *np.abs(p.v1_fixed))
        powers = max(p.durations) ** np.arange(p.v2_terms)
        peak = max(float(np.max(np.abs(c[1:]) * powers)), 1e-9)
        return np.concatenate([[c11], np.maximum(np.abs(c[1:]), peak / powers)])
