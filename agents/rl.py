"""RL baselines: PPO, SAC and TD3 (Stable-Baselines3), CrossQ and TQC (sb3-contrib) on the one-trial
env (the ``rl`` extra), run on SBX, their JAX implementation by SB3's maintainers, where it is
installed (the ``rl-jax`` extra).

Hyperparameters live in ``configs/rl/<algorithm>.yaml``, one file per algorithm with a section
per prior (``nominal``, ``none``), each keyed by scenario with a ``default`` (rl-baselines3-zoo
style); the ``nominal`` values come from the tuning sweep of ``benchmarks/tune_rl.py``. Every
episode is one step and one trial, so a budget of ``B`` trials is at most ``B`` timesteps; the
trial loop stops training at the budget. PPO's ``n_steps`` is the number of trials before its
first update; the off-policy methods spend their first ``learning_starts`` trials on uniformly
random actions. ``gamma`` does not matter (there is no next state), and the constant observation
makes the policy a search over one action: RL solves a bandit here.

**Backends.** The same hyperparameters drive either implementation (:data:`RL_BACKENDS`):
``sbx`` where ``import sbx`` works, else ``sb3`` (SB3 and sb3-contrib, the reference
implementations); the environment variable :data:`BACKEND_VARIABLE` (``sb3``, ``sbx`` or
``auto``) chooses one by name. A key one of them does not accept is refused when the file is
read. :func:`implementation` names what ran (``"sbx-rl 0.28.0"``), and a comparison cell
records it. On the SB3 path, :func:`train` runs torch with :data:`TORCH_THREADS` thread(s) and
gives the caller's thread count back when it returns: torch's default (one thread per core)
makes TD3's small updates several times slower on a 2-core machine
(``results/benchmarks/rl_speed.md``), and a library call should not change its caller's setting
for good. On the SBX path it turns on JAX's persistent compilation cache, unless one is configured
(:func:`_jax_compilation_cache`).

What the algorithm sees and does, the same under both priors and both backends:

- actions in the ``[-1, 1]`` units of :class:`~ilc_steering.boxes.SearchBox`: the
  residual box around the nominal solution (``prior="nominal"``) or the whole action box;
- the first trial is the context's start (the nominal solution under that prior);
- the reward is ``-log10(cost)`` (the cost floored at :data:`REWARD_FLOOR`): the cost spans ten
  decades, from an off-chart trial's penalty to a sub-millimetre error, and on a log scale every
  tenfold improvement is worth the same;
- with ``start_at_centre``, the policy's output layer starts at zero, so that its mean action is
  the search box's centre, the nominal solution under that prior (``initial_std``: the first
  spread of a squashed-Gaussian policy, SAC, CrossQ or TQC, in search units);
- every ``eval_every`` training trials, one more trial at the policy's deterministic action (no
  exploration noise): run and counted like any other. Training trials carry exploration noise;
  these show what the policy has learned.
"""

import math
import os
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any, SupportsFloat

import gymnasium as gym
import numpy as np

from ilc_steering.agents.adapters import PullLearner
from ilc_steering.agents.base import LearnerContext
from ilc_steering.agents.rl_settings import (
    OWN_KEYS,
    algorithm_class,
    facts,
    rl_backend,
    squashed,
)
from ilc_steering.boxes import SearchBox

__all__ = [
    "REWARD_FLOOR",
    "TORCH_THREADS",
    "build",
    "log_reward",
    "make_learner",
    "start_at_centre",
    "train",
]

TORCH_THREADS = 1
"""torch's intra-op threads while :func:`train` runs on SB3 (restored when it returns)."""
REWARD_FLOOR = 1e-9
"""The smallest cost the log reward tells apart [m + rad]."""


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


def _start_at_centre_sb3(model: Any, algorithm: str, initial_std: float | None) -> None:
    import torch

    if facts(algorithm).actor == "deterministic":  # TD3: the action layer and its target's
        layers = [model.actor.mu[-2], model.actor_target.mu[-2]]
    elif squashed(algorithm):
        layers = [model.actor.mu]
    else:
        layers = [model.policy.action_net]
    with torch.no_grad():
        for layer in layers:
            layer.weight.zero_()
            layer.bias.zero_()
        if squashed(algorithm) and initial_std is not None:
            model.actor.log_std.weight.zero_()
            model.actor.log_std.bias.fill_(math.log(initial_std))


def _start_at_centre_sbx(model: Any, algorithm: str, initial_std: float | None) -> None:
    """SBX's actors are flax modules whose ``Dense_<i>`` layers are numbered in call order: the
    last is TD3's and PPO's action layer; a squashed-Gaussian actor ends with mean, then log-std."""
    import jax
    import jax.numpy as jnp

    state = model.policy.actor_state
    params = jax.tree_util.tree_map(lambda leaf: leaf, state.params)  # a mutable copy of the tree
    layers = params.get("params", params)  # CrossQ's actor keeps its batch statistics apart, without the level
    dense = sorted((name for name in layers if name.startswith("Dense_")), key=lambda name: int(name[6:]))
    mean = dense[-2] if squashed(algorithm) else dense[-1]
    layers[mean] = jax.tree_util.tree_map(jnp.zeros_like, layers[mean])
    if squashed(algorithm) and initial_std is not None:
        log_std = layers[dense[-1]]
        layers[dense[-1]] = {
            "kernel": jnp.zeros_like(log_std["kernel"]),
            "bias": jnp.full_like(log_std["bias"], math.log(initial_std)),
        }
    changes: dict[str, Any] = {"params": params}
    if facts(algorithm).actor == "deterministic":
        changes["target_params"] = params
    model.policy.actor_state = state.replace(**changes)


