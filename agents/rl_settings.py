"""The RL baselines' settings: which implementation runs them (:data:`RL_BACKENDS`, chosen by
:data:`BACKEND_VARIABLE`) and their hyperparameters (``configs/rl/<algorithm>.yaml``, read by the one
YAML reader and checked key by key against the algorithm's class on every installed backend).
:mod:`ilc_steering.agents.rl` trains them."""

from __future__ import annotations

import inspect
import math
import os
import re
from collections.abc import Iterable
from dataclasses import dataclass
from importlib import import_module, metadata, resources
from typing import Any

from ilc_steering.agents.base import PRIORS
from ilc_steering.errors import BadInput, ConfigError
from ilc_steering.yaml_reader import load_yaml

__all__ = [
    "ALGORITHMS",
    "BACKEND_VARIABLE",
    "OWN_KEYS",
    "RL_ALGORITHMS",
    "RL_BACKENDS",
    "RLAlgorithm",
    "algorithm_class",
    "backend_setting",
    "check_hyperparameters",
    "check_value",
    "facts",
    "hyperparameters",
    "implementation",
    "installed_backends",
    "rl_backend",
    "squashed",
    "zoo_file",
]


@dataclass(frozen=True)
class RLAlgorithm:
    """What the RL family needs to know of one algorithm."""

    class_name: str
    """Its class in SB3, sb3-contrib and SBX (``"TQC"``)."""
    sb3_module: str
    """The PyTorch package that has it: ``stable_baselines3`` or ``sb3_contrib`` (SBX has them all)."""
    actor: str
    """``"deterministic"`` (an action layer and a target actor: TD3), ``"squashed"`` (a
    squashed-Gaussian actor, mean then log-std layers: SAC, CrossQ, TQC) or ``"gaussian"`` (an action
    layer and a state-independent std: PPO)."""
    on_policy: bool = False
    """Collects rollouts of ``n_steps`` trials before each update (PPO)."""


ALGORITHMS: dict[str, RLAlgorithm] = {
    "ppo": RLAlgorithm("PPO", "stable_baselines3", "gaussian", on_policy=True),
    "sac": RLAlgorithm("SAC", "stable_baselines3", "squashed"),
    "td3": RLAlgorithm("TD3", "stable_baselines3", "deterministic"),
    "crossq": RLAlgorithm("CrossQ", "sb3_contrib", "squashed"),
    "tqc": RLAlgorithm("TQC", "sb3_contrib", "squashed"),
}
"""Each RL method id's facts; the learner registry (:mod:`~ilc_steering.agents.registry`) makes a
learner of each."""
RL_ALGORITHMS = tuple(ALGORITHMS)
"""The RL method ids."""
RL_BACKENDS = ("sbx", "sb3")
"""``sbx``: SBX (JAX); ``sb3``: Stable-Baselines3 and sb3-contrib (PyTorch), the reference."""
BACKEND_VARIABLE = "ILC_STEERING_RL_BACKEND"
"""Environment variable that picks the backend: ``sb3``, ``sbx`` or ``auto`` (unset: ``auto``,
SBX where it is installed)."""
_DISTRIBUTIONS = {"stable_baselines3": "stable-baselines3", "sb3_contrib": "sb3-contrib", "sbx": "sbx-rl"}
OWN_KEYS = {
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
        raise BadInput(f"{BACKEND_VARIABLE}={asked!r}: choose one of {[*RL_BACKENDS, 'auto']}")
    try:
        import_module("sbx")
    except ImportError:
        if asked == "sbx":
            raise BadInput(
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
    if backend not in RL_BACKENDS:
        raise BadInput(f"backend must be one of {RL_BACKENDS}, got {backend!r}")
    return "sbx" if backend == "sbx" else facts(algorithm).sb3_module


def facts(algorithm: str) -> RLAlgorithm:
    """The registry's facts of RL method ``algorithm``; ``ValueError`` for any other id."""
    found = ALGORITHMS.get(algorithm)
    if found is None:
        raise BadInput(f"algorithm must be one of {RL_ALGORITHMS}, got {algorithm!r}")
    return found


def squashed(algorithm: str) -> bool:
    return facts(algorithm).actor == "squashed"


def algorithm_class(algorithm: str, backend: str | None = None) -> type[Any]:
    """The class of ``algorithm`` on ``backend`` (default: :func:`rl_backend`); a ``ValueError``
    naming the extra to install where its package is missing."""
    module = _module(algorithm, backend or rl_backend())
    try:
        imported = import_module(module)
    except ModuleNotFoundError as error:
        extra = "rl-jax" if module == "sbx" else "rl"
        raise BadInput(f'{algorithm} needs {error.name}: pip install "ilc-steering[{extra}]"') from None
    return getattr(imported, facts(algorithm).class_name)  # type: ignore[no-any-return]


def implementation(algorithm: str, backend: str | None = None) -> str:
    """What runs ``algorithm`` on ``backend`` (default: :func:`rl_backend`): distribution and version,
    ``"sbx-rl 0.28.0"``, ``"stable-baselines3 2.9.2"``, ``"sb3-contrib 2.9.2"``."""
    distribution = _DISTRIBUTIONS[_module(algorithm, backend or rl_backend())]
    return f"{distribution} {metadata.version(distribution)}"


def installed_backends() -> list[str]:
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
        raise BadInput(f"prior must be one of {list(PRIORS)}, got {prior!r}")
    table = load_yaml((resources.files("ilc_steering.configs") / "rl" / f"{algorithm}.yaml").read_text(), source)
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


def zoo_file(algorithm: str) -> str:
    """The path of the packaged hyperparameter file of ``algorithm`` in RL Zoo's own format,
    ``.../ilc_steering/configs/rl_zoo/<algorithm>.yml``, for ``python -m rl_zoo3.train -conf``
    (docs/usage.md, "Train with RL Zoo"): the ``nominal`` defaults of ``configs/rl/<algorithm>.yaml``
    for every registered env that trains; ``ValueError`` for an algorithm that is not an RL baseline."""
    facts(algorithm)
    return str(resources.files("ilc_steering.configs") / "rl_zoo" / f"{algorithm}.yml")


def check_hyperparameters(algorithm: str, params: dict[str, Any], where: str) -> dict[str, Any]:
    """``params`` if every key (and every ``policy_kwargs`` key) is an argument of the algorithm's
    class (or ours) on every installed backend, else :class:`ConfigError` naming the key and
    ``where`` it came from: the same file must mean the same on SB3 and SBX."""
    for backend in installed_backends():
        cls = algorithm_class(algorithm, backend)
        allowed = set(inspect.signature(cls.__init__).parameters) - {"self", "env"} | OWN_KEYS
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
    if std is not None and (not squashed(algorithm) or not isinstance(std, float) or not 0 < std <= 1):
        names = ", ".join(facts(a).class_name for a in RL_ALGORITHMS if squashed(a))
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
