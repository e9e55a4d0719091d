"""The boxes a learner searches, in the env's physical units: the residual box around the nominal
solution under ``prior="nominal"``, and the wrapper that maps actions in ``[-1, 1]`` into a box.

They sit below the envs and the agents (only the nominal model and Gymnasium's spaces beneath
them): the agents build their search from them, and
:class:`~ilc_steering.envs.wrappers.ResidualAction` offers the same box to any user, without an
agent reaching an env or an env an agent.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
import numpy.typing as npt
from gymnasium import spaces

from ilc_steering.core.nominal import NominalModel

__all__ = ["RESIDUAL_SCALE", "SearchBox", "action_box", "residual_box"]

Array = npt.NDArray[np.float64]

RESIDUAL_SCALE = 0.3
"""Half-width of the residual search box under ``prior="nominal"``, in units of
``NominalModel.action_scale()``: the true solution of every packaged task lies within 0.21 of it
(forward parking 0.10, the saturated task 0.21, parallel parking 0.09, the chained plant 0.09)."""


def action_box(high: npt.ArrayLike) -> spaces.Box:
    """The env's action box ``[-high, high]`` [physical units] as a float32 ``Box`` that holds every
    float64 value of it: each bound rounded *outward* to float32, never inward.

    A bound such as ``10 * action_scale()`` is computed in float64, and its last bits differ from
    one CPU to another (the BLAS kernel, FMA). Rounded to the nearest float32, it falls below the
    float64 value on some machines, and an action on the documented edge (``ResidualAction`` with
    ``scale=9``) would be clipped there and not here. Rounded outward, the edge is inside the box on
    every machine; what lies past it by more than a float32 step is clipped everywhere."""
    bound = np.asarray(high, dtype=np.float64)
    rounded = bound.astype(np.float32)
    below = rounded.astype(np.float64) < bound
    rounded[below] = np.nextafter(rounded[below], np.float32(np.inf))
    return spaces.Box(-rounded, rounded, dtype=np.float32)


def residual_box(model: NominalModel, action_space: spaces.Box) -> tuple[Array, Array]:
    """Centre and half-widths [physical units] of the residual box under ``prior="nominal"``: the
    nominal solution (clipped to ``action_space``) and :data:`RESIDUAL_SCALE` times its action scale."""
    low = np.asarray(action_space.low, dtype=np.float64)
    high = np.asarray(action_space.high, dtype=np.float64)
    return np.clip(model.solve(), low, high), RESIDUAL_SCALE * model.action_scale()


class SearchBox(gym.ActionWrapper[Any, Any, Any]):
    """Actions ``a`` in ``[-1, 1]`` for coefficients ``c = centre + half * a`` [physical units]:
    the residual box around the nominal solution, or the whole action box
    (:meth:`~ilc_steering.agents.base.LearnerContext.search_box`)."""

    def __init__(self, env: gym.Env[Any, Any], centre: Array, half: Array) -> None:
        super().__init__(env)
        self.centre = np.asarray(centre, dtype=np.float64)
        self.half = np.asarray(half, dtype=np.float64)
        self.action_space = gym.spaces.Box(np.float32(-1), np.float32(1), shape=self.centre.shape, dtype=np.float32)

    def action(self, action: Any) -> Array:
        return self.centre + self.half * np.clip(np.asarray(action, dtype=np.float64), -1.0, 1.0)
