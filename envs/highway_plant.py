r"""highway-env's parking car (``parking-v0``) as an external plant: a car nobody here wrote.

highway-env's own code steps the car (``Vehicle.step``): a kinematic bicycle referenced at its
centre, slip angle :math:`\beta = \arctan(\tan\delta / 2)`, heading rate
:math:`v \sin\beta / (L/2)`, Euler at 15 Hz, (acceleration, steering) actions held for 0.2 s
(5 Hz) and clipped by ``ContinuousAction`` to ±5 m/s² and ±45°, with the lot's walls and crashes.
:class:`HighwayParkingPlant` drives it through a fresh ``reset(seed=seed)`` of ``parking-v0`` per
trial; at each 0.2 s action step it measures the car (centre, heading, speed, the steering angle
it holds), turns that into the library's configuration (rear axle, heading, steering angle, task
frame) and sends the action that follows the library's inputs over the next step: the steering
angle the nominal closed loop (eqs. 3-5 with the nominal geometry, from the measured
configuration) reaches at mid-step, and the acceleration that brings the speed to the profile's
at the step's end, both normalised to parking-v0's action scale (not clipped here: highway-env
clips). Every action it sends is logged (``info["plant"]["actions"]``): :func:`replay` runs them
in a fresh ``parking-v0`` and gives the same final pose.

**The controller's nominal car** (:func:`nominal_map`): the library's car of eqs. 3-5 with
wheelbase ``L = Vehicle.LENGTH`` (5 m) and wheel radius 1 m (``u1`` is the rear axle's speed
[m/s]), the configuration referenced at the rear axle, ``L/2`` behind highway-env's centre. In
continuous time highway-env's bicycle *is* that car (its rear axle moves along the heading at
:math:`v\cos\beta`, turning at :math:`v\cos\beta\tan\delta / L`). What differs is outside any
geometry: Euler integration at 1/15 s, the steering angle set (not integrated) and held 0.2 s,
the speed reached through a clipped acceleration (one action step of lag), the ±45° stop, and
the walls (a crash stops the car; ``info["plant"]["crashed"]``).

**The walls.** Before a trial is sent, the adapter predicts it on the nominal closed loop it
follows, from the measured start (:meth:`HighwayParkingPlant.keeps_inside`); a trial whose
predicted outline (``LENGTH`` x ``WIDTH``, :func:`outline`) comes within :data:`WALL_MARGIN` of a
wall (:func:`inside_lot`) is never sent: it fails where the car stands, ``info["plant"]["refused"]``
(the pre-send check of a command against the robot's workspace; the learner sees a failed trial and
steps back). A trial sent whose outline still comes within :data:`WALL_MARGIN` of a wall at an
action step, or that crashes, is a failed trial too: from there the car brakes to a stop, wheels
straight, ``info["plant"]["left_lot"]``. Either reports the configuration where it failed with the
status ``LEFT_CHART`` (``info["left_chart"]``: the off-chart penalty, never within the tolerance)
and is counted like any trial.

The tasks (parking-v0's start and goal for a seed, as a config) are :mod:`~ilc_steering.envs.highway`'s.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from math import pi
from typing import Any, ClassVar, Literal

import numpy as np
import numpy.typing as npt

from ilc_steering.core.checks import require
from ilc_steering.core.external import ExternalPlantBase, chart_status
from ilc_steering.core.integrate import LEFT_CHART, OK
from ilc_steering.core.plants import CHART_MARGIN, PlantKind, check_angles, check_limit, check_magnitude
from ilc_steering.core.profiles import InputProfile
from ilc_steering.core.robots.car import CAR, CarModel, car_velocity, chained_inputs, check_chart, rotate
from ilc_steering.envs.highway_lot import LENGTH, WALL_MARGIN, WALLS, WIDTH, inside_lot, outline
from ilc_steering.errors import BadInput, ConfigError

__all__ = [
    "ACCELERATION",
    "ACTION_STEP",
    "LENGTH",
    "MAX_TURN",
    "SEEDS",
    "STEERING",
    "WALLS",
    "WALL_MARGIN",
    "WIDTH",
    "HighwayParkingPlant",
    "HighwayPlantConfig",
    "inside_lot",
    "nominal_map",
    "outline",
    "parking_task",
    "replay",
]

Array = npt.NDArray[np.float64]

ENV_ID = "parking-v0"
HIGHWAY = PlantKind("highway_parking", True, CAR.coordinates, CAR.inputs)
"""A car (the library's configuration, rear axle first), stepped by highway-env."""
ACCELERATION = 5.0
"""[m/s²] ``ContinuousAction.ACCELERATION_RANGE``: an action of 1 is this acceleration."""
STEERING = pi / 4
"""[rad] ``ContinuousAction.STEERING_RANGE``: an action of 1 is this steering angle, the car's stop."""
ACTION_STEP = 0.2
"""[s] parking-v0's action period (``policy_frequency`` 5 Hz)."""
FRAMES = 3
"""Simulation frames per action (``simulation_frequency`` 15 Hz over 5 Hz)."""
SUBSTEPS = 8
"""RK4 steps of the nominal closed loop over one action step (the adapter's prediction)."""
MAX_TURN = 150 * pi / 180
"""[rad] the largest turn from the start's heading to the goal's one chart serves: the task frame
puts both ``MAX_TURN / 2`` from its axis, leaving 15° to the chart's edge for the manoeuvre."""


def nominal_map() -> CarModel:
    """The controller's car: wheelbase ``LENGTH`` [m], wheel radius 1 m (``u1`` the rear axle's speed [m/s])."""
    return CarModel(LENGTH, 1.0)


def _make_env(render_mode: str | None = None) -> Any:
    try:
        import gymnasium as gym
        import highway_env  # registers parking-v0
    except ImportError:
        raise ConfigError('highway_parking needs highway-env: pip install "ilc-steering[highway]"') from None
    gym.register_envs(highway_env)
    return gym.make(ENV_ID, render_mode=render_mode)


def _pose(vehicle: Any) -> Array:
    """The library's world configuration (rear axle [m], heading [rad], steering [rad]) of a highway-env vehicle."""
    heading = float(vehicle.heading)
    x, y = (float(p) for p in vehicle.position)
    steering = float(np.clip(vehicle.action["steering"], -STEERING, STEERING))
    return np.array([x - 0.5 * LENGTH * np.cos(heading), y - 0.5 * LENGTH * np.sin(heading), heading, steering])


SEEDS = 2**31
"""parking-v0's seeds a task is made of: ``[0, SEEDS)``, a config's ``plant.seed`` (a 32-bit signed integer)."""


def parking_task(seed: int, one_chart: bool = True) -> tuple[Array, Array]:
    """parking-v0's start and goal for ``seed`` as world configurations ``(x, y, theta, phi)`` (rear
    axle [m], heading and steering [rad], the goal's steering 0): the start's heading in
    ``(-pi, pi]``, the goal's the way nearer it. ``ValueError`` naming the seed when the turn between
    them exceeds :data:`MAX_TURN` (one chart cannot serve it; not checked with ``one_chart=False``,
    for a manoeuvre of several segments), or when ``seed`` is not a whole number in ``[0, 2**31)``
    (:data:`SEEDS`: what a config's ``plant.seed`` takes)."""
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or not 0 <= seed < SEEDS:
        raise BadInput(f"parking-v0 seed {seed!r:.40}: needs a whole number in [0, 2**31)")
    env = _make_env()
    env.reset(seed=seed)
    vehicle = env.unwrapped.vehicle
    start = _pose(vehicle)
    start[2] = np.angle(np.exp(1j * start[2]))
    goal_heading = float(vehicle.goal.heading)
    goal_heading += 2 * pi * np.round((start[2] - goal_heading) / (2 * pi))
    gx, gy = (float(p) for p in vehicle.goal.position)
    goal = np.array(
        [gx - 0.5 * LENGTH * np.cos(goal_heading), gy - 0.5 * LENGTH * np.sin(goal_heading), goal_heading, 0]
    )
    env.close()
    turn = abs(goal[2] - start[2])
    if one_chart and turn > MAX_TURN:
        raise BadInput(
            f"parking-v0 seed {seed}: the goal's heading is {np.degrees(turn):.0f}° from the start's, over the "
            f"{np.degrees(MAX_TURN):.0f}° one chart serves; this task cannot serve it (it needs a waypoint)"
        )
    return start, goal


@dataclass(frozen=True)
class HighwayParkingPlant(ExternalPlantBase):
    """parking-v0's car for ``seed``, stepped by highway-env, reporting the library's configuration
    in the task frame (the world rotated by ``frame`` [rad]). See the module for the adapter."""

    kind: ClassVar[PlantKind] = HIGHWAY
    factor_names: ClassVar[tuple[str, str]] = ("wheelbase_ratio", "wheel_radius_ratio")
    name: ClassVar[str] = "highway-env's parking car"
    seed: int
    frame: float = 0.0
    render_mode: str | None = None
    _env: list[Any] = field(default_factory=list, compare=False, repr=False)
    _carry: list[bool] = field(default_factory=lambda: [False], compare=False, repr=False)
    frames: list[Any] = field(default_factory=list, compare=False, repr=False)
    """With ``render_mode="rgb_array"``: highway-env's frames of the last trial, one per action step."""

    state_dim: ClassVar[int] = 4
    steering_limit: ClassVar[float] = STEERING

    @property
    def env(self) -> Any:
        """The ``parking-v0`` env this plant drives (made on first use)."""
        if not self._env:
            self._env.append(_make_env(self.render_mode))
        return self._env[0]

    def with_frame(self, angle: float) -> HighwayParkingPlant:
        return replace(self, frame=float(angle), _env=self._env, _carry=self._carry, frames=self.frames)

    def carry_on(self) -> None:
        """The next trial goes on from where the car stands, without parking-v0's reset: the next
        segment of a manoeuvre (:mod:`~ilc_steering.envs.segmented_env`), one trial of which resets once."""
        self._carry[0] = True

    def check_configuration(self, q: Array) -> None:
        check_chart(q)
        check_magnitude(q)
        check_angles(q, "|theta| and |phi|")
        check_limit(np.asarray(q, dtype=np.float64)[..., 3], STEERING)

    def control_period(self) -> float:
        return float(ACTION_STEP)

    def _measure(self, vehicle: Any) -> Array:
        """The vehicle's configuration in the task frame, its heading wrapped to ``(-pi, pi]``."""
        q = rotate(_pose(vehicle), self.frame)
        q[2] = np.angle(np.exp(1j * q[2]))
        return q

    def trial(self, profile: InputProfile, x0: Array, c: Array, steps: int) -> tuple[Array, int, Array, dict[str, Any]]:
        env = self.env
        carried, self._carry[0] = self._carry[0], False
        if not carried:
            env.reset(seed=self.seed)
            self.frames.clear()
        vehicle = env.unwrapped.vehicle
        q, start_speed = self._measure(vehicle), float(vehicle.speed)
        gap = q - x0
        gap[2] = np.angle(np.exp(1j * gap[2]))  # headings compared modulo 2 pi: the measured one is wrapped
        if float(np.max(np.abs(gap))) > 1e-6:  # the config's task.start or start_error: bad input
            where = "where the last segment left the car" if carried else f"parking-v0 seed {self.seed}'s start"
            raise ConfigError(
                f"task.start {rotate(x0, -self.frame).tolist()} is not {where} "
                f"{_pose(vehicle).tolist()}: a highway-env trial starts where parking-v0 puts the car "
                "(no simulation.start_error)"
            )
        if not self.keeps_inside(profile, c, q, steps):  # refused before anything is sent: a failed trial
            log = {"seed": self.seed, "actions": [], "crashed": False, "left_lot": False, "refused": True}
            log["start_speed"] = start_speed
            return q, LEFT_CHART, np.repeat(q[None], steps + 1, axis=0), {**log, "is_success": _success(env)}
        states, actions = [q], []
        status, halted, left_lot = OK, q, False
        command = float(q[3])  # the steering command the adapter integrates from u2 (the servo's state)
        for k in range(steps):
            status, halted = chart_status(q, states, status, halted)
            if status == OK:
                acted_on = np.array([q[0], q[1], q[2], command])
                phi_mid, command, speed_end = self._follow(profile, c, acted_on, k * ACTION_STEP)[:3]
                beta = np.arctan(0.5 * np.tan(np.clip(phi_mid, -STEERING, STEERING)))
                accel = (speed_end / np.cos(beta) - vehicle.speed) / ACTION_STEP
                action = np.array([accel / ACCELERATION, phi_mid / STEERING])
            else:  # out of the chart, eqs. 4-5 break down: brake to a stop, wheels straight
                action = np.array([-vehicle.speed / ACTION_STEP / ACCELERATION, 0.0])
            # env.step's dynamics without its observation, reward and info (pandas, 2/3 of a step's
            # time); tests/test_highway.py replays the logged actions through env.step, bit for bit
            env.unwrapped._simulate(action)
            actions.append(action.tolist())
            if self.render_mode is not None:
                self.frames.append(env.render())
            q = self._measure(vehicle)
            states.append(q)
            if status == OK and (vehicle.crashed or not inside_lot(_pose(vehicle))):  # a failed trial, counted
                status, halted, left_lot = LEFT_CHART, q, True
        final = q if status == OK else halted
        log = {
            "seed": self.seed,
            "actions": actions,
            "crashed": bool(vehicle.crashed),
            "left_lot": left_lot,
            "refused": False,
            "start_speed": start_speed,  # [m/s] the nominal model assumes rest: a segment's car may roll in
            "is_success": _success(env),
        }
        return final, status, np.array(states), log

    def keeps_inside(self, profile: InputProfile, c: Array, q: Array, steps: int) -> bool:
        """Whether the trial of ``c`` from the measured configuration ``q`` (task frame), predicted
        on the nominal closed loop the adapter follows (:meth:`_follow`, every RK4 substep of
        ``steps`` action steps), keeps the car's outline :data:`WALL_MARGIN` inside the lot's
        walls: the pre-send check. A trial whose prediction does not is never sent (``refused``)."""
        x, path = np.array(q, dtype=np.float64), [q[None]]
        with np.errstate(all="ignore"):  # a path that blows up is not finite, and refused below
            for k in range(steps):
                if not abs(x[2]) < pi / 2 - CHART_MARGIN:  # where the trial halts and brakes to a stop
                    break
                x, substeps = self._follow(profile, c, x, k * ACTION_STEP)[3:]
                path.append(substeps)
            return bool(np.all(inside_lot(rotate(np.concatenate(path), -self.frame))))

    @staticmethod
    def _follow(profile: InputProfile, c: Array, q: Array, t0: float) -> tuple[float, float, float, Array, Array]:
        """The nominal closed loop (eqs. 3-5, nominal geometry, the wheel at the stop beyond
        ``STEERING`` while the command winds on) from ``q`` (its ``phi`` the adapter's steering
        command) at ``t0`` over one action step by RK4: the steering command at mid-step and at the
        end [rad], the rear axle's speed at the end [m/s], the state at the end and at each
        substep's end ``(SUBSTEPS, 4)`` (task frame)."""
        model = nominal_map()
        h = ACTION_STEP / SUBSTEPS
        # every RK4 stage falls on a half step: the inputs of the whole step in one call
        v1s, v2s = profile.evaluate(c, t0 + 0.5 * h * np.arange(2 * SUBSTEPS + 1, dtype=np.float64))
        ell, rho = model.wheelbase, model.wheel_radius

        def field_(i: int, x: Array) -> Array:
            phi = min(max(x[3], -STEERING), STEERING)
            u1, u2 = chained_inputs(x[2], phi, float(v1s[i]), float(v2s[i]), ell, rho)
            return np.array(car_velocity(x[2], phi, u1, u2, ell, rho))

        x, phi_mid, substeps = q.copy(), float(q[3]), np.empty((SUBSTEPS, 4))
        for i in range(SUBSTEPS):
            k1 = field_(2 * i, x)
            k2 = field_(2 * i + 1, x + h / 2 * k1)
            k3 = field_(2 * i + 1, x + h / 2 * k2)
            k4 = field_(2 * i + 2, x + h * k3)
            x = substeps[i] = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
            if i == SUBSTEPS // 2 - 1:
                phi_mid = float(x[3])
        speed = float(v1s[-1]) / np.cos(x[2]) * rho
        return phi_mid, float(x[3]), speed, x, substeps


def _success(env: Any) -> bool:
    """parking-v0's own success test (its ``info["is_success"]``) at the car's present state."""
    parking = env.unwrapped
    obs = parking.observation_type_parking.observe()
    return bool(parking._is_success(obs["achieved_goal"], obs["desired_goal"]))


def replay(seed: int, actions: list[list[float]], render_mode: str | None = None) -> tuple[Array, bool, Any]:
    """Run logged ``actions`` in a fresh ``parking-v0`` reset with ``seed``: the final world
    configuration (rear axle, heading, steering), whether the car crashed, and the env."""
    env = _make_env(render_mode)
    env.reset(seed=seed)
    for action in actions:
        env.step(np.array(action, dtype=np.float64))
    vehicle = env.unwrapped.vehicle
    return _pose(vehicle), bool(vehicle.crashed), env


@dataclass(frozen=True)
class HighwayPlantConfig:
    model: Literal["highway_parking"]
    seed: int  # parking-v0's reset seed: the car's start and the goal (task.start, task.goal must be its)

    kind: ClassVar[PlantKind] = HIGHWAY
    plant_class: ClassVar[type] = HighwayParkingPlant
    dimension: ClassVar[int] = 4
    steering_limit: ClassVar[float] = STEERING

    def __post_init__(self) -> None:
        require(
            isinstance(self.seed, int) and 0 <= self.seed < SEEDS, "seed", f"must be in [0, 2**31), got {self.seed}"
        )

    def nominal_map(self) -> CarModel:
        """The geometry the controller assumes (see the module)."""
        return nominal_map()

    def plant(self) -> HighwayParkingPlant:
        return HighwayParkingPlant(self.seed)

    def check_task(self, max_step: float, cyclic: bool) -> None:
        if cyclic:
            raise BadInput("highway_parking is a one-trial task (parking-v0 resets the car for each trial)")
