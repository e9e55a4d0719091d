r"""A car-like robot in MuJoCo as an external plant: wheels that roll on contacts, slip and scatter.

## Description

The car's body is :mod:`ilc_steering.envs.mujoco_model`: an MJCF (:func:`~ilc_steering.envs.mujoco_model.mjcf`)
of a chassis on a free joint, four wheels on MuJoCo's soft contacts with Coulomb friction, a
position-controlled Ackermann steering linkage on the front wheels and velocity-controlled rear
wheels (an electronic differential: each wheel's speed is the one that rolls it without slip on
the bicycle's turn), at the paper's scale (wheelbase ``ell`` = 0.2 m, wheel radius ``rho`` =
0.02 m, track 0.12 m, a 1 kg chassis on 30 g wheels). This module is the plant that drives it
and its config keys.

:class:`MujocoCarPlant` runs one trial as highway's adapter does (:mod:`ilc_steering.envs.highway`):
every ``control_period`` it measures the car (the rear axle's midpoint [m], the chassis' heading
[rad], the steering angle of the linkage [rad]) in the task frame and follows the chained-form
inputs ``v1(t)``, ``v2(t)`` of the trial's profile and coefficients through the nominal closed
loop (eqs. 3-5 with the nominal geometry, RK4 over the period from the measured pose and the
steering command it integrates from ``u2``): the steering target is the command at the period's
end, the rear wheels' speed is ``u1`` [rad/s] of eq. 5 at mid-period. MuJoCo then steps the
physics (``timestep``, implicit-in-velocity ``implicitfast``). The final configuration is the
measured one: the pose and the linkage's bicycle angle (:func:`~ilc_steering.envs.mujoco_model.bicycle_angle`).

**The controller's nominal car** is the MJCF's geometry (:class:`~ilc_steering.core.robots.car.CarModel`
of ``wheelbase``, ``wheel_radius``). What differs is everything outside a geometry: the car
spins up from rest through motors of finite torque (the paper's ``v1`` jumps to its level at
``t = 0``), the tyres creep on their soft contacts (and sink 0.01 mm into the floor), the
steering servos lag, the car rocks on its contacts. On the packaged forward parking the nominal
solution ends 1.8 cm and 12 mrad from where the kinematic car of eqs. 3-5 ends.

## Scatter

With ``friction_spread`` > 0 every trial draws each wheel's friction coefficient anew, log-normal
around ``friction`` with that relative spread: near the grip limit the car slides a little
differently each time, so the same commands end a few millimetres apart. The draws come from a
generator of the plant's own, seeded by the config's ``seed`` until the env is reset with a seed
(``reset(seed=s)``: ``run_ilc(seed=s)``, each of ``compare``'s seeds), which restarts it from ``s``
and ``seed`` together (:meth:`MujocoCarPlant.reseed`,
:func:`~ilc_steering.core.external.plant_generator`, a stream apart from the env's measurement
noise): the same seed gives the same trials, another seed another draw; the trials within a run
differ. With ``friction_spread`` = 0 the plant repeats itself bit for bit.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from math import cos, isfinite, pi, sin, tan
from typing import Any, ClassVar, Literal

import numpy as np
import numpy.typing as npt

from ilc_steering.core.checks import require, require_length
from ilc_steering.core.external import ExternalPlantBase, ExternalTrials, chart_status, plant_generator
from ilc_steering.core.integrate import OK
from ilc_steering.core.plants import PlantKind, check_angles, check_limit, check_magnitude
from ilc_steering.core.profiles import InputProfile
from ilc_steering.core.robots.car import CAR, CarModel, car_velocity, chained_inputs, check_chart, rotate
from ilc_steering.envs.mujoco_model import (
    STEER_JOINT_RANGE,
    WHEEL_HALF_WIDTH,
    WHEELS,
    MujocoSim,
    ackermann,
    bicycle_angle,
    mjcf,
)
from ilc_steering.errors import ConfigError

__all__ = ["MUJOCO_CAR", "MujocoCarConfig", "MujocoCarPlant", "ackermann", "bicycle_angle", "mjcf"]

Array = npt.NDArray[np.float64]

MUJOCO_CAR = PlantKind("mujoco_car", True, CAR.coordinates, CAR.inputs)
"""A car (the library's configuration, rear axle first), stepped by MuJoCo."""
SUBSTEPS = 2
"""RK4 steps of the nominal closed loop over one control period (the adapter's prediction)."""
MASS_RANGE = (0.01, 100.0)
"""[kg] the chassis' mass a config may give."""
MAX_FRICTION = 5.0
"""The largest tyre-floor friction coefficient a config may give [-]."""
MAX_FRICTION_SPREAD = 1.0
"""The largest relative spread of the wheels' friction per trial [-]."""
TIMESTEP_RANGE = (1e-4, 5e-3)
"""[s] MuJoCo's step a config may give."""
MAX_CONTACT_TIME = 0.1
"""[s] the softest contact (MuJoCo's ``solref`` time constant) a config may give."""
MAX_STEPS_PER_PERIOD = 1000
"""The most MuJoCo steps in one control period."""


@dataclass
class _Shared:
    """What a plant and its copies in other frames share: the simulator (made on first use), the
    scatter's generator and the counts of trials run and of MuJoCo steps taken."""

    sims: list[MujocoSim] = field(default_factory=list)
    rng: list[np.random.Generator] = field(default_factory=list)
    env_seed: int | None = None
    """The env's seed the generator was last restarted from (``None``: the config's ``seed`` alone)."""
    trials: int = 0
    steps: int = 0


@dataclass(frozen=True)
class MujocoCarPlant(ExternalPlantBase):
    """The MuJoCo car of ``config``, reporting the library's configuration in the task frame (the
    world rotated by ``frame`` [rad]). See the module for the adapter and the scatter."""

    kind: ClassVar[PlantKind] = MUJOCO_CAR
    factor_names: ClassVar[tuple[str, str]] = ("wheelbase_ratio", "wheel_radius_ratio")
    name: ClassVar[str] = "the MuJoCo car"
    state_dim: ClassVar[int] = 4
    config: MujocoCarConfig
    frame: float = 0.0
    shared: _Shared = field(default_factory=_Shared, compare=False, repr=False)
    """The simulator, the scatter's generator (``config.seed``; :meth:`reseed` restarts it) and the counts."""

    @property
    def steering_limit(self) -> float:
        return self.config.steering_limit

    @property
    def sim(self) -> MujocoSim:
        """MuJoCo's model and data of this car (made on first use)."""
        if not self.shared.sims:
            self.shared.sims.append(MujocoSim(self.config))
        return self.shared.sims[0]

    def with_frame(self, angle: float) -> MujocoCarPlant:
        return replace(self, frame=float(angle), shared=self.shared)

    def check_configuration(self, q: Array) -> None:
        check_chart(q)
        check_magnitude(q)
        check_angles(q, "|theta| and |phi|")
        check_limit(np.asarray(q, dtype=np.float64)[..., 3], self.steering_limit)

    def draw_friction(self) -> Array:
        """The wheels' friction coefficients of the next trial (:data:`WHEELS` order): ``friction``
        times a log-normal factor of relative spread ``friction_spread``, from the seeded generator."""
        config = self.config
        if not config.friction_spread:
            return np.full(len(WHEELS), config.friction)
        if not self.shared.rng:  # no env seed given yet: the config's seed alone
            self.shared.rng.append(np.random.default_rng(config.seed))
        return config.friction * np.exp(config.friction_spread * self.shared.rng[0].standard_normal(len(WHEELS)))

    def reseed(self, seed: int) -> None:
        """Restart the scatter's draws from the env's ``seed`` and the config's ``seed`` together
        (:func:`~ilc_steering.core.external.plant_generator`), for this plant and its copies in other frames."""
        self.shared.rng[:] = [plant_generator(seed, self.config.seed)]
        self.shared.env_seed = int(seed)

    def control_period(self) -> float:
        return float(self.config.control_period)

    def run_trials(self, profile: InputProfile, x0: Array, c: Array, record: bool = False) -> ExternalTrials:
        """The base's, a task whose pieces are no whole number of control periods refused as the
        config's error (exit 2, nothing run), not the plant's failure."""
        total, period = sum(profile.durations), self.control_period()
        if abs(round(total / period) * period - total) >= 1e-9:
            raise ConfigError(
                f"task.pieces: add up to {total:g} s, not a whole number of {self.name}'s control periods "
                f"(plant.control_period = {period:g} s); make each piece a multiple of it"
            )
        return super().run_trials(profile, x0, c, record)

    def _measure(self, sim: MujocoSim) -> Array:
        """The car's configuration in the task frame: the rear axle's midpoint [m], the chassis'
        heading wrapped to ``(-pi, pi]`` and the linkage's bicycle angle [rad]."""
        data, config = sim.data, self.config
        x, y = data.xpos[sim.chassis, :2]
        r = data.xmat[sim.chassis]
        phi = bicycle_angle(data.qpos[sim.steer[0]], data.qpos[sim.steer[1]], config.wheelbase, config.track)
        q = rotate(np.array([x, y, np.arctan2(r[3], r[0]), phi]), self.frame)
        q[2] = np.angle(np.exp(1j * q[2]))
        return q

    def _place(self, sim: MujocoSim, q: Array) -> None:
        """The car at rest at world configuration ``q``, its tyres sunk to their resting depth."""
        mujoco, model, data, config = sim.mujoco, sim.model, sim.data, self.config
        mujoco.mj_resetData(model, data)
        data.qpos[:3] = q[0], q[1], sim.height
        data.qpos[3:7] = cos(0.5 * q[2]), 0.0, 0.0, sin(0.5 * q[2])
        wheels = ackermann(float(q[3]), config.wheelbase, config.track)
        data.qpos[sim.steer] = wheels
        data.ctrl[:2] = wheels
        mujoco.mj_forward(model, data)

    def trial(
        self, profile: InputProfile, x0: Array, c: Array, periods: int
    ) -> tuple[Array, int, Array, dict[str, Any]]:
        sim, config = self.sim, self.config
        friction = self.draw_friction()
        sim.model.geom_friction[sim.wheels, 0] = friction
        self._place(sim, rotate(x0, -self.frame))
        self.shared.trials += 1
        period, limit = config.control_period, config.steering_limit
        ell, half = config.wheelbase, 0.5 * config.track
        nstep = round(period / config.timestep)
        # every RK4 stage falls on a half step: the inputs of the whole trial in one call
        h = period / SUBSTEPS
        v1s, v2s = profile.evaluate(c, 0.5 * h * np.arange(2 * SUBSTEPS * periods + 1, dtype=np.float64))
        q = self._measure(sim)
        states = [q]
        status, halted = OK, q
        command = float(x0[3])  # the steering command the adapter integrates from u2 (the servo's state)
        for k in range(periods):
            status, halted = chart_status(q, states, status, halted)
            if status == OK:
                acted_on = np.array([q[0], q[1], q[2], command])
                command, u1, phi_mid = self._follow(v1s, v2s, 2 * SUBSTEPS * k, acted_on)
                spin = half * tan(phi_mid) / ell  # the electronic differential: each wheel rolls on the turn
                left, right = ackermann(min(max(command, -limit), limit), ell, config.track)
                sim.data.ctrl[:] = left, right, u1 * (1 - spin), u1 * (1 + spin)
            else:  # out of the chart, eqs. 4-5 break down: stop the wheels, hold the steering
                sim.data.ctrl[2:] = 0.0
            sim.mujoco.mj_step(sim.model, sim.data, nstep=nstep)
            self.shared.steps += nstep
            q = self._measure(sim)
            states.append(q)
        final = q if status == OK else halted
        log = {"seed": config.seed, "env_seed": self.shared.env_seed, "friction": friction.tolist()}
        return final, status, np.array(states), log

    def _follow(self, v1s: Array, v2s: Array, first: int, q: Array) -> tuple[float, float, float]:
        """The nominal closed loop (eqs. 3-5, nominal geometry, the wheel at the stop beyond
        ``steering_limit`` while the command winds on) from ``q`` (its ``phi`` the adapter's
        steering command) over one control period by RK4, the inputs from ``v1s[first:]``: the
        steering command at the end [rad], the rear wheels' speed ``u1`` of eq. 5 [rad/s] and the
        steering angle [rad] at mid-period."""
        config = self.config
        ell, rho, limit = config.wheelbase, config.wheel_radius, config.steering_limit
        h = config.control_period / SUBSTEPS

        def field_(i: int, x: Array) -> Array:
            phi = min(max(x[3], -limit), limit)
            u1, u2 = chained_inputs(x[2], phi, float(v1s[first + i]), float(v2s[first + i]), ell, rho)
            return np.array(car_velocity(x[2], phi, u1, u2, ell, rho))

        x, u1, phi_mid = q.copy(), 0.0, float(q[3])
        for i in range(SUBSTEPS):
            if i == SUBSTEPS // 2:
                phi_mid = min(max(float(x[3]), -limit), limit)
                u1 = float(chained_inputs(x[2], phi_mid, float(v1s[first + 2 * i]), 0.0, ell, rho)[0])
            k1 = field_(2 * i, x)
            k2 = field_(2 * i + 1, x + h / 2 * k1)
            k3 = field_(2 * i + 1, x + h / 2 * k2)
            k4 = field_(2 * i + 2, x + h * k3)
            x = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        return float(x[3]), u1, phi_mid


@dataclass(frozen=True)
class MujocoCarConfig:
    """The MuJoCo car's config keys (``plant.model: mujoco_car``)."""

    model: Literal["mujoco_car"]
    wheelbase: float  # ell [m]: the MJCF's and the controller's
    wheel_radius: float  # rho [m]: the MJCF's and the controller's
    track: float = 0.12  # [m] between the wheels of an axle
    mass: float = 1.0  # [kg] the chassis (the four wheels add 0.12 kg)
    steering_limit: float = 1.2  # [rad] the linkage's stop, as a bicycle angle
    friction: float = 1.0  # tyre-floor Coulomb friction coefficient [-]
    friction_spread: float = 0.0  # relative spread of each wheel's friction, drawn per trial [-]; 0: none
    contact_time: float = 0.005  # [s] MuJoCo's contact time constant (solref): the tyres' softness
    timestep: float = 0.001  # [s] MuJoCo's step
    control_period: float = 0.01  # [s] the adapter measures and commands once per period
    seed: int = 0  # the scatter's generator (friction_spread), with the env's seed

    kind: ClassVar[PlantKind] = MUJOCO_CAR
    plant_class: ClassVar[type] = MujocoCarPlant
    dimension: ClassVar[int] = 4

    def __post_init__(self) -> None:
        require_length("wheelbase", self.wheelbase)
        require_length("wheel_radius", self.wheel_radius)
        require_length("track", self.track)
        require(
            self.track >= 4 * WHEEL_HALF_WIDTH * self.wheel_radius,
            "track",
            f"must leave room for the chassis between the wheels (at least {4 * WHEEL_HALF_WIDTH:g} wheel_radius "
            f"= {4 * WHEEL_HALF_WIDTH * self.wheel_radius:g} m), got {self.track}",
        )
        low, high = MASS_RANGE
        require(
            isfinite(self.mass) and low <= self.mass <= high, "mass", f"must be in [{low}, {high}] kg, got {self.mass}"
        )
        limit = self.steering_limit
        require(
            isfinite(limit) and 0 < limit < pi / 2 and self._inner_wheel(limit) < STEER_JOINT_RANGE,
            "steering_limit",
            f"must be in (0, pi/2) rad with the inner front wheel inside its hinge's {STEER_JOINT_RANGE} rad stop "
            f"(Ackermann with wheelbase {self.wheelbase} m and track {self.track} m), got {limit}",
        )
        friction = self.friction
        require(
            isfinite(friction) and 0 < friction <= MAX_FRICTION,
            "friction",
            f"must be in (0, {MAX_FRICTION}], got {friction}",
        )
        spread = self.friction_spread
        require(
            isfinite(spread) and 0 <= spread <= MAX_FRICTION_SPREAD,
            "friction_spread",
            f"must be in [0, {MAX_FRICTION_SPREAD}], got {spread}",
        )
        low, high = TIMESTEP_RANGE
        require(
            isfinite(self.timestep) and low <= self.timestep <= high,
            "timestep",
            f"must be in [{low}, {high}] s, got {self.timestep}",
        )
        require(
            isfinite(self.contact_time) and 2 * self.timestep <= self.contact_time <= MAX_CONTACT_TIME,
            "contact_time",
            f"must be in [2 * timestep, {MAX_CONTACT_TIME}] = [{2 * self.timestep}, {MAX_CONTACT_TIME}] s "
            f"(a stiffer contact than two steps MuJoCo cannot resolve), got {self.contact_time}",
        )
        steps = self.control_period / self.timestep
        require(
            isfinite(steps) and 1 <= round(steps) <= MAX_STEPS_PER_PERIOD and abs(steps - round(steps)) < 1e-9,
            "control_period",
            f"must be a whole number (1-{MAX_STEPS_PER_PERIOD}) of MuJoCo steps of {self.timestep} s, "
            f"got {self.control_period}",
        )
        require(
            isinstance(self.seed, int) and 0 <= self.seed < 2**31, "seed", f"must be in [0, 2**31), got {self.seed}"
        )

    def _inner_wheel(self, phi: float) -> float:
        """The inner front wheel's angle [rad] at bicycle angle ``phi`` [rad] (``inf`` past 90°)."""
        if 0.5 * self.track * tan(phi) >= self.wheelbase:
            return float("inf")
        return ackermann(phi, self.wheelbase, self.track)[0]

    def nominal_map(self) -> CarModel:
        """The geometry the controller assumes: the MJCF's wheelbase and wheel radius."""
        return CarModel(self.wheelbase, self.wheel_radius)

    def plant(self) -> MujocoCarPlant:
        return MujocoCarPlant(self)

    def check_task(self, max_step: float, cyclic: bool) -> None:
        """Nothing between these keys and the rest of the config (``run_trials`` checks the pieces)."""
