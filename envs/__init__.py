"""The environments: one trial per episode, N trials per vector step, the cyclic task, the manoeuvre, and
``ResidualAction``.

The env ids are registered by ``import ilc_steering``; the classes here are loaded on first use.
"""

from __future__ import annotations

from importlib import import_module
from typing import Any

__all__ = [
    "ChainedSteeringEnv",
    "ChainedSteeringVectorEnv",
    "CyclicSteeringEnv",
    "CyclicSteeringVectorEnv",
    "ResidualAction",
    "Scenario",
    "SegmentedSteeringEnv",
    "SegmentedSteeringVectorEnv",
]

_LAZY = {
    "ChainedSteeringEnv": "ilc_steering.envs.steering_env",
    "ChainedSteeringVectorEnv": "ilc_steering.envs.steering_vector_env",
    "CyclicSteeringEnv": "ilc_steering.envs.cyclic_env",
    "CyclicSteeringVectorEnv": "ilc_steering.envs.cyclic_vector_env",
    "ResidualAction": "ilc_steering.envs.wrappers",
    "Scenario": "ilc_steering.envs.scenario",
    "SegmentedSteeringEnv": "ilc_steering.envs.segmented_env",
    "SegmentedSteeringVectorEnv": "ilc_steering.envs.segmented_vector_env",
}


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        return getattr(import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'ilc_steering.envs' has no attribute {name!r}")
