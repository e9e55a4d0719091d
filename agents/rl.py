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
(``docs/benchmarks/rl_speed.md``), and a library call should not change its caller's setting
for good. On the SBX path it turns on JAX's persistent compilation cache, unless one is configured
(:func:`_jax_compilation_cache`).

What the algorithm sees and does, the same under both priors and both backends:

- actions in the ``[-1, 1]`` units of :class:`~ilc_steering.agents.adapters.SearchBox`: the
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

from __future__ import annotations

import inspect
import math
import os
import re
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from importlib import import_module, metadata, resources
from typing import Any, SupportsFloat

import gymnasium as gym
import numpy as np
import yaml

from ilc_steering.agents.adapters import PullLearner, SearchBox
from ilc_steering.agents.base import PRIORS, LearnerContext
from ilc_steering.config import ConfigError

__all__ = [
    "BACKEND_VARIABLE",
    "REWARD_FLOOR",
    "RL_ALGORITHMS",
    "RL_BACKENDS",
    "TORCH_THREADS",
    "algorithm_class",
    "backend_setting",
    "build",
    "check_hyperparameters",
    "check_value",
    "hyperparameters",
    "implementation",
    "log_reward",
    "make_learner",
    "rl_backend",
    "train",
]

RL_ALGORITHMS = ("ppo", "sac", "td3", "crossq", "tqc")
RL_BACKENDS = ("sbx", "sb3")
"""``sbx``: SBX (JAX); ``sb3``: Stable-Baselines3 and sb3-contrib (PyTorch), the reference."""
BACKEND_VARIABLE = "ILC_STEERING_RL_BACKEND"
"""Environment variable that picks the backend: ``sb3``, ``sbx`` or ``auto`` (unset: ``auto``,
SBX where it is installed)."""
TORCH_THREADS = 1
"""torch's intra-op threads while :func:`train` runs on SB3 (restored when it returns)."""
REWARD_FLOOR = 1e-9
"""The smallest cost the log reward tells apart [m + rad]."""
_CLASS_NAMES = {"ppo": "PPO", "sac": "SAC", "td3": "TD3", "crossq": "CrossQ", "tqc": "TQC"}
_SB3_MODULE = {"ppo": "stable_baselines3", "sac": "stable_baselines3", "td3": "stable_baselines3"}
_DISTRIBUTIONS = {"stable_baselines3": "stable-baselines3", "sb3_contrib": "sb3-contrib", "sbx": "sbx-rl"}
_SQUASHED = ("sac", "crossq", "tqc")  # a squashed-Gaussian actor: mean and log-std layers
_OWN_KEYS = {
    "n_timesteps",
    "noise_std",
    "eval_every",
    "start_at_centre",
    "initial_std",
}  # ours; every other key goes to the algorithm's constructor


def rl_backend() -> str:
    """The backend :func:`train` uses: :data:`BACKEND_VARIABLE` if set to ``sb3`` or ``sbx``, else
    ``sbx`` where it is importable, else ``sb3``; ``ValueError`` for any other value, or for
    ``sbx`` asked for by name and not installed."""
    asked = os.environ.get(BACKEND_VARIABLE, "auto")
    if asked not in (*RL_BACKENDS, "auto"):
        raise ValueError(f"{BACKEND_VARIABLE}={asked!r}: choose one of {[*RL_BACKENDS, 'auto']}")
    try:
        import_module("sbx")
    except ImportError:
        if asked == "sbx":
            raise ValueError(
                f"{BACKEND_VARIABLE}=sbx: SBX is not installed (pip install 'ilc-steering[rl-jax]')"
            ) from None
        return "sb3"
    return "sbx" if asked == "auto" else asked


def backend_setting(methods: Iterable[str]) -> dict[str, str]:
    """The run setting that pins the RL backend, ``{"rl_backend": "sbx"}``, when ``methods`` holds an
    RL algorithm (``{}`` otherwise): read (and :data:`BACKEND_VARIABLE` checked) once, before any
    cell runs, and recorded with a run's settings, so a run resumed under another backend is
    refused (its RL cells were computed by the other one)."""
    return {"rl_backend": rl_backend()} if any(m in RL_ALGORITHMS for m in methods) else {}


