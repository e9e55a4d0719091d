"""RL baselines: Stable-Baselines3's PPO, SAC and TD3 on the one-trial env (the ``rl`` extra).

Hyperparameters live in ``configs/rl/<algorithm>.yaml``, one file per algorithm keyed by
scenario (rl-baselines3-zoo style). Every episode is one step and one trial, so:

- a budget of ``B`` trials is ``B`` timesteps; :class:`StopTrainingOnMaxEpisodes` stops there;
- PPO's ``n_steps`` is the number of trials before its first update;
- SAC and TD3 spend their first ``learning_starts`` trials on uniformly random actions;
- ``gamma`` does not matter (there is no next state), and the constant observation makes the
  policy a search over one action: RL solves a bandit here.
"""

from __future__ import annotations

import inspect
from importlib import resources
from typing import Any

import gymnasium as gym
import numpy as np
import yaml

from ilc_steering.agents.adapters import PullLearner
from ilc_steering.agents.base import LearnerContext
from ilc_steering.config import ConfigError

__all__ = ["RL_ALGORITHMS", "check_hyperparameters", "hyperparameters", "make_learner", "train"]

RL_ALGORITHMS = ("ppo", "sac", "td3")
_OWN_KEYS = {"n_timesteps", "noise_std"}  # ours; every other key goes to the SB3 constructor


def _algorithm_class(algorithm: str) -> type[Any]:
    import stable_baselines3

    if algorithm not in RL_ALGORITHMS:
        raise ValueError(f"algorithm must be one of {RL_ALGORITHMS}, got {algorithm!r}")
    return getattr(stable_baselines3, algorithm.upper())  # type: ignore[no-any-return]


def hyperparameters(algorithm: str, scenario: str) -> dict[str, Any]:
    """The hyperparameters of ``algorithm`` for ``scenario`` from the packaged YAML file."""
    source = f"configs/rl/{algorithm}.yaml"
    _algorithm_class(algorithm)
    table = yaml.safe_load((resources.files("ilc_steering.configs") / "rl" / f"{algorithm}.yaml").read_text())
    key = scenario if scenario in table else "default"
    if key not in table:
        raise ConfigError(
            f"{source}: no hyperparameters for scenario {scenario!r} and no default (has {sorted(table)})"
        )
    return check_hyperparameters(algorithm, dict(table[key]), f"{source}: {key}")


def check_hyperparameters(algorithm: str, params: dict[str, Any], where: str) -> dict[str, Any]:
    """``params`` if every key is an argument of the SB3 class (or ours), else :class:`ConfigError`
    naming the key and ``where`` it came from."""
    cls = _algorithm_class(algorithm)
    allowed = set(inspect.signature(cls.__init__).parameters) - {"self", "env"} | _OWN_KEYS
    unknown = sorted(set(params) - allowed)
    if unknown:
        raise ConfigError(f"{where}.{unknown[0]}: unknown key for {cls.__name__}")
    if not isinstance(params.get("n_timesteps"), int) or params["n_timesteps"] < 1:
        raise ConfigError(f"{where}.n_timesteps: the budget must be an integer >= 1 [trials]")
    return params


def train(
    algorithm: str, env: gym.Env[Any, Any], params: dict[str, Any], seed: int, trials: int, progress_bar: bool = False
) -> Any:
    """Train ``algorithm`` on ``env`` (actions in ``[-1, 1]``) for exactly ``trials`` trials."""
    from stable_baselines3.common.callbacks import StopTrainingOnMaxEpisodes
    from stable_baselines3.common.noise import NormalActionNoise

    cls = _algorithm_class(algorithm)
    kwargs = {k: v for k, v in params.items() if k not in _OWN_KEYS}
    if "noise_std" in params:
        (size,) = env.action_space.shape or (0,)
        kwargs["action_noise"] = NormalActionNoise(np.zeros(size), params["noise_std"] * np.ones(size))
    if "learning_starts" in kwargs:
        kwargs["learning_starts"] = min(kwargs["learning_starts"], trials)
    if "n_steps" in kwargs:
        kwargs["n_steps"] = min(kwargs["n_steps"], trials)
        kwargs["batch_size"] = min(kwargs.get("batch_size", 64), kwargs["n_steps"])
    model = cls(env=env, seed=seed, device="cpu", verbose=0, **kwargs)
    model.learn(
        total_timesteps=trials, callback=StopTrainingOnMaxEpisodes(max_episodes=trials), progress_bar=progress_bar
    )
    return model


def make_learner(
    algorithm: str, params: dict[str, Any], trials: int, progress_bar: bool, context: LearnerContext
) -> PullLearner:
    """``algorithm`` with hyperparameters ``params`` as a learner that trains for ``trials``
    trials in the ``[-1, 1]`` rescaling of the context's action box, seeded with ``context.seed``."""

    def run(env: gym.Env[Any, Any]) -> None:
        rescaled = gym.wrappers.RescaleAction(env, np.float32(-1), np.float32(1))
        train(algorithm, rescaled, params, context.seed, trials, progress_bar)

    return PullLearner(run, context.action_space, context.observation_space)
