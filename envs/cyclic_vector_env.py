"""``CyclicSteeringVectorEnv``: ``num_envs`` robots around the cycle of waypoints, one batched call per segment."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
from gymnasium import spaces
from gymnasium.vector import AutoresetMode

from ilc_steering.boxes import action_box
from ilc_steering.config import SteeringConfig
from ilc_steering.core.nominal import NominalModel
from ilc_steering.envs.base import check_action
from ilc_steering.envs.cyclic_env import check_cycles
from ilc_steering.envs.scenario import Scenario
from ilc_steering.envs.trials import reward, trial_infos
from ilc_steering.envs.vector_base import SteeringVectorEnv, draw_noise
from ilc_steering.errors import BadInput

__all__ = ["CyclicSteeringVectorEnv"]

Array = npt.NDArray[np.float64]


class CyclicSteeringVectorEnv(SteeringVectorEnv):
    """``num_envs`` copies of ``CyclicSteering-v0`` (a :class:`~ilc_steering.envs.cyclic_env.CyclicSteeringEnv`
    in ``TimeLimit``), stepped together.

    Made by ``gym.make_vec("ilc_steering/CyclicSteering-v0", num_envs=N,
    vectorization_mode="vector_entry_point", config=..., cycles=...)``. Each ``step`` takes
    actions ``(N, 1 + q)`` and drives every robot along the same segment, from wherever each of
    them is, in one call of the compiled integrator (on all cores from
    :data:`~ilc_steering.envs.steering_vector_env.PARALLEL_FROM` robots up). The robots stay in
    step: they start together, every one drives the same segment at each step, and all are
    truncated together after ``cycles * r`` steps. Observations, rewards and ``info`` are the
    scalar env's, batched: ``(N, n + r)`` measured chained states with the segment one-hot, and
    ``info`` arrays with a leading batch axis and Gymnasium's ``_key`` masks.

    The truncating step resets in the same step (``metadata["autoreset_mode"] =
    AutoresetMode.SAME_STEP``): it returns the next episode's observation (every robot at home)
    and its reset ``info``, the last segment's results in ``info["final_obs"]`` and
    ``info["final_info"]``, as ``SyncVectorEnv`` of the scalar env in that mode (tested bit for
    bit). ``reset(options={"start": q})`` starts every robot at ``q`` (world configuration;
    ``z`` for a chained plant), or robot ``i`` at row ``i`` of an ``(N, nq)`` array.
    ``measurement_noise`` is the scalar env's; a step's noise is drawn in one call from the vector
    env's ``np_random``, so with noise the robots match the scalar env's in distribution, not draw
    for draw; after ``reset(seed=[s_0, ..., s_N-1])`` robot ``i`` draws from a stream of its own,
    seeded as the scalar env's ``reset(seed=s_i)``. ``num_envs`` is at most
    :data:`~ilc_steering.envs.steering_vector_env.MAX_ENVS`.

    >>> import gymnasium as gym
    >>> import ilc_steering
    >>> envs = gym.make_vec("ilc_steering/CyclicSteering-v0", num_envs=3, vectorization_mode="vector_entry_point",
    ...                     config="cyclic_home_goal", cycles=1)
    >>> obs, info = envs.reset(seed=0)
    >>> for segment in range(2):
    ...     c = envs.unwrapped.nominal_models[segment].solve()
    ...     obs, rewards, terminations, truncations, info = envs.step(np.tile(c, (3, 1)))
    >>> truncations.tolist(), info["final_info"]["waypoint"].tolist(), info["segment"].tolist()
    ([True, True, True], [2, 2, 2], [0, 0, 0])
    """

    metadata: dict[str, Any] = {"render_modes": [], "autoreset_mode": AutoresetMode.SAME_STEP}
    """No render mode: render a ``CyclicSteeringEnv`` instead."""

    def __init__(
        self,
        num_envs: int,
        config: str | Path | SteeringConfig = "cyclic_home_goal",
        cycles: int | None = None,
        render_mode: str | None = None,
        parallel: bool | None = None,
        measurement_noise: float | Sequence[float] | None = None,
    ) -> None:
        check_cycles(cycles)
        self.open(num_envs, config, "cyclic", "the cyclic vector env", render_mode)
        self._scenario = Scenario.from_config(self.config, measurement_noise)
        self._scenario.refuse_disturbances("the cyclic vector env")
        models = self._scenario.nominals
        self.num_segments = len(models)
        self.max_episode_steps = (self.config.learning.trials if cycles is None else int(cycles)) * self.num_segments
        n = models[0].dimension
        observations = spaces.Box(-np.inf, np.inf, shape=(n + self.num_segments,), dtype=np.float64)
        actions = action_box(self._scenario.action_high)
        self.batch(actions, observations, parallel)
        high = self._high = actions.high
        self._action_names = f"(num_envs = {self.num_envs}, (c11, c21..c2{high.size - 1}))"
        self._start = np.tile(self._scenario.waypoints[0], (self.num_envs, 1))
        self._x = np.tile(self._scenario.x_start, (self.num_envs, 1))
        self._segment, self._cycle, self._steps = 0, 1, 0

    @property
    def nominal_models(self) -> list[NominalModel]:
        """One nominal model per segment: the only view of the system a learner should use."""
        return self._scenario.nominals

    def reset(
        self, *, seed: int | list[int] | None = None, options: dict[str, Any] | None = None
    ) -> tuple[Array, dict[str, Any]]:
        if options is not None and not isinstance(options, dict):
            raise BadInput(f"options must be a dict such as {{'start': q}} or None, got {type(options).__name__}")
        unknown = sorted(set(options or {}) - {"start"})
        if unknown:
            raise BadInput(f"options: unknown key {unknown[0]!r}; the cyclic vector env takes 'start'")
        self.take_seed(seed, self._scenario)
        start = self._scenario.waypoints[0] if not options else self._check_start(options["start"])
        return self._restart(np.broadcast_to(start, self._start.shape))

    def _check_start(self, start: Any) -> Array:
        nq = self._scenario.waypoints.shape[1]
        names = "(" + ", ".join(self._scenario.kind.coordinate_labels(nq)) + ")"
        try:
            shape = np.shape(start)
        except ValueError:  # a ragged list: check_action names the problem
            shape = ()
        if len(shape) == 2:
            names = f"(num_envs = {self.num_envs}, {names})"
        q = check_action(start, (self.num_envs, nq) if len(shape) == 2 else (nq,), names, what="options['start']")
        for i, row in enumerate(np.atleast_2d(q)):
            try:
                self._scenario.check_start(row)
            except ValueError as error:
                raise BadInput(f"options['start']{f'[{i}]' if q.ndim == 2 else ''}: {error}") from None
        return q

    def _restart(self, start: Array) -> tuple[Array, dict[str, Any]]:
        """Every robot at rest at ``start`` ``(N, nq)``, at the first segment of the first cycle."""
        self._start = np.array(start, dtype=np.float64)
        self._x = self._scenario.plant.initial_state(self._scenario.to_task(self._start))
        self._segment, self._cycle, self._steps = 0, 1, 0
        z = self._scenario.to_chained(self._scenario.plant.configuration(self._x))
        everyone = np.ones(self.num_envs, dtype=np.bool_)
        info = {
            "q": self._start.copy(),
            "segment": np.zeros(self.num_envs, dtype=np.int64),
            "cycle": np.ones(self.num_envs, dtype=np.int64),
        }
        return self._observations(z), {**info, **{f"_{key}": everyone.copy() for key in info}}

    def _observations(self, z: Array) -> Array:
        """The measured chained states ``z`` ``(N, n)`` and the one-hot of the next segment."""
        onehot = np.tile(np.eye(self.num_segments)[self._segment], (self.num_envs, 1))
        return np.concatenate([z, onehot], axis=1)

    def step(self, actions: Any) -> tuple[Array, Array, npt.NDArray[np.bool_], npt.NDArray[np.bool_], dict[str, Any]]:
        c = check_action(actions, (self.num_envs, *self._high.shape), self._action_names, what="actions")
        applied = np.clip(c, -self._high, self._high)
        leg = self._segment
        trials = self._scenario.run(applied, x0=self._x, leg=leg, parallel=self.parallel)
        self._x = trials.final
        noise = draw_noise(self._scenario, self.np_random, self._streams, self.num_envs)
        info: dict[str, Any] = trial_infos(
            self._scenario.measure(trials.final, trials.status, leg=leg, noise=noise), applied, c
        )
        count = np.ones(self.num_envs, dtype=np.int64)
        info.update(waypoint_error=info["error"].copy(), segment=leg * count, waypoint=(leg + 1) * count)
        info["cycle"] = self._cycle * count
        rewards = np.asarray(reward(info), dtype=np.float64)
        self._segment = (leg + 1) % self.num_segments
        self._cycle += self._segment == 0
        self._steps += 1
        everyone = np.ones(self.num_envs, dtype=np.bool_)
        info = {**info, **{f"_{key}": everyone.copy() for key in info}}
        observations = self._observations(info["z_final"])
        terminations = np.zeros(self.num_envs, dtype=np.bool_)
        if self._steps < self.max_episode_steps:
            return observations, rewards, terminations, terminations.copy(), info
        final_obs = np.empty(self.num_envs, dtype=object)
        final_obs[:] = list(observations)
        observations, reset_info = self._restart(np.tile(self._scenario.waypoints[0], (self.num_envs, 1)))
        final = {"final_obs": final_obs, "_final_obs": everyone, "final_info": info, "_final_info": everyone.copy()}
        return observations, rewards, terminations, everyone.copy(), {**final, **reset_info}
