"""One trial as an env reports it: the spaces of a one-trial task, its ``info`` and its reward.

Shared by the one-trial env, its vector entry point, the cyclic and segmented envs and a map's
oracle: the observation is the task (start and goal in chained coordinates), the action the
coefficients ``c`` of eqs. 15-17 in the env's box (:func:`~ilc_steering.boxes.action_box`), the
``info`` what :meth:`~ilc_steering.envs.scenario.Scenario.measure` measured with the action as
applied and whether it was clipped, the reward minus the weighted final error.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
import numpy.typing as npt

from ilc_steering.boxes import action_box
from ilc_steering.core.nominal import NominalModel
from ilc_steering.core.score import TRUE_KEYS, trial_cost
from ilc_steering.envs.scenario import Scenario

__all__ = ["action_names", "reward", "task_spaces", "trial_info", "trial_infos"]

Array = npt.NDArray[np.float64]


def trial_infos(measured: dict[str, Array], applied: Array, requested: Array) -> dict[str, Array]:
    """The per-trial ``info`` of a batch (arrays with a leading batch axis), from
    ``Scenario.measure`` and the actions as applied (clipped) and as requested."""
    return {**measured, "action": applied, "clipped": np.any(applied != requested, axis=-1)}


def trial_info(measured: dict[str, Array], applied: Array, requested: Array) -> dict[str, Any]:
    """The ``info`` of one trial from a batch-of-one measurement, with Python scalars."""
    info: dict[str, Any] = {k: v[0] for k, v in trial_infos(measured, applied[None], requested[None]).items()}
    for key in ("error_norm", "cartesian_error", "orientation_error", *TRUE_KEYS):
        if key in info:
            info[key] = float(info[key])
    for key in ("left_chart", "clipped"):
        info[key] = bool(info[key])
    return info


def task_spaces(scenario: Scenario) -> tuple[gym.spaces.Box, gym.spaces.Box, npt.NDArray[np.float32]]:
    """The action space, observation space and (constant) observation of a one-trial task."""
    model = scenario.nominal
    observation = np.concatenate([model.z_start, model.z_goal]).astype(np.float32)
    limit = np.float32(10.0 * (np.abs(observation).max() + 1.0))
    observation_space = gym.spaces.Box(-limit, limit, shape=observation.shape, dtype=np.float32)
    return action_box(scenario.action_high), observation_space, observation


def action_names(model: NominalModel) -> str:
    """``"(c11, c21..c2q)"``, for error messages."""
    q = model.profile.v2_terms
    return f"(c11, c21..c2{q})" if q > 1 else "(c11, c21)"


def reward(info: dict[str, Any]) -> Any:
    """Minus the weighted final error, for one trial's ``info`` or a batch's (see the ``## Rewards``
    section of :class:`~ilc_steering.envs.steering_env.ChainedSteeringEnv`)."""
    return -trial_cost(info)
