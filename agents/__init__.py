"""Learners that drive the steering environments, and the :class:`Learner` protocol they meet.

``ILCAgent`` and ``CyclicILCAgent`` need only the nominal model (numpy). The baselines are
imported from their modules: :mod:`ilc_steering.agents.newton` (numpy),
:mod:`ilc_steering.agents.blackbox` (scipy, ``cma``) and :mod:`ilc_steering.agents.rl`
(Stable-Baselines3).
"""

from ilc_steering.agents.base import Learner, LearnerContext, LearnerFactory
from ilc_steering.agents.cyclic_ilc import CyclicILCAgent
from ilc_steering.agents.ilc import ILCAgent

__all__ = ["CyclicILCAgent", "ILCAgent", "Learner", "LearnerContext", "LearnerFactory"]
