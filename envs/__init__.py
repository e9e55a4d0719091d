"""Environments and the mathematics they share: chained form, input profiles, car, integrator.

Importing this package registers ``ilc_steering/ChainedSteering-v0`` with Gymnasium.
"""

from gymnasium.envs.registration import register, registry

from ilc_steering.envs.scenario import NominalModel
from ilc_steering.envs.steering_env import ChainedSteeringEnv

__all__ = ["ChainedSteeringEnv", "NominalModel"]

if "ilc_steering/ChainedSteering-v0" not in registry:
    register(id="ilc_steering/ChainedSteering-v0", entry_point="ilc_steering.envs.steering_env:ChainedSteeringEnv")
