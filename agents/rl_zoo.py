"""RL Zoo's side of the RL baselines: what the hyperparameter files of ``configs/rl_zoo/`` name
beside an algorithm's own keys, so that ``python -m rl_zoo3.train`` trains a baseline as
:func:`ilc_steering.agents.rl.train` does under ``prior="nominal"`` (docs/usage.md, "Train with
RL Zoo"; the ``zoo`` extra).

- ``env_wrapper``: :class:`~ilc_steering.envs.wrappers.ResidualAction` (the residual box around
  the nominal solution; :class:`SegmentedResidualAction` for the segmented env), then
  :class:`LogReward` (the reward ``-log10(cost)``);
- ``callback``: :class:`StartAtCentre` (``start_at_centre`` and ``initial_std`` of
  ``configs/rl/``: the first policy acts at the nominal solution).

The files themselves: :func:`~ilc_steering.agents.rl_settings.zoo_file`.
"""

from __future__ import annotations

from typing import Any, SupportsFloat

import gymnasium as gym
import numpy as np
from stable_baselines3.common.callbacks import BaseCallback

from ilc_steering.agents.rl import log_reward, start_at_centre
from ilc_steering.agents.rl_settings import RL_ALGORITHMS, check_value, facts, squashed
from ilc_steering.boxes import SearchBox, residual_box
from ilc_steering.envs.segmented_env import SegmentedSteeringEnv
from ilc_steering.errors import BadInput

__all__ = ["LogReward", "SegmentedResidualAction", "StartAtCentre"]


class LogReward(gym.RewardWrapper[Any, Any]):
    """The reward ``-log10(cost)`` of a trial whose env reward is ``-cost``
    (:func:`~ilc_steering.agents.rl.log_reward`), as the library's RL baselines are trained: a
    tenfold improvement is worth the same at every scale."""

    def reward(self, reward: SupportsFloat) -> float:
        return log_reward(reward)


class SegmentedResidualAction(SearchBox):
    """Actions in ``[-1, 1]`` for ``ilc_steering/SegmentedSteering-v0``: each segment's residual
    box around its nominal solution (:func:`~ilc_steering.boxes.residual_box` of its view, the box
    its own learner searches in a comparison), concatenated in the env's order. ``a = 0`` is
    every segment's nominal solution."""

    def __init__(self, env: gym.Env[Any, Any]) -> None:
        owner = env.unwrapped
        if not isinstance(owner, SegmentedSteeringEnv):
            raise BadInput(
                f"SegmentedResidualAction wraps ilc_steering/SegmentedSteering-v0, got {type(owner).__name__}; "
                "for the one-trial and the cyclic env, use ilc_steering.envs.ResidualAction"
            )
        boxes = [residual_box(view.nominal_model, view.action_space) for view in owner.segment_views()]
        super().__init__(env, np.concatenate([c for c, _ in boxes]), np.concatenate([h for _, h in boxes]))


class StartAtCentre(BaseCallback):
    """Zero the policy's output layer before the first trial, so that its first deterministic
    action is the search box's centre, the nominal solution (``start_at_centre: true`` of
    ``configs/rl/``; :func:`~ilc_steering.agents.rl.start_at_centre`); ``initial_std``: the first
    spread of a squashed-Gaussian policy (SAC, CrossQ, TQC) [search units].

    A model that has been trained (RL Zoo's ``--trained-agent``) is left as it is: the callback
    acts on a model that has made no update yet."""

    def __init__(self, initial_std: float | None = None, verbose: int = 0) -> None:
        super().__init__(verbose)
        if initial_std is not None:
            initial_std = check_value("initial_std", initial_std, "StartAtCentre.initial_std")
        self.initial_std = initial_std

    def _init_callback(self) -> None:
        name = type(self.model).__name__
        found = [a for a in RL_ALGORITHMS if facts(a).class_name == name]
        if not found:
            known = ", ".join(facts(a).class_name for a in RL_ALGORITHMS)
            raise BadInput(f"StartAtCentre: {name} is none of the RL baselines ({known})")
        algorithm = found[0]
        if self.initial_std is not None and not squashed(algorithm):
            raise BadInput(f"StartAtCentre: initial_std is for a squashed-Gaussian policy, not {name}'s")
        # SB3 counts a model's updates and saves the count with it: a loaded, trained model has some
        if self.model._n_updates == 0:
            start_at_centre(self.model, algorithm, "sb3", self.initial_std)

    def _on_step(self) -> bool:
        return True
