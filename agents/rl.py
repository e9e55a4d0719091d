"""RL baselines: Stable-Baselines3's PPO, SAC and TD3 on the one-trial env (the ``rl`` extra).

Hyperparameters live in ``configs/rl/<algorithm>.yaml``, one file per algorithm with a section
per prior (``nominal``, ``none``), each keyed by scenario with a ``default`` (rl-baselines3-zoo
style); the ``nominal`` values come from the tuning sweep of ``benchmarks/tune_rl.py``. Every
episode is one step and one trial, so a budget of ``B`` trials is at most ``B`` timesteps; the
trial loop stops training at the budget. PPO's ``n_steps`` is the number of trials before its
first update; SAC and TD3 spend their first ``learning_starts`` trials on uniformly random
actions. ``gamma`` does not matter (there is no next state), and the constant observation makes
the policy a search over one action: RL solves a bandit here.

What the algorithm sees and does, the same under both priors:

- actions in the ``[-1, 1]`` units of :class:`~ilc_steering.agents.adapters.SearchBox`: the
  residual box around the nominal solution (``prior="nominal"``) or the whole action box;
- the first trial is the context's start (the nominal solution under that prior);
- the reward is ``-log10(cost)`` (the cost floored at :data:`REWARD_FLOOR`): the cost spans ten
  decades, from an off-chart trial's penalty to a sub-millimetre error, and on a log scale every
  tenfold improvement is worth the same;
- with ``start_at_centre``, the policy's output layer starts at zero, so that its mean action is
  the search box's centre, the nominal solution under that prior (``initial_std``: SAC's first
  spread, in search units);
- every ``eval_every`` training trials, one more trial at the policy's deterministic action (no
  exploration noise): run and counted like any other. Training trials carry exploration noise;
  these show what the policy has learned.
"""

from __future__ import annotations

import inspect
import math
from importlib import resources
from typing import Any, SupportsFloat

import gymnasium as gym
import numpy as np
import yaml

from ilc_steering.agents.adapters import PullLearner, SearchBox
from ilc_steering.agents.base import PRIORS, LearnerContext
from ilc_steering.config import ConfigError

__all__ = [
    "REWARD_FLOOR",
    "RL_ALGORITHMS",
    "check_hyperparameters",
    "hyperparameters",
    "log_reward",
    "make_learner",
    "train",
]

RL_ALGORITHMS = ("ppo", "sac", "td3")
REWARD_FLOOR = 1e-9
"""The smallest cost the log reward tells apart [m + rad]."""
_OWN_KEYS = {
    "n_timesteps",
    "noise_std",
    "eval_every",
    "start_at_centre",
    "initial_std",
}  # ours; every other key goes to the SB3 constructor


def _algorithm_class(algorithm: str) -> type[Any]:
    import stable_baselines3

    if algorithm not in RL_ALGORITHMS:
        raise ValueError(f"algorithm must be one of {RL_ALGORITHMS}, got {algorithm!r}")
    return getattr(stable_baselines3, algorithm.upper())  # type: ignore[no-any-return]


def hyperparameters(algorithm: str, scenario: str, prior: str = "nominal") -> dict[str, Any]:
    """The hyperparameters of ``algorithm`` for ``scenario`` under ``prior`` from the packaged YAML
    file: the scenario's entry, else the prior's ``default``."""
    source = f"configs/rl/{algorithm}.yaml"
    _algorithm_class(algorithm)
    if prior not in PRIORS:
        raise ValueError(f"prior must be one of {list(PRIORS)}, got {prior!r}")
    table = yaml.safe_load((resources.files("ilc_steering.configs") / "rl" / f"{algorithm}.yaml").read_text())
    section = table.get(prior) if isinstance(table, dict) else None
    if not isinstance(section, dict):
        raise ConfigError(f"{source}: no section for prior {prior!r}")
    key = scenario if scenario in section else "default"
    if key not in section:
        raise ConfigError(
            f"{source}: {prior}: no hyperparameters for scenario {scenario!r} and no default (has {sorted(section)})"
        )
    return check_hyperparameters(algorithm, dict(section[key]), f"{source}: {prior}.{key}")


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
    every = params.get("eval_every")
    if every is not None and (not isinstance(every, int) or every < 1):
        raise ConfigError(f"{where}.eval_every: must be an integer >= 1 [trials] or absent")
    std = params.get("initial_std")
    if std is not None and (algorithm != "sac" or not isinstance(std, float) or not 0 < std <= 1):
        raise ConfigError(f"{where}.initial_std: SAC only, a number in (0, 1] [search units]")
    return params


def log_reward(reward: SupportsFloat) -> float:
    """``-log10(cost)`` of a trial whose env reward is ``-cost`` (cost floored at :data:`REWARD_FLOOR`)."""
    return -math.log10(max(-float(reward), REWARD_FLOOR))


def _deterministic_trials(env: gym.Env[Any, Any], every: int) -> Any:
    """An SB3 callback that runs one trial at the policy's deterministic action every ``every``
    training steps (trials), on ``env``, the env the algorithm trains on."""
    from stable_baselines3.common.callbacks import BaseCallback

    class DeterministicTrials(BaseCallback):
        def _on_step(self) -> bool:
            if self.num_timesteps % every == 0:
                observation, _ = env.reset()
                action, _ = self.model.predict(observation, deterministic=True)
                env.step(action)
            return True

    return DeterministicTrials()


def _start_at_centre(model: Any, algorithm: str, initial_std: float | None) -> None:
    """Zero the policy's output layer, so that its first deterministic action is the search box's
    centre (under ``prior="nominal"``, the nominal solution); for SAC, ``initial_std`` sets the
    spread of its first actions (``log_std_init`` acts only with ``use_sde``)."""
    import torch

    if algorithm == "td3":
        layers = [model.actor.mu[-2], model.actor_target.mu[-2]]
    elif algorithm == "sac":
        layers = [model.actor.mu]
    else:
        layers = [model.policy.action_net]
    with torch.no_grad():
        for layer in layers:
            layer.weight.zero_()
            layer.bias.zero_()
        if algorithm == "sac" and initial_std is not None:
            model.actor.log_std.weight.zero_()
            model.actor.log_std.bias.fill_(math.log(initial_std))


def train(
    algorithm: str, env: gym.Env[Any, Any], params: dict[str, Any], seed: int, trials: int, progress_bar: bool = False
) -> Any:
    """Train ``algorithm`` on ``env`` (actions in ``[-1, 1]``) with the log reward for at most
    ``trials`` training trials, with the deterministic trials of ``eval_every`` between them."""
    from stable_baselines3.common.noise import NormalActionNoise

    cls = _algorithm_class(algorithm)
    env = gym.wrappers.TransformReward(env, log_reward)
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
    if params.get("start_at_centre"):
        _start_at_centre(model, algorithm, params.get("initial_std"))
    every = params.get("eval_every")
    callback = _deterministic_trials(env, every) if every else None
    model.learn(total_timesteps=trials, callback=callback, progress_bar=progress_bar)
    return model


def make_learner(
    algorithm: str, params: dict[str, Any], trials: int, progress_bar: bool, context: LearnerContext
) -> PullLearner:
    """``algorithm`` with hyperparameters ``params`` as a learner for a budget of ``trials``
    trials, in the search box of the context's prior, seeded with ``context.seed``; its first
    trial is the context's start."""

    def run(port: gym.Env[Any, Any]) -> None:
        env = SearchBox(port, *context.search_box())
        env.reset()
        env.step(context.start_point(0))
        train(algorithm, env, params, context.seed, trials, progress_bar)

    return PullLearner(run, context.action_space, context.observation_space)
