"""A steering scenario: the true plant, the nominal models a learner may see, and measurements.

The environments own a :class:`Scenario`; learners get only its
:class:`~ilc_steering.core.nominal.NominalModel`, one per leg. :meth:`Scenario.from_config`
builds every domain object from a config once; nothing reads the config's plant, task bounds or
simulation keys after that. Tasks of a robot with a pose are simulated in a *task frame*, the
world frame rotated by :func:`~ilc_steering.core.robots.car.frame_angle` so that every waypoint's
orientation sits in the chained-form chart; everything reported is in the world frame.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import numpy.typing as npt

from ilc_steering.config import SteeringConfig
from ilc_steering.core.checks import check_jitter, check_noise
from ilc_steering.core.external import ExternalPlant, run_external, users_plant
from ilc_steering.core.grid import DEFAULT_MAX_STEP
from ilc_steering.core.integrate import OK
from ilc_steering.core.nominal import ChainedMap, NominalModel
from ilc_steering.core.plants import CHART_MARGIN, Plant, PlantBatch
from ilc_steering.core.profiles import InputProfile
from ilc_steering.core.robots.car import rotate
from ilc_steering.core.simulate import Trials, simulate
from ilc_steering.core.trajectory import Trajectory
from ilc_steering.errors import BadInput

__all__ = ["PlantGroups", "Scenario"]

Array = npt.NDArray[np.float64]


START_DRAWS = 100
"""Draws of a trial's start (``start_error``) before one outside the chart is an error."""


class PlantGroups:
    """True plants, one per trial of a batch, grouped by the compiled kernel they run on: each group's
    parameters stacked once, so a batch costs one compiled call per kernel. Plants of one robot may
    need two kernels (a car with a steering offset or lag runs on the servo kernel, one with neither
    on the plain one) and may measure differently on one (a lag-free car reads its commanded wheel
    angle, a lagging one its wheel's lag state): :meth:`Scenario.run_groups` runs and measures each
    trial as a scenario of its own plant would."""

    def __init__(self, plants: Sequence[Plant]) -> None:
        self.plants = list(plants)
        kernels = [plant.kernel() for plant in self.plants]
        members: dict[int, list[int]] = {}
        for i, (field, _) in enumerate(kernels):
            members.setdefault(id(field), []).append(i)
        self.groups = [
            (np.array(index), PlantBatch.from_rows(kernels[index[0]][0], np.array([kernels[i][1] for i in index])))
            for index in members.values()
        ]

    def __len__(self) -> int:
        return len(self.plants)


