"""The environments: one trial per episode, N trials per vector step, the cyclic task, and ``ResidualAction``.

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
]

_LAZY = {
    "ChainedSteeringEnv": "ilc_steering.envs.steering_env",
    "ChainedSteeringVectorEnv": "ilc_steering.envs.steering_vector_env",
    "CyclicSteeringEnv": "ilc_steering.envs.cyclic_env",
    "CyclicSteeringVectorEnv": "ilc_steering.envs.cyclic_vector_env",
    "ResidualAction": "ilc_steering.envs.wrappers",
    "Scenario": "ilc_steering.envs.scenario",
}


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        return getattr(import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'ilc_steering.envs' has no attribute {name!r}")
