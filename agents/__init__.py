"""Learners that drive the steering environments."""

from ilc_steering.agents.ilc import ILCAgent

__all__ = ["ILCAgent"]