def _module(algorithm: str, backend: str) -> str:
    if algorithm not in RL_ALGORITHMS:
        raise ValueError(f"algorithm must be one of {RL_ALGORITHMS}, got {algorithm!r}")
    if backend not in RL_BACKENDS:
        raise ValueError(f"backend must be one of {RL_BACKENDS}, got {backend!r}")
    return "sbx" if backend == "sbx" else _SB3_MODULE.get(algorithm, "sb3_contrib")


def algorithm_class(algorithm: str, backend: str | None = None) -> type[Any]:
    """The class of ``algorithm`` on ``backend`` (default: :func:`rl_backend`); a ``ValueError``
    naming the extra to install where its package is missing."""
    module = _module(algorithm, backend or rl_backend())
    try:
        imported = import_module(module)
    except ModuleNotFoundError as error:
        extra = "rl-jax" if module == "sbx" else "rl"
        raise ValueError(f'{algorithm} needs {error.name}: pip install "ilc-steering[{extra}]"') from None
    return getattr(imported, _CLASS_NAMES[algorithm])  # type: ignore[no-any-return]


def implementation(algorithm: str, backend: str | None = None) -> str:
    """What runs ``algorithm`` on ``backend`` (default: :func:`rl_backend`): distribution and version,
    ``"sbx-rl 0.28.0"``, ``"stable-baselines3 2.9.2"``, ``"sb3-contrib 2.9.2"``."""
    distribution = _DISTRIBUTIONS[_module(algorithm, backend or rl_backend())]
    return f"{distribution} {metadata.version(distribution)}"


def _installed_backends() -> list[str]:
    try:
        import_module("sbx")
    except ImportError:
        return ["sb3"]
    return list(RL_BACKENDS)


def hyperparameters(algorithm: str, scenario: str, prior: str = "nominal") -> dict[str, Any]:
    """The hyperparameters of ``algorithm`` for ``scenario`` under ``prior`` from the packaged YAML
    file: the scenario's entry, else the prior's ``default``."""
    source = f"configs/rl/{algorithm}.yaml"
    _module(algorithm, "sb3")
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
    if not isinstance(section[key], dict):
        raise ConfigError(f"{source}: {prior}.{key}: must be a mapping of hyperparameters")
    return check_hyperparameters(algorithm, dict(section[key]), f"{source}: {prior}.{key}")


def check_hyperparameters(algorithm: str, params: dict[str, Any], where: str) -> dict[str, Any]:
    """``params`` if every key (and every ``policy_kwargs`` key) is an argument of the algorithm's
    class (or ours) on every installed backend, else :class:`ConfigError` naming the key and
    ``where`` it came from: the same file must mean the same on SB3 and SBX."""
    for backend in _installed_backends():
        cls = algorithm_class(algorithm, backend)
        allowed = set(inspect.signature(cls.__init__).parameters) - {"self", "env"} | _OWN_KEYS
        unknown = sorted(set(params) - allowed)
        if unknown:
            raise ConfigError(
                f"{where}.{unknown[0]}: unknown key for {cls.__name__} ({implementation(algorithm, backend)})"
            )
        policy = cls.policy_aliases.get(params.get("policy", "MlpPolicy"))
        accepted = set(inspect.signature(policy.__init__).parameters) if policy is not None else set()
        unknown = sorted(set(params.get("policy_kwargs") or {}) - accepted)
        if unknown:
            raise ConfigError(
                f"{where}.policy_kwargs.{unknown[0]}: unknown key for {cls.__name__}'s policy "
                f"({implementation(algorithm, backend)})"
            )
    if "n_timesteps" not in params:
        raise ConfigError(f"{where}.n_timesteps: missing; the budget, an integer >= 1 [trials]")
    params = {key: check_value(key, value, f"{where}.{key}") for key, value in params.items()}
    std = params.get("initial_std")
    if std is not None and (algorithm not in _SQUASHED or not isinstance(std, float) or not 0 < std <= 1):
        names = ", ".join(_CLASS_NAMES[a] for a in _SQUASHED)
        raise ConfigError(f"{where}.initial_std: {names} only, a number in (0, 1] [search units]")
    return params