class Scenario:
    """The true plant, the nominal models and the legs of a task, and what a trial measures.

    A one-trial task has one leg, start -> goal. A cyclic task has one leg per segment, waypoint
    ``l`` -> waypoint ``l + 1`` (the last leg returns home). ``waypoints`` are world configurations
    (chained coordinates for a chained plant); leg ``l`` ends at ``waypoints[(l + 1) % m]``.

    Parameters
    ----------
    plant
        The true plant (its parameters stay here).
    chained_map
        The nominal map to the chained form (the identity ``ChainedForm`` for a chained plant).
    profiles
        The input profile of each leg.
    waypoints
        ``(m, nq)`` world configurations: start and goal, or the cycle's waypoints.
    frame
        Rotation [rad] of the task frame (0 for a plant without a pose).
    action_bound
        ``|c_i|`` bounds of the action box, or ``None`` for 10 times the largest
        ``NominalModel.action_scale()`` over the legs.
    max_step
        Longest integrator step [s].
    measurement_noise
        Standard deviations of the final configuration's measurement (world frame; one for every
        coordinate or one per coordinate [m, rad]), or ``None`` to measure exactly.
    start_error
        Standard deviations of the start configuration, drawn anew for every trial (imperfect
        homing; world frame, as ``measurement_noise``), or ``None`` to start exactly.
    parameter_jitter
        Relative standard deviation of the true plant's two parameters (a car's wheelbase and wheel
        radius, the chained form's gains), drawn anew for every trial as log-normal factors, or ``None``.
    """

    def __init__(
        self,
        plant: Plant,
        chained_map: ChainedMap,
        profiles: Sequence[InputProfile],
        waypoints: Array,
        frame: float = 0.0,
        action_bound: Sequence[float] | None = None,
        max_step: float = DEFAULT_MAX_STEP,
        measurement_noise: float | Sequence[float] | None = None,
        start_error: float | Sequence[float] | None = None,
        parameter_jitter: float | None = None,
    ) -> None:
        # Asked once here, not per trial: a Protocol's isinstance checks every member.
        self.external: ExternalPlant | None = None
        if isinstance(plant, ExternalPlant):  # someone else's code: it reports in the task frame, nothing to jitter
            if parameter_jitter:
                raise BadInput("simulation.parameter_jitter: an external plant has no true factors to jitter")
            with users_plant(plant, "with_frame"):
                self.external = plant.with_frame(frame)
            plant = self.external  # type: ignore[assignment]  # an ExternalPlant serves as the Plant here
        self.plant = plant
        self.kind = plant.kind
        self.frame = frame
        self.max_step = max_step
        self.waypoints = np.array(waypoints, dtype=np.float64)
        size = self.waypoints.shape[1]
        self.noise = None if measurement_noise is None else check_noise(measurement_noise, size)
        self.start_error = None if start_error is None else check_noise(start_error, size, "start_error")
        self.jitter = None if parameter_jitter is None else check_jitter(parameter_jitter)
        self.x_start = plant.initial_state(self.to_task(self.waypoints[0]))
        task_points = self.to_task(self.waypoints)
        self.z_waypoints = chained_map.to_chained(task_points)
        m, n = self.z_waypoints.shape
        limit = plant.steering_limit  # a specification of the robot, known to the controller
        pulses = int(getattr(plant, "encoder_pulses", 0))  # the controller's own odometry, known to it
        self.nominals = [
            NominalModel(n, profile, self.z_waypoints[leg], self.z_waypoints[(leg + 1) % m], chained_map, limit, pulses)
            for leg, profile in enumerate(profiles)
        ]
        if action_bound is None:
            self.action_high = 10.0 * np.max([model.action_scale() for model in self.nominals], axis=0)
        else:
            self.action_high = np.asarray(action_bound, dtype=np.float64)

    @classmethod
    def from_config(
        cls,
        config: SteeringConfig,
        measurement_noise: float | Sequence[float] | None = None,
        start_error: float | Sequence[float] | None = None,
        parameter_jitter: float | None = None,
        plant: Plant | None = None,
    ) -> Scenario:
        """Every domain object of ``config``, built once (the config checked each rule on loading);
        ``measurement_noise``, ``start_error`` and ``parameter_jitter`` replace the config's if given;
        ``plant`` replaces the config's true plant (the one car every segment of a manoeuvre drives)."""
        if config.is_segmented:  # one scenario per segment: config.segment_configs()
            raise BadInput(
                f"{config.name}: a manoeuvre of several segments (task.segments); "
                "it runs in ilc_steering/SegmentedSteering-v0 (ilc-steering run), one scenario per segment"
            )
        points = np.array([point for _, point in config.points()], dtype=np.float64)
        # the arguments win over the config's, 0 included
        simulation = config.simulation
        noise = simulation.measurement_noise if measurement_noise is None else measurement_noise
        start = simulation.start_error if start_error is None else start_error
        jitter = simulation.parameter_jitter if parameter_jitter is None else parameter_jitter
        return cls(
            config.plant.plant() if plant is None else plant,
            config.plant.nominal_map(),
            [leg.profile() for _, leg in config.legs()],
            points,
            config.frame(),
            config.task.action_bound,
            config.simulation.max_step,
            noise,
            start,
            jitter,
        )

    def reseed(self, seed: int) -> None:
        """Hand the env's ``seed`` (``reset(seed=...)``) to an external plant, whose scatter is its
        own draw (:meth:`~ilc_steering.core.external.ExternalPlant.reseed`); a simulated plant's
        disturbances are drawn from the env's generator and need nothing."""
        if self.external is not None:
            with users_plant(self.external, "reseed"):
                self.external.reseed(seed)

    def draw_noise(self, rng: np.random.Generator, count: int) -> Array | None:
        """Measurement errors of ``count`` trials ``(count, nq)`` drawn from ``rng``, or ``None``
        (and nothing drawn) when the scenario measures exactly."""
        if self.noise is None:
            return None
        return rng.standard_normal((count, self.noise.size)) * self.noise

    def refuse_disturbances(self, env: str) -> None:
        """``ValueError`` if the scenario has non-repetitive disturbances, for an env that cannot draw them."""
        if self.start_error is not None or self.jitter is not None:
            raise BadInput(
                f"{env} does not draw simulation.start_error or simulation.parameter_jitter; "
                "use ilc_steering/ChainedSteering-v0 for a task with them"
            )

    def draw_disturbance(self, rng: np.random.Generator) -> tuple[Array | None, Plant | None]:
        """One trial's non-repetitive disturbances from ``rng``: its start state (task frame) and its
        true plant, each ``None`` (and nothing drawn) where the scenario has none."""
        x0 = plant = None
        if self.start_error is not None:
            x0 = self.plant.initial_state(self._draw_start(rng, self.start_error))
        if self.jitter is not None:
            plant = self.plant.with_true_factors(np.exp(self.jitter * rng.standard_normal(2)))
        return x0, plant

    def _draw_start(self, rng: np.random.Generator, sigma: Array) -> Array:
        """A start configuration (task frame) drawn about the task's with ``sigma``, drawn again
        where it falls outside the chart or the steering limit (a start there would be folded by pi,
        the heading reversed); ``ValueError`` when :data:`START_DRAWS` draws in a row all do."""
        for _ in range(START_DRAWS):
            q = self.to_task(self.waypoints[0] + rng.standard_normal(sigma.size) * sigma)
            try:
                self.plant.check_configuration(q)
            except ValueError:
                continue
            return q
        raise BadInput(
            f"simulation.start_error {sigma.tolist()}: {START_DRAWS} draws in a row start outside the "
            "chart or past the steering limit; it is too large for this task"
        )

    @property
    def nominal(self) -> NominalModel:
        """The nominal model of the first (for a one-trial task, the only) leg."""
        return self.nominals[0]

    @property
    def profile(self) -> InputProfile:
        return self.nominals[0].profile

    @property
    def start(self) -> Array:
        start: Array = self.waypoints[0]
        return start

    @property
    def goal(self) -> Array:
        goal: Array = self.waypoints[1]
        return goal

    def to_chained(self, x: Array) -> Array:
        """Configurations ``(..., nx)`` in the task frame to chained coordinates (nominal map)."""
        return self.nominal.chained_map.to_chained(x)

    def to_world(self, x: Array) -> Array:
        """Configurations in the task frame to the world frame."""
        return rotate(x, -self.frame) if self.kind.has_pose and self.frame else np.array(x, dtype=np.float64)

    def to_task(self, q: Array) -> Array:
        """World configurations to the task frame."""
        return rotate(q, self.frame) if self.kind.has_pose and self.frame else np.array(q, dtype=np.float64)

    def run(
        self,
        c: Array,
        x0: Array | None = None,
        record: bool = False,
        parallel: bool = False,
        leg: int = 0,
        plant: Plant | PlantBatch | Sequence[Plant] | None = None,
    ) -> Trials:
        """Simulate leg ``leg`` with coefficients ``c`` ``(B, 1 + q)`` from plant states ``x0``
        (task frame; default: the start) on the true plant, or on ``plant`` (a jittered one, or
        one plant per trial)."""
        if x0 is None:
            x0 = np.empty((c.shape[0], self.x_start.shape[0]))
            x0[:] = self.x_start
        profile = self.nominals[leg].profile
        if self.external is not None:  # it runs its own trials (a disturbance was refused above)
            return run_external(self.external, profile, np.ascontiguousarray(x0), c, record)
        true = self.plant if plant is None else plant
        return simulate(true, profile, np.ascontiguousarray(x0), c, self.max_step, record, parallel)

    def run_groups(self, c: Array, plants: PlantGroups, parallel: bool = False) -> tuple[Array, npt.NDArray[np.int64]]:
        """Trial ``i`` with coefficients ``c[i]`` on ``plants.plants[i]``, from that plant's state at
        rest at the start, one compiled call per kernel: the final configurations (task frame, each
        measured as its own plant measures it) ``(B, nq)`` and the statuses ``(B,)``."""
        if len(plants) != len(c):
            raise BadInput(f"plants: one plant per trial is needed ({len(c)}), got {len(plants)}")
        start = self.to_task(self.waypoints[0])
        q = np.empty((len(c), start.shape[0]))
        status = np.empty(len(c), dtype=np.int64)
        for index, batch in plants.groups:
            members = [plants.plants[i] for i in index]
            x0 = np.ascontiguousarray([plant.initial_state(start) for plant in members], dtype=np.float64)
            trials = self.run(np.ascontiguousarray(c[index]), x0, parallel=parallel, plant=batch)
            q[index] = [plant.configuration(x) for plant, x in zip(members, trials.final)]
            status[index] = trials.status
        return q, status

    def trajectory(self, trials: Trials, c: Array, index: int = 0, leg: int = 0) -> Trajectory:
        """The recorded motion of trial ``index`` of ``trials`` (from ``run(..., record=True)``
        with coefficients ``c`` ``(B, 1 + q)`` on leg ``leg``), in the world frame.

        A robot's inputs are what the controller commands: eqs. 4-5 with the nominal geometry
        at the configuration it acts on (the wheel angle at the stop when saturated; a lab
        robot's dead-reckoned estimate).
        """
        if trials.times is None or trials.states is None:
            raise BadInput("the trials were run without record=True; nothing to build a trajectory from")
        t, states = trials.times, trials.states[index]
        left_chart = bool(trials.status[index] != OK)
        if left_chart:  # the robot halted at its last valid state; drop the standstill after it
            moved = np.flatnonzero(np.any(states[1:] != states[:-1], axis=1))
            end = moved[-1] + 2 if moved.size else 1
            t, states = t[:end], states[:end]
        q = self.plant.configuration(states)
        v1, v2 = self.nominals[leg].profile.evaluate(c[index], t)
        chained_map = self.nominal.chained_map
        acted_on = self.plant.estimate(states)
        u = np.stack(chained_map.inputs(acted_on, v1, v2), axis=-1)
        return Trajectory(t.copy(), self.to_world(q), u, left_chart)

    def measure(
        self, final: Array, status: npt.NDArray[np.int64], leg: int = 0, noise: Array | None = None
    ) -> dict[str, Array]:
        """Errors of a batch of final plant states ``(B, nx)`` against the end of leg ``leg``.

        ``noise`` ``(B, nq)`` is added to the true final configuration (world frame) to give the
        measured one; ``None`` measures exactly. Returns arrays with a leading batch axis, all of
        the *measured* configuration: ``q_final`` (world), ``z_final``, ``error`` (``z^d - z(T)``, the
        epsilon of eqs. 33-34 and 40), ``error_norm``, ``left_chart`` and, for a robot with a
        pose, ``cartesian_error`` [m] and ``orientation_error`` [rad]; and the same errors of the
        true configuration as ``true_error_norm``, ``true_cartesian_error``, ``true_orientation_error``.
        """
        return self.measure_configurations(self.plant.configuration(final), status, leg, noise)

    def measure_configurations(
        self, q_task: Array, status: npt.NDArray[np.int64], leg: int = 0, noise: Array | None = None
    ) -> dict[str, Array]:
        """:meth:`measure` of final configurations ``q_task`` ``(B, nq)`` (task frame), each already
        read from its state by its own plant (:meth:`run_groups`)."""
        target = (leg + 1) % len(self.waypoints)
        q_world = self.to_world(q_task)
        z = self.to_chained(q_task)
        out = self._errors(z, q_world, target, "true_")
        if noise is None:  # measured exactly: the same errors, not computed twice on the fast path
            out.update({key.removeprefix("true_"): value for key, value in out.items()})
        else:
            q_world = q_world + noise
            q_task = self.to_task(q_world)
            if self.kind.has_pose:
                # noise on a trial that halted at the chart's edge may read past it, where z is undefined:
                # the measurement is taken at the edge
                edge = np.pi / 2 - CHART_MARGIN
                q_task[..., 2:] = np.clip(q_task[..., 2:], -edge, edge)
            z = self.to_chained(q_task)
            out.update(self._errors(z, q_world, target, ""))
        out["q_final"] = q_world
        out["z_final"] = z
        out["error"] = self.z_waypoints[target] - z
        out["left_chart"] = status != OK
        return out

    def _errors(self, z: Array, q_world: Array, target: int, prefix: str) -> dict[str, Array]:
        """The error norm (of chained coordinates ``z``) and, with a pose, the Cartesian [m] and
        orientation [rad] errors of a configuration (in the world frame) at waypoint ``target``."""
        goal = self.waypoints[target]
        dz = self.z_waypoints[target] - z
        out = {prefix + "error_norm": np.sqrt((dz * dz).sum(axis=-1))}
        if self.kind.has_pose:
            dx, dy = q_world[..., 0] - goal[0], q_world[..., 1] - goal[1]
            out[prefix + "cartesian_error"] = np.sqrt(dx * dx + dy * dy)
            out[prefix + "orientation_error"] = np.abs(q_world[..., 2] - goal[2])
        return out

    def check_start(self, q: Array) -> None:
        """``ValueError`` unless the world configuration ``q`` is a valid start for the plant."""
        self.plant.check_configuration(self.to_task(q))
