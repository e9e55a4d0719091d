"""Iterative learning control of nonholonomic robots as Gymnasium environments and agents.

``import ilc_steering`` registers the environments (``ilc_steering/ChainedSteering-v0``).
"""

from ilc_steering import envs
from ilc_steering.agents import ILCAgent
from ilc_steering.config import SteeringConfig, load_config

__all__ = ["ILCAgent", "SteeringConfig", "envs", "load_config"]
__version__ = "0.1.0"
