"""Environments and the mathematics they share: chained form, input profiles, car, integrator.

Importing this package registers ``ilc_steering/ChainedSteering-v0`` (one trial per episode;
its ``vector_entry_point`` runs ``num_envs`` trials per step in one batched call)
and ``ilc_steering/CyclicSteering-v0`` (a non-resetting cycle of waypoints) with Gymnasium.
"""

from gymnasium.envs.registration import register, registry

from ilc_steering.envs.cyclic_env import CyclicSteeringEnv
from ilc_steering.envs.scenario import NominalModel
from ilc_steering.envs.steering_env import ChainedSteeringEnv
from ilc_steering.envs.steering_vector_env import ChainedSteeringVectorEnv

__all__ = ["ChainedSteeringEnv", "ChainedSteeringVectorEnv", "CyclicSteeringEnv", "NominalModel"]

if "ilc_steering/ChainedSteering-v0" not in registry:
    register(
        id="ilc_steering/ChainedSteering-v0",
        entry_point="ilc_steering.envs.steering_env:ChainedSteeringEnv",
        vector_entry_point="ilc_steering.envs.steering_vector_env:ChainedSteeringVectorEnv",
    )
if "ilc_steering/CyclicSteering-v0" not in registry:
    register(id="ilc_steering/CyclicSteering-v0", entry_point="ilc_steering.envs.cyclic_env:make_cyclic_env")
