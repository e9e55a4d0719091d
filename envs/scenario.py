"""A steering scenario: the true plant, the nominal model a learner may see, and measurements.

The environments own a :class:`Scenario`; learners get only its :class:`NominalModel`. Car tasks
are simulated in a *task frame*, the world frame rotated by :func:`~ilc_steering.envs.car.frame_angle`
so that both orientations sit in the chained-form chart; everything reported is in the world frame.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from ilc_steering.config import SteeringConfig
from ilc_steering.envs.car import CarModel, frame_angle, rotate
from ilc_steering.envs.integrate import OK
from ilc_steering.envs.plants import CarPlant, ChainedPlant, Plant, Trials, simulate
from ilc_steering.envs.profiles import PiecewiseProfile

__all__ = ["NominalModel", "Scenario"]

Array = npt.NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class NominalModel:
    """What a learner may know: the nominal chained form, the input profile and the task.

    ``z_start`` and ``z_goal`` are the start and goal in chained coordinates (computed with the
    nominal geometry, in the task frame). ``car`` is the nominal car geometry, or ``None`` for a
    chained plant. No true plant parameter is reachable from here.
    """

    dimension: int
    profile: PiecewiseProfile
    z_start: Array
    z_goal: Array
    car: CarModel | None = None

    def transition(self, c11: float) -> tuple[Array, Array]:
        """Eqs. (24)-(25): ``V`` and ``W`` of ``z_b`` when the learned ``v1`` value is ``c11``."""
        return self.profile.transition(c11, self.dimension)

    def final_state(self, c: Array, z_start: Array | None = None) -> Array:
        """Eq. (23) with eq. (12): the nominal ``z(T)`` of a trial with coefficients ``c``."""
        z0 = self.z_start if z_start is None else z_start
        z1 = z0[0] + float(self.profile.v1_pieces(c[0]) @ np.asarray(self.profile.durations))
        V, W = self.transition(c[0])
        return np.concatenate([[z1], V @ z0[1:] + W @ c[1:]])

    def solve(self) -> Array:
        """The open-loop coefficients that steer the *nominal* system exactly (section 2.2)."""
        p = self.profile
        fixed = float(np.dot(p.v1_fixed, p.durations[1:]))
        c11 = (self.z_goal[0] - self.z_start[0] - fixed) / p.durations[0]
        V, W = self.transition(c11)
        c2 = np.linalg.lstsq(W, self.z_goal[1:] - V @ self.z_start[1:], rcond=None)[0]
        return np.concatenate([[c11], c2])

    def action_scale(self) -> Array:
        """A natural magnitude for each coefficient, never zero: for ``c11`` the largest of the
        nominal solution, the mean speed ``|z1^d - z1^0| / Delta_1`` and the fixed ``v1`` values;
        for ``c2j`` the largest term ``|c2i| Delta**(i-1)`` of the nominal ``v2``, over ``Delta**(j-1)``
        (``Delta`` the longest piece), so every term may reach the peak of the nominal ``v2``."""
        c = self.solve()
        p = self.profile
        c11 = max(abs(c[0]), abs(self.z_goal[0] - self.z_start[0]) / p.durations[0], *np.abs(p.v1_fixed))
        powers = max(p.durations) ** np.arange(p.v2_terms)
        peak = max(float(np.max(np.abs(c[1:]) * powers)), 1e-9)
        return np.concatenate([[c11], np.maximum(np.abs(c[1:]), peak / powers)])


class Scenario:
    """The true plant, the nominal model and the task of a config, and what a trial measures."""

    def __init__(self, config: SteeringConfig) -> None:
        self.config = config
        plant_cfg, task = config.plant, config.task
        self.profile = PiecewiseProfile(task.pieces, task.v1_fixed, task.v2_terms)
        self.start = np.array(task.start, dtype=np.float64)
        self.goal = np.array(task.goal, dtype=np.float64)
        self.plant: Plant
        if plant_cfg.model == "car":
            nominal_car = CarModel(plant_cfg.wheelbase, plant_cfg.wheel_radius)
            self.plant = CarPlant(
                CarModel(plant_cfg.true_wheelbase, plant_cfg.true_wheel_radius), nominal_car, plant_cfg.steering_limit
            )
            self.frame = frame_angle(self.start[2], self.goal[2])
            self.x_start = rotate(self.start, self.frame)
            z_start = nominal_car.to_chained(self.x_start)
            z_goal = nominal_car.to_chained(rotate(self.goal, self.frame))
            self.nominal = NominalModel(4, self.profile, z_start, z_goal, nominal_car)
        else:
            self.plant = ChainedPlant(plant_cfg.dimension, plant_cfg.v1_gain, plant_cfg.v2_gain)
            self.frame = 0.0
            self.x_start = self.start
            self.nominal = NominalModel(plant_cfg.dimension, self.profile, self.start.copy(), self.goal.copy())

    @property
    def is_car(self) -> bool:
        return isinstance(self.plant, CarPlant)

    def to_chained(self, x: Array) -> Array:
        """Plant states ``(..., nx)`` in the task frame to chained coordinates (nominal map)."""
        return self.nominal.car.to_chained(x) if self.nominal.car is not None else np.asarray(x)

    def to_world(self, x: Array) -> Array:
        """Plant states in the task frame to world configurations."""
        return rotate(x, -self.frame) if self.is_car else np.asarray(x)

    def run(self, c: Array, x0: Array | None = None, record: bool = False, parallel: bool = False) -> Trials:
        """Simulate trials with coefficients ``c`` ``(B, 1 + q)`` from ``x0`` (default: the start)."""
        if x0 is None:
            x0 = np.broadcast_to(self.x_start, (c.shape[0], self.x_start.shape[0]))
        return simulate(
            self.plant, self.profile, np.ascontiguousarray(x0), c, self.config.simulation.max_step, record, parallel
        )

    def measure(self, final: Array, status: npt.NDArray[np.int64], goal: Array | None = None) -> dict[str, Array]:
        """Errors of a batch of final plant states ``(B, nx)`` against ``goal`` (world; default: the task's goal).

        Returns arrays with a leading batch axis: ``q_final`` (world), ``z_final``, ``error``
        (``z_goal - z(T)``, eq. 33-34's epsilon), ``error_norm``, ``left_chart`` and, for a car,
        ``cartesian_error`` [m] and ``orientation_error`` [rad].
        """
        goal_world = self.goal if goal is None else goal
        z_goal = self.to_chained(rotate(goal_world, self.frame)) if self.is_car else goal_world
        q_final = self.plant.configuration(final)
        z_final = self.to_chained(q_final)
        error = z_goal - z_final
        out = {
            "q_final": self.to_world(q_final),
            "z_final": z_final,
            "error": error,
            "error_norm": np.linalg.norm(error, axis=-1),
            "left_chart": status != OK,
        }
        if self.is_car:
            out["cartesian_error"] = np.linalg.norm(out["q_final"][..., :2] - goal_world[:2], axis=-1)
            out["orientation_error"] = np.abs(out["q_final"][..., 2] - goal_world[2])
        return out
