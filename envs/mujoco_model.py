r"""The MuJoCo car's body: its MJCF, its build, the Ackermann linkage, and MuJoCo's model and data of it.

The car is written as MJCF (:func:`mjcf`, a template filled from the config's geometry): a
chassis on a free joint, four wheels touching a floor plane through MuJoCo's soft contacts with
Coulomb friction (elliptic cones), a position-controlled steering linkage on the front wheels
(one hinge per wheel about the vertical, its angle set by the Ackermann rule :func:`ackermann`
from the bicycle angle ``phi``) and velocity-controlled rear wheels. The wheels are thin
ellipsoids, which touch the floor at one point: a cylinder touches it at its two rims, whose
friction scrubs in every turn (with cylinders the nominal forward parking ended 3.1 cm from the
kinematic car's end, with ellipsoids 1.8 cm). At the paper's scale: wheelbase ``ell`` = 0.2 m,
wheel radius ``rho`` = 0.02 m, track 0.12 m, a 1 kg chassis on 30 g wheels (section 5,
``configs/forward_parking.yaml``). The plant that drives it is :mod:`ilc_steering.envs.mujoco_car`.

## Why a template string

The MJCF lives here as a string filled from the config (wheelbase, wheel radius, track,
friction, contact stiffness): the geometry the controller is told and the one MuJoCo simulates
are then the same numbers by construction; ``mjcf(config)`` prints the file for MuJoCo's own viewer.
"""

from __future__ import annotations

from math import atan, tan
from typing import Any

from ilc_steering.errors import ConfigError

__all__ = ["STEER_JOINT_RANGE", "WHEELS", "WHEEL_HALF_WIDTH", "MujocoSim", "ackermann", "bicycle_angle", "mjcf"]

STEER_JOINT_RANGE = 1.5
"""[rad] the front wheels' hinge stops (past any wheel angle :func:`ackermann` asks within the limit)."""
WHEEL_HALF_WIDTH = 0.4
"""A wheel's half-width, in wheel radii."""


def ackermann(phi: float, wheelbase: float, track: float) -> tuple[float, float]:
    r"""The left and right front wheels' angles [rad] of a bicycle angle ``phi`` [rad] (Ackermann:
    both wheels' axes through the turn's centre on the rear axle, :math:`\cot\delta_{l,r} =
    \cot\phi \mp w / (2\ell)`), for ``wheelbase`` ``ell`` and ``track`` ``w`` [m]."""
    t = tan(phi)
    half = 0.5 * track
    return atan(wheelbase * t / (wheelbase - half * t)), atan(wheelbase * t / (wheelbase + half * t))


def bicycle_angle(left: float, right: float, wheelbase: float, track: float) -> float:
    """The bicycle angle ``phi`` [rad] of measured front wheel angles [rad] (:func:`ackermann`
    inverted for each wheel, averaged)."""
    half = 0.5 * track
    tl, tr = tan(left), tan(right)
    return 0.5 * (atan(wheelbase * tl / (wheelbase + half * tl)) + atan(wheelbase * tr / (wheelbase - half * tr)))


