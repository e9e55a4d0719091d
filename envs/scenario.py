"""A steering scenario: the true plant, the nominal models a learner may see, and measurements.

The environments own a :class:`Scenario`; learners get only its :class:`NominalModel`, one per
leg. Car tasks are simulated in a *task frame*, the world frame rotated by
:func:`~ilc_steering.envs.car.frame_angle` so that every waypoint's orientation sits in the
chained-form chart; everything reported is in the world frame.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from ilc_steering.config import CyclicTaskConfig, SteeringConfig
from ilc_steering.envs.car import CarModel, chained_inputs, frame_angle, rotate
from ilc_steering.envs.integrate import OK
from ilc_steering.envs.plants import CarPlant, ChainedPlant, Plant, Trials, simulate
from ilc_steering.envs.profiles import PiecewiseProfile
from ilc_steering.envs.trajectory import Trajectory

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

    def solve(self, z_start: Array | None = None, z_goal: Array | None = None) -> Array:
        """The open-loop coefficients that steer the *nominal* system exactly from ``z_start`` to
        ``z_goal`` (default: the task's), by eq. 12 for ``c11`` and eq. 23 for ``c2`` (section 2.2)."""
        z0 = self.z_start if z_start is None else z_start
        zd = self.z_goal if z_goal is None else z_goal
        p = self.profile
        fixed = float(np.dot(p.v1_fixed, p.durations[1:]))
        c11 = (zd[0] - z0[0] - fixed) / p.durations[0]
        V, W = self.transition(c11)
        c2 = np.linalg.lstsq(W, zd[1:] - V @ z0[1:], rcond=None)[0]
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
    """The true plant, the nominal models and the legs of a config, and what a trial measures.

    A one-trial task has one leg, start -> goal. A cyclic task has one leg per segment, waypoint
    ``l`` -> waypoint ``l + 1`` (the last leg returns home). ``waypoints`` are world configurations
    (chained coordinates for a chained plant); leg ``l`` ends at ``waypoints[(l + 1) % m]``.
    """

    def __init__(self, config: SteeringConfig) -> None:
        self.config = config
        plant_cfg, task = config.plant, config.task
        if isinstance(task, CyclicTaskConfig):
            self.waypoints = np.array(task.waypoints, dtype=np.float64)
            segments = [task.segment(i) for i in range(len(task.waypoints))]
        else:
            self.waypoints = np.array([task.start, task.goal], dtype=np.float64)
            segments = [task]
        profiles = [PiecewiseProfile(s.pieces, s.v1_fixed, s.v2_terms) for s in segments]
        self.plant: Plant
        if plant_cfg.model == "car":
            nominal_car: CarModel | None = CarModel(plant_cfg.wheelbase, plant_cfg.wheel_radius)
            self.plant = CarPlant(
                CarModel(plant_cfg.true_wheelbase, plant_cfg.true_wheel_radius), nominal_car, plant_cfg.steering_limit
            )
            self.frame = frame_angle(*self.waypoints[:, 2])
        else:
            nominal_car = None
            self.plant = ChainedPlant(plant_cfg.dimension, plant_cfg.v1_gain, plant_cfg.v2_gain)
            self.frame = 0.0
        self.x_start = self.to_task(self.waypoints[0]).copy()
        self.z_waypoints = nominal_car.to_chained(self.to_task(self.waypoints)) if nominal_car else self.waypoints.copy()
        m, n = self.waypoints.shape
        self.nominals = [
            NominalModel(n, profile, self.z_waypoints[leg], self.z_waypoints[(leg + 1) % m], nominal_car)
            for leg, profile in enumerate(profiles)
        ]

    @property
    def is_car(self) -> bool:
        return isinstance(self.plant, CarPlant)

    @property
    def nominal(self) -> NominalModel:
        """The nominal model of the first (for a one-trial task, the only) leg."""
        return self.nominals[0]

    @property
    def profile(self) -> PiecewiseProfile:
        return self.nominals[0].profile

    @property
    def start(self) -> Array:
        return self.waypoints[0]

    @property
    def goal(self) -> Array:
        return self.waypoints[1]

    def to_chained(self, x: Array) -> Array:
        """Configurations ``(..., nx)`` in the task frame to chained coordinates (nominal map)."""
        return self.nominal.car.to_chained(x) if self.nominal.car is not None else np.asarray(x)

    def to_world(self, x: Array) -> Array:
        """Configurations in the task frame to the world frame."""
        return rotate(x, -self.frame) if self.is_car else np.asarray(x)

    def to_task(self, q: Array) -> Array:
        """World configurations to the task frame."""
        return rotate(q, self.frame) if self.is_car else np.asarray(q)

    def run(
        self, c: Array, x0: Array | None = None, record: bool = False, parallel: bool = False, leg: int = 0
    ) -> Trials:
        """Simulate leg ``leg`` with coefficients ``c`` ``(B, 1 + q)`` from plant states ``x0``
        (task frame; default: the start)."""
        if x0 is None:
            x0 = np.broadcast_to(self.x_start, (c.shape[0], self.x_start.shape[0]))
        profile = self.nominals[leg].profile
        return simulate(
            self.plant, profile, np.ascontiguousarray(x0), c, self.config.simulation.max_step, record, parallel
        )

    def trajectory(self, trials: Trials, c: Array, index: int = 0, leg: int = 0) -> Trajectory:
        """The recorded motion of trial ``index`` of ``trials`` (from ``run(..., record=True)``
        with coefficients ``c`` ``(B, 1 + q)`` on leg ``leg``), in the world frame.

        The car's inputs are what the controller commands: eqs. 4-5 with the nominal geometry
        at the measured configuration (the wheel angle at the stop when saturated).
        """
        if trials.times is None or trials.states is None:
            raise ValueError("the trials were run without record=True; nothing to build a trajectory from")
        t, states = trials.times, trials.states[index]
        left_chart = bool(trials.status[index] != OK)
        if left_chart:  # the robot halted at its last valid state; drop the standstill after it
            moved = np.flatnonzero(np.any(states[1:] != states[:-1], axis=1))
            end = moved[-1] + 2 if moved.size else 1
            t, states = t[:end], states[:end]
        q = self.plant.configuration(states)
        v1, v2 = self.nominals[leg].profile.evaluate(c[index], t)
        car = self.nominal.car
        if car is None:
            u = np.stack([v1, v2], axis=-1)
        else:
            u = np.stack(chained_inputs.py_func(q[:, 2], q[:, 3], v1, v2, car.wheelbase, car.wheel_radius), axis=-1)
        return Trajectory(t.copy(), self.to_world(q), u, left_chart)

    def measure(self, final: Array, status: npt.NDArray[np.int64], leg: int = 0) -> dict[str, Array]:
        """Errors of a batch of final plant states ``(B, nx)`` against the end of leg ``leg``.

        Returns arrays with a leading batch axis: ``q_final`` (world), ``z_final``, ``error``
        (``z^d - z(T)``, the epsilon of eqs. 33-34 and 40), ``error_norm``, ``left_chart`` and,
        for a car, ``cartesian_error`` [m] and ``orientation_error`` [rad].
        """
        target = (leg + 1) % len(self.waypoints)
        goal_world = self.waypoints[target]
        q_final = self.plant.configuration(final)
        z_final = self.to_chained(q_final)
        error = self.z_waypoints[target] - z_final
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