_INTEGERS = {  # key: the least value (an integer); -1 also allowed where listed
    "n_timesteps": 1, "eval_every": 1, "batch_size": 1, "n_steps": 1, "n_epochs": 1, "buffer_size": 1,
    "train_freq": 1, "gradient_steps": 1, "learning_starts": 0, "policy_delay": 1,
    "top_quantiles_to_drop_per_net": 0, "n_critics": 1, "n_quantiles": 1, "seed": 0,
}  # fmt: skip
_MINUS_ONE = {"gradient_steps"}  # SB3: -1 is "as many gradient steps as trials collected"
_NUMBERS = {  # key: (low, high, low included)
    "learning_rate": (0.0, 1.0, False), "gamma": (0.0, 1.0, True), "gae_lambda": (0.0, 1.0, True),
    "tau": (0.0, 1.0, False), "clip_range": (0.0, 10.0, False), "noise_std": (0.0, 10.0, True),
    "initial_std": (0.0, 1.0, False), "vf_coef": (0.0, 1e6, True), "max_grad_norm": (0.0, 1e6, False),
    "target_policy_noise": (0.0, 10.0, True), "target_noise_clip": (0.0, 10.0, True),
    "ent_coef": (0.0, 1e6, True), "target_entropy": (-1e6, 1e6, True),
}  # fmt: skip
_AUTO = {"ent_coef", "target_entropy"}  # may also be "auto" ("auto_0.01" for ent_coef)
_NUMBER_TEXT = re.compile(r"[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?")


def _widths(layer: Any) -> bool:
    return isinstance(layer, list) and all(
        isinstance(w, int) and not isinstance(w, bool) and 1 <= w <= 4096 for w in layer
    )


def check_value(key: str, value: Any, where: str) -> Any:
    """``value`` of hyperparameter ``key`` checked by type and range (:data:`_INTEGERS`,
    :data:`_NUMBERS`), a number written ``3e-4`` (text to YAML 1.1) read as the number it shows;
    :class:`ConfigError` naming ``where`` otherwise. Keys of no table are passed on as they are."""
    if key in _INTEGERS:
        least = _INTEGERS[key]
        ok = isinstance(value, int) and not isinstance(value, bool)
        if not ok or not (value >= least or (key in _MINUS_ONE and value == -1)):
            also = " (or -1)" if key in _MINUS_ONE else ""
            raise ConfigError(f"{where}: must be an integer >= {least}{also}, got {value!r:.60}")
        return value
    if key in _NUMBERS:
        if key in _AUTO and isinstance(value, str) and (value == "auto" or value.startswith("auto_")):
            if value.startswith("auto_"):
                check_value(key, value.removeprefix("auto_"), where)
            return value
        if isinstance(value, str) and _NUMBER_TEXT.fullmatch(value.strip()):
            value = float(value)  # YAML 1.1 reads 3e-4 as text; the user means the number
        low, high, closed = _NUMBERS[key]
        number = isinstance(value, (int, float)) and not isinstance(value, bool)
        inside = number and math.isfinite(value) and (low <= value if closed else low < value) and value <= high
        if not inside:
            bracket = "[" if closed else "("
            also = ' or "auto"' if key in _AUTO else ""
            raise ConfigError(f"{where}: must be a number in {bracket}{low:g}, {high:g}]{also}, got {value!r:.60}")
        return float(value)
    if key == "start_at_centre" and not isinstance(value, bool):
        raise ConfigError(f"{where}: must be true or false, got {value!r:.60}")
    if key == "policy" and not isinstance(value, str):
        raise ConfigError(f"{where}: must be a policy name (a string), got {value!r:.60}")
    if key == "policy_kwargs":
        if not isinstance(value, dict):
            raise ConfigError(f"{where}: must be a mapping, got {value!r:.60}")
        arch = value.get("net_arch")
        layers = list(arch.values()) if isinstance(arch, dict) else [arch]  # SB3 also takes {pi: [...], qf: [...]}
        if arch is not None and not all(_widths(layer) for layer in layers):
            raise ConfigError(
                f"{where}.net_arch: must be a list of layer widths (integers in [1, 4096]) or a mapping of such "
                f"lists, got {arch!r:.60}"
            )
        init = value.get("log_std_init")
        if init is not None and not (
            isinstance(init, (int, float)) and not isinstance(init, bool) and -20 <= init <= 2
        ):
            raise ConfigError(f"{where}.log_std_init: must be a number in [-20, 2], got {init!r:.60}")
    return value


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

    if algorithm == "td3":
        layers = [model.actor.mu[-2], model.actor_target.mu[-2]]
    elif algorithm in _SQUASHED:
        layers = [model.actor.mu]
    else:
        layers = [model.policy.action_net]
    with torch.no_grad():
        for layer in layers:
            layer.weight.zero_()
            layer.bias.zero_()
        if algorithm in _SQUASHED and initial_std is not None:
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
    mean = dense[-2] if algorithm in _SQUASHED else dense[-1]
    layers[mean] = jax.tree_util.tree_map(jnp.zeros_like, layers[mean])
    if algorithm in _SQUASHED and initial_std is not None:
        log_std = layers[dense[-1]]
        layers[dense[-1]] = {
            "kernel": jnp.zeros_like(log_std["kernel"]),
            "bias": jnp.full_like(log_std["bias"], math.log(initial_std)),
        }
    changes: dict[str, Any] = {"params": params}
    if algorithm == "td3":
        changes["target_params"] = params
    model.policy.actor_state = state.replace(**changes)


