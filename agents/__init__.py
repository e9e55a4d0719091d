"""Learners that drive the steering environments."""

from ilc_steering.agents.cyclic_ilc import CyclicILCAgent
from ilc_steering.agents.ilc import ILCAgent

__all__ = ["CyclicILCAgent", "ILCAgent"]
