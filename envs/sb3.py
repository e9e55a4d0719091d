"""Stable-Baselines3's ``VecEnv`` API over a Gymnasium vector env that resets in the same step.

SB3 has its own vector API (``step_async``/``step_wait``, ``dones``, a list of per-env infos with
``"terminal_observation"``). :class:`SB3VecEnv` presents a natively batched
:class:`~ilc_steering.envs.steering_vector_env.ChainedSteeringVectorEnv` (or any Gymnasium
vector env with ``AutoresetMode.SAME_STEP``, wrappers included) through it, so SB3 trains on
batched trials::

    import gymnasium as gym
    import numpy as np
    from gymnasium.wrappers.vector import RescaleAction
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecMonitor
    from ilc_steering.envs.sb3 import SB3VecEnv

    envs = gym.make_vec("ilc_steering/ChainedSteering-v0", num_envs=16,
                        vectorization_mode="vector_entry_point", config="forward_parking")
    envs = VecMonitor(SB3VecEnv(RescaleAction(envs, np.float32(-1), np.float32(1))))
    PPO("MlpPolicy", envs, n_steps=64, batch_size=256, seed=0).learn(total_timesteps=16 * 64 * 4)

Each per-env info holds the trial's ``info`` (``cartesian_error``, ``error``, ...) from
``info["final_info"]``. Requires the ``rl`` extra.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import gymnasium as gym
import numpy as np
import numpy.typing as npt
from gymnasium.vector import AutoresetMode
from stable_baselines3.common.vec_env.base_vec_env import VecEnv, VecEnvIndices, VecEnvObs, VecEnvStepReturn

from ilc_steering.errors import BadInput

__all__ = ["SB3VecEnv"]


class SB3VecEnv(VecEnv):
    """SB3's ``VecEnv`` over a Gymnasium ``VectorEnv`` whose ``metadata["autoreset_mode"]`` is
    ``SAME_STEP``. Attributes and methods are those of the vector env (the same for every index)."""

    def __init__(self, venv: gym.vector.VectorEnv) -> None:
        mode = venv.metadata.get("autoreset_mode")
        if mode != AutoresetMode.SAME_STEP:
            raise BadInput(f"SB3VecEnv needs a vector env with autoreset_mode SAME_STEP, got {mode!r}")
        self.venv = venv
        self._actions: npt.NDArray[Any] | None = None
        super().__init__(venv.num_envs, venv.single_observation_space, venv.single_action_space)

    def reset(self) -> VecEnvObs:
        options = self._options[0] or None
        obs, info = self.venv.reset(seed=self._seeds[0], options=options)
        self.reset_infos = _unbatch(info, self.num_envs)
        self._reset_seeds()
        self._reset_options()
        observations: VecEnvObs = obs
        return observations

    def step_async(self, actions: npt.NDArray[Any]) -> None:
        self._actions = actions

    def step_wait(self) -> VecEnvStepReturn:
        if self._actions is None:
            raise RuntimeError("step_wait() without step_async()")
        obs, rewards, terminations, truncations, info = self.venv.step(self._actions)
        self._actions = None
        dones = terminations | truncations
        infos = _unbatch(info.get("final_info", {}), self.num_envs)
        final_obs: Any = info.get("final_obs")
        for i in np.flatnonzero(dones):
            infos[i]["terminal_observation"] = final_obs[i]
            infos[i]["TimeLimit.truncated"] = bool(truncations[i] and not terminations[i])
        return obs, rewards.astype(np.float32), dones, infos

    def close(self) -> None:
        self.venv.close()

    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        value = _find_attr(self.venv, attr_name)
        return [value for _ in self._get_indices(indices)]

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        setattr(self.venv.unwrapped, attr_name, value)

    def env_method(
        self, method_name: str, *method_args: Any, indices: VecEnvIndices = None, **method_kwargs: Any
    ) -> list[Any]:
        result = _find_attr(self.venv, method_name)(*method_args, **method_kwargs)
        return [result for _ in self._get_indices(indices)]

    def env_is_wrapped(self, wrapper_class: type[gym.Wrapper], indices: VecEnvIndices = None) -> list[bool]:
        return [False for _ in self._get_indices(indices)]  # the copies are not single gym.Envs

    def get_images(self) -> Sequence[npt.NDArray[Any] | None]:
        frames: Any = self.venv.render()
        return list(frames) if frames is not None else [None] * self.num_envs


def _find_attr(env: Any, name: str) -> Any:
    """``name`` on the outermost vector wrapper that has it."""
    while True:
        if hasattr(env, name):
            return getattr(env, name)
        if not hasattr(env, "env"):
            raise AttributeError(f"no vector env in the wrapper chain has attribute {name!r}")
        env = env.env


def _unbatch(info: dict[str, Any], num_envs: int) -> list[dict[str, Any]]:
    """A Gymnasium vector ``info`` (arrays with ``_key`` masks) as one dict per env."""
    out: list[dict[str, Any]] = [{} for _ in range(num_envs)]
    for key, values in info.items():
        if key.startswith("_") or isinstance(values, dict):
            continue
        mask = info.get(f"_{key}", np.ones(num_envs, dtype=bool))
        for i in np.flatnonzero(mask):
            out[i][key] = values[i]
    return out