def _start_at_centre(model: Any, algorithm: str, backend: str, initial_std: float | None) -> None:
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
) -> Any:
    """The untrained model of ``algorithm`` on ``env`` (actions in ``[-1, 1]``, rewarded with
    :func:`log_reward`) for a budget of ``trials``, on ``backend`` (default: :func:`rl_backend`),
    its output layer zeroed under ``start_at_centre``. On the SB3 path, call it inside
    :func:`train`'s thread setting (or accept torch's)."""
    from stable_baselines3.common.noise import NormalActionNoise

    backend = backend or rl_backend()
    cls = algorithm_class(algorithm, backend)
    if backend == "sbx":
        _jax_compilation_cache()
    env = gym.wrappers.TransformReward(env, log_reward)
    kwargs = {k: v for k, v in params.items() if k not in _OWN_KEYS}
    if "noise_std" in params:
        (size,) = env.action_space.shape or (0,)
        kwargs["action_noise"] = NormalActionNoise(np.zeros(size), params["noise_std"] * np.ones(size))
    if "learning_starts" in kwargs:
        kwargs["learning_starts"] = min(kwargs["learning_starts"], trials)
    if "n_steps" in kwargs and algorithm == "ppo":
        kwargs["n_steps"] = min(kwargs["n_steps"], trials)
        kwargs["batch_size"] = min(kwargs.get("batch_size", 64), kwargs["n_steps"])
    model = cls(env=env, seed=seed, device="cpu", verbose=0, **kwargs)
    if params.get("start_at_centre"):
        _start_at_centre(model, algorithm, backend, params.get("initial_std"))
    return model


def train(
    algorithm: str,
    env: gym.Env[Any, Any],
    params: dict[str, Any],
    seed: int,
    trials: int,
    progress_bar: bool = False,
    backend: str | None = None,
) -> Any:
    """Train ``algorithm`` on ``env`` (actions in ``[-1, 1]``) with the log reward for at most
    ``trials`` training trials, with the deterministic trials of ``eval_every`` between them, on
    ``backend`` (default: :func:`rl_backend`)."""
    backend = backend or rl_backend()
    with _torch_threads(backend):
        model = build(algorithm, env, params, seed, trials, backend)
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
    (default: :func:`rl_backend`, read now); its first trial is the context's start."""
    backend = backend or rl_backend()
    algorithm_class(algorithm, backend)

    def run(port: gym.Env[Any, Any]) -> None:
        env = SearchBox(port, *context.search_box())
        env.reset()
        env.step(context.start_point(0))
        train(algorithm, env, params, context.seed, trials, progress_bar, backend)

    return PullLearner(run, context.action_space, context.observation_space)
