"""Iterative learning control of nonholonomic robots as Gymnasium environments and agents.

``import ilc_steering`` registers ``ilc_steering/ChainedSteering-v0`` (one trial per episode; its
``vector_entry_point`` runs ``num_envs`` trials per step in one batched call) and
``ilc_steering/CyclicSteering-v0`` (a non-resetting cycle of waypoints; its ``vector_entry_point``
drives ``num_envs`` robots around it in step) and ``ilc_steering/SegmentedSteering-v0`` (a manoeuvre of
several segments in one trial; its ``vector_entry_point`` runs ``num_envs`` manoeuvres per step, a
batched call per segment) with string entry points,
so nothing heavy is imported before ``gym.make``. ``ILCAgent``, ``SteeringConfig`` and
``load_config`` are loaded on first use.
"""

from __future__ import annotations

from importlib import import_module
from typing import Any

from gymnasium.envs.registration import register, registry

__all__ = ["ILCAgent", "SteeringConfig", "load_config"]
__version__ = "0.1.0"

_LAZY = {
    "ILCAgent": "ilc_steering.agents.ilc",
    "SteeringConfig": "ilc_steering.config",
    "load_config": "ilc_steering.config",
}

if "ilc_steering/ChainedSteering-v0" not in registry:
    register(
        id="ilc_steering/ChainedSteering-v0",
        entry_point="ilc_steering.envs.steering_env:ChainedSteeringEnv",
        vector_entry_point="ilc_steering.envs.steering_vector_env:ChainedSteeringVectorEnv",
    )
if "ilc_steering/CyclicSteering-v0" not in registry:
    register(
        id="ilc_steering/CyclicSteering-v0",
        entry_point="ilc_steering.envs.cyclic_env:make_cyclic_env",
        vector_entry_point="ilc_steering.envs.cyclic_vector_env:CyclicSteeringVectorEnv",
    )
if "ilc_steering/SegmentedSteering-v0" not in registry:
    register(
        id="ilc_steering/SegmentedSteering-v0",
        entry_point="ilc_steering.envs.segmented_env:SegmentedSteeringEnv",
        vector_entry_point="ilc_steering.envs.segmented_vector_env:SegmentedSteeringVectorEnv",
    )


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        return getattr(import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'ilc_steering' has no attribute {name!r}")