_MJCF = """<mujoco model="ilc_steering car">
  <compiler angle="radian" autolimits="true"/>
  <option timestep="{timestep}" integrator="implicitfast" cone="elliptic"/>
  <default>
    <geom contype="0" conaffinity="0"/>
    <default class="wheel">
      <geom type="ellipsoid" size="{rho} {rho} {half_width}" zaxis="0 1 0" mass="{wheel_mass}" contype="1"
            conaffinity="0" friction="{friction} 0 0" condim="3" solref="{contact_time} 1"/>
    </default>
  </default>
  <worldbody>
    <geom name="floor" type="plane" size="0 0 1" conaffinity="1" friction="0 0 0" solref="{contact_time} 1"/>
    <body name="chassis" pos="0 0 {rho}">
      <freejoint name="root"/>
      <geom name="body" type="box" pos="{body_x} 0 {body_z}" size="{body_half} {body_width} 0.008" mass="{mass}"/>
      <body name="rear_left" pos="0 {half_track} 0">
        <joint name="rear_left" axis="0 1 0" armature="{drive_armature}"/>
        <geom name="rear_left" class="wheel"/>
      </body>
      <body name="rear_right" pos="0 -{half_track} 0">
        <joint name="rear_right" axis="0 1 0" armature="{drive_armature}"/>
        <geom name="rear_right" class="wheel"/>
      </body>
{steer_left}{steer_right}    </body>
  </worldbody>
  <actuator>
    <position name="steer_left" joint="steer_left" kp="{steer_kp}" dampratio="1"/>
    <position name="steer_right" joint="steer_right" kp="{steer_kp}" dampratio="1"/>
    <velocity name="drive_left" joint="rear_left" kv="{drive_kv}" forcerange="-{drive_torque} {drive_torque}"/>
    <velocity name="drive_right" joint="rear_right" kv="{drive_kv}" forcerange="-{drive_torque} {drive_torque}"/>
  </actuator>
</mujoco>
"""
_STEERED = """      <body name="steer_{side}" pos="{ell} {y} 0">
        <inertial pos="0 0 0" mass="0.005" diaginertia="1e-6 1e-6 1e-6"/>
        <joint name="steer_{side}" axis="0 0 1" range="-{steer_range} {steer_range}" armature="{steer_armature}"/>
        <body name="front_{side}">
          <joint name="front_{side}" axis="0 1 0"/>
          <geom name="front_{side}" class="wheel"/>
        </body>
      </body>
"""
"""A front wheel on its kingpin, ``side`` left or right at ``y`` [m] (the MJCF's ``steer_left`` and ``steer_right``)."""
WHEELS = ("rear_left", "rear_right", "front_left", "front_right")
"""The wheels' geom names, in the order of a trial's logged friction coefficients."""
# The robot's build, beside its config keys: a 1 kg chassis on 30 g wheels, motors through gearboxes.
WHEEL_MASS = 0.03
"""[kg] each wheel."""
DRIVE_KV = 0.05
"""[N m s/rad] the rear wheels' velocity servo gain (torque per rad/s of speed error)."""
DRIVE_TORQUE = 0.1
"""[N m] the rear motors' torque limit."""
DRIVE_ARMATURE = 1e-5
"""[kg m²] the drive gearbox's reflected inertia on each rear wheel's axle."""
STEER_KP = 20.0
"""[N m/rad] the steering servos' stiffness (critically damped)."""
STEER_ARMATURE = 1e-4
"""[kg m²] the steering gearbox's reflected inertia on each kingpin."""


def mjcf(config: Any) -> str:
    """The car's MJCF (MuJoCo's XML) for ``config`` (a :class:`~ilc_steering.envs.mujoco_car.MujocoCarConfig`,
    which imports this module): its geometry, contact and build (see the module)."""
    ell, rho = config.wheelbase, config.wheel_radius
    half_track = 0.5 * config.track
    steered = {
        f"steer_{side}": _STEERED.format(
            side=side, ell=ell, y=y, steer_range=STEER_JOINT_RANGE, steer_armature=STEER_ARMATURE
        )
        for side, y in (("left", f"{half_track}"), ("right", f"-{half_track}"))
    }
    return _MJCF.format(
        **steered,
        timestep=config.timestep,
        rho=rho,
        half_width=WHEEL_HALF_WIDTH * rho,
        wheel_mass=WHEEL_MASS,
        friction=config.friction,
        contact_time=config.contact_time,
        body_x=0.5 * ell,
        body_z=0.5 * rho,
        body_half=0.65 * ell,
        body_width=0.5 * config.track - 0.6 * rho,
        mass=config.mass,
        half_track=half_track,
        ell=ell,
        steer_range=STEER_JOINT_RANGE,
        drive_armature=DRIVE_ARMATURE,
        steer_armature=STEER_ARMATURE,
        steer_kp=STEER_KP,
        drive_kv=DRIVE_KV,
        drive_torque=DRIVE_TORQUE,
    )


def _load_mujoco() -> Any:
    try:
        import mujoco
    except ImportError:
        raise ConfigError('mujoco_car needs MuJoCo: pip install "ilc-steering[mujoco]"') from None
    return mujoco


class MujocoSim:
    """MuJoCo's model and data of one plant, with the addresses the adapter reads and writes."""

    def __init__(self, config: Any) -> None:
        mujoco = _load_mujoco()
        self.mujoco = mujoco
        self.model = mujoco.MjModel.from_xml_string(mjcf(config))
        self.data = mujoco.MjData(self.model)
        model = self.model
        self.chassis = model.body("chassis").id
        self.steer = [model.joint(name).qposadr[0] for name in ("steer_left", "steer_right")]
        self.wheels = [model.geom(name).id for name in WHEELS]
        self.height = self._settle(config)

    def _settle(self, config: Any) -> float:
        """The chassis' height [m] at rest on its tyres (they sink into the soft floor): the car is
        dropped from ``rho`` and held still for 0.5 s, once per plant."""
        mujoco, data = self.mujoco, self.data
        mujoco.mj_resetData(self.model, data)
        mujoco.mj_step(self.model, data, nstep=round(0.5 / config.timestep))
        return float(data.qpos[2])