def start_at_centre(model: Any, algorithm: str, backend: str, initial_std: float | None) -> None:
    """Zero the policy's output layer, so that its first deterministic action is the search box's
    centre (under ``prior="nominal"``, the nominal solution); for a squashed-Gaussian policy,
    ``initial_std`` sets the spread of its first actions (``log_std_init`` acts only with ``use_sde``)."""
    if backend == "sbx":
        _start_at_centre_sbx(model, algorithm, initial_std)
    else:
        _start_at_centre_sb3(model, algorithm, initial_std)


def _jax_compilation_cache() -> None:
    """Point JAX's persistent compilation cache at ``$XDG_CACHE_HOME/ilc-steering/jax`` (default
    ``~/.cache``) unless the user configured one (``JAX_COMPILATION_CACHE_DIR`` or
    ``jax.config``): every SBX model compiles its update anew (about 10-20 s here), and from the
    cache a later model, in this process or another, loads it in about 1 s."""
    import jax

    config: Any = jax.config
    if config.jax_compilation_cache_dir is None:
        home = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
        config.update("jax_compilation_cache_dir", os.path.join(home, "ilc-steering", "jax"))
        config.update("jax_persistent_cache_min_compile_time_secs", 0.0)


@contextmanager
def _torch_threads(backend: str) -> Iterator[None]:
    """:data:`TORCH_THREADS` torch threads on the SB3 path while the block runs, the caller's after."""
    if backend != "sb3":
        yield
        return
    import torch

    before = torch.get_num_threads()
    torch.set_num_threads(TORCH_THREADS)
    try:
        yield
    finally:
        torch.set_num_threads(before)


def build(
    algorithm: str,
    env: gym.Env[Any, Any],
    params: dict[str, Any],
    seed: int,
    trials: int,
    backend: str | None = None,
    tensorboard_log: str | None = None,
) -> Any:
    """The untrained model of ``algorithm`` on ``env`` (actions in ``[-1, 1]``, rewarded with
    :func:`log_reward`) for a budget of ``trials``, on ``backend`` (default: :func:`rl_backend`),
    its output layer zeroed under ``start_at_centre``, logging to TensorBoard in ``tensorboard_log``
    where one is given. On the SB3 path, call it inside :func:`train`'s thread setting (or accept torch's)."""
    from stable_baselines3.common.noise import NormalActionNoise

    backend = backend or rl_backend()
    cls = algorithm_class(algorithm, backend)
    if backend == "sbx":
        _jax_compilation_cache()
    env = gym.wrappers.TransformReward(env, log_reward)
    kwargs = {k: v for k, v in params.items() if k not in OWN_KEYS}
    if "noise_std" in params:
        (size,) = env.action_space.shape or (0,)
        kwargs["action_noise"] = NormalActionNoise(np.zeros(size), params["noise_std"] * np.ones(size))
    if "learning_starts" in kwargs:
        kwargs["learning_starts"] = min(kwargs["learning_starts"], trials)
    if "n_steps" in kwargs and facts(algorithm).on_policy:
        kwargs["n_steps"] = min(kwargs["n_steps"], trials)
        kwargs["batch_size"] = min(kwargs.get("batch_size", 64), kwargs["n_steps"])
    model = cls(env=env, seed=seed, device="cpu", verbose=0, tensorboard_log=tensorboard_log, **kwargs)
    if params.get("start_at_centre"):
        start_at_centre(model, algorithm, backend, params.get("initial_std"))
    return model


def train(
    algorithm: str,
    env: gym.Env[Any, Any],
    params: dict[str, Any],
    seed: int,
    trials: int,
    progress_bar: bool = False,
    backend: str | None = None,
    tensorboard_log: str | None = None,
) -> Any:
    """Train ``algorithm`` on ``env`` (actions in ``[-1, 1]``) with the log reward for at most
    ``trials`` training trials, with the deterministic trials of ``eval_every`` between them, on
    ``backend`` (default: :func:`rl_backend`), with the algorithm's own TensorBoard logs in
    ``tensorboard_log`` (a folder ``<ALGORITHM>_<n>`` there) where one is given."""
    backend = backend or rl_backend()
    with _torch_threads(backend):
        model = build(algorithm, env, params, seed, trials, backend, tensorboard_log)
        every = params.get("eval_every")
        callback = _deterministic_trials(env, every) if every else None
        model.learn(total_timesteps=trials, callback=callback, progress_bar=progress_bar)
    return model


def make_learner(
    algorithm: str,
    params: dict[str, Any],
    trials: int,
    progress_bar: bool,
    context: LearnerContext,
    backend: str | None = None,
) -> PullLearner:
    """``algorithm`` with hyperparameters ``params`` as a learner for a budget of ``trials``
    trials, in the search box of the context's prior, seeded with ``context.seed``, on ``backend``
    (default: :func:`rl_backend`, read now); its first trial is the context's start; it logs to
    TensorBoard in ``context.tensorboard_log`` where one is given."""
    backend = backend or rl_backend()
    algorithm_class(algorithm, backend)

    def run(port: gym.Env[Any, Any]) -> None:
        env = SearchBox(port, *context.search_box())
        env.reset()
        env.step(context.start_point(0))
        train(algorithm, env, params, context.seed, trials, progress_bar, backend, context.tensorboard_log)

    return PullLearner(run, context.action_space, context.observation_space)
