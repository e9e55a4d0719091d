"""``ChainedSteeringVectorEnv``: ``num_envs`` trials per ``step``, in one compiled batched call."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
from gymnasium.vector import AutoresetMode

from ilc_steering.config import SteeringConfig
from ilc_steering.core.external import ExternalTrials
from ilc_steering.core.nominal import NominalModel
from ilc_steering.core.plants import Plant
from ilc_steering.envs.base import check_action
from ilc_steering.envs.scenario import PlantGroups, Scenario
from ilc_steering.envs.trials import action_names, reward, task_spaces, trial_infos
from ilc_steering.envs.vector_base import SteeringVectorEnv, draw_noise
from ilc_steering.errors import BadInput

__all__ = ["ChainedSteeringVectorEnv"]

Array = npt.NDArray[np.float64]


class ChainedSteeringVectorEnv(SteeringVectorEnv):
    """``num_envs`` copies of :class:`~ilc_steering.envs.steering_env.ChainedSteeringEnv`, stepped together.

    Made by ``gym.make_vec("ilc_steering/ChainedSteering-v0", num_envs=N,
    vectorization_mode="vector_entry_point", config=...)``. Each ``step`` takes actions of shape
    ``(N, 1 + q)`` and runs ``N`` whole trials in one call of the compiled integrator, on all
    cores from :data:`PARALLEL_FROM` trials up. ``measurement_noise`` is the scalar env's; the
    noise of a step's trials is drawn in one call from the vector env's ``np_random``, or, after
    ``reset(seed=[s_0, ..., s_N-1])``, env ``i``'s from a stream seeded as the scalar env's
    ``reset(seed=s_i)`` (so env ``i`` measures what that env would). ``num_envs`` is at most
    :data:`MAX_ENVS`.

    ``true_factors`` ``(N, 2)`` makes every env a different robot: env ``i``'s true plant is the
    config's with its two parameters (``plant.factor_names``: a car's wheelbase and wheel radius)
    multiplied by row ``i`` (each ratio in :data:`~ilc_steering.core.checks.FACTOR_RANGE`), still
    one compiled call per step (``ilc-steering sweep`` maps a learner over such a grid);
    ``true_plants``, a plant per env of the config's kind, gives them outright (a map over any
    plant key, a steering offset say). Each env's trial starts from its own plant's state at rest
    and is measured as its own plant measures it, exactly as the single env with that plant does
    (a lag-free car under a lagging config included; tested bit for bit); plants that need other
    kernels (a car with and without a servo) cost a compiled call per kernel. The learner's nominal
    model is the same for all.

    Every episode is one step long, so the env resets in the same step
    (``metadata["autoreset_mode"] = AutoresetMode.SAME_STEP``) and every step is a trial: the
    returned observation is the next episode's (the task, which never changes), and the trial's
    own results are in ``info["final_info"]`` and ``info["final_obs"]``, exactly as
    ``SyncVectorEnv`` in the same mode would give them (tested, bit for bit). ``rewards``,
    ``terminations`` (all ``True``) and ``truncations`` (all ``False``) are the trials'.

    Examples
    --------
    >>> import gymnasium as gym
    >>> import ilc_steering
    >>> envs = gym.make_vec("ilc_steering/ChainedSteering-v0", num_envs=3,
    ...                     vectorization_mode="vector_entry_point", config="forward_parking")
    >>> obs, info = envs.reset(seed=0)
    >>> c = envs.unwrapped.nominal_model.solve()
    >>> obs, rewards, terminations, truncations, info = envs.step(np.tile(c, (3, 1)))
    >>> obs.shape, terminations.tolist(), bool(info["final_info"]["cartesian_error"].max() < 0.1)
    ((3, 8), [True, True, True], True)
    """

    metadata: dict[str, Any] = {"render_modes": [], "autoreset_mode": AutoresetMode.SAME_STEP}
    """No render mode: one step runs thousands of trials; render a ``ChainedSteeringEnv`` instead."""

    def __init__(
        self,
        num_envs: int,
        config: str | Path | SteeringConfig = "forward_parking",
        render_mode: str | None = None,
        parallel: bool | None = None,
        measurement_noise: float | Sequence[float] | None = None,
        true_factors: Any = None,
        true_plants: Sequence[Plant] | None = None,
    ) -> None:
        self.open(num_envs, config, "one-trial", "the vector env", render_mode)
        self._scenario = Scenario.from_config(self.config, measurement_noise)
        self._scenario.refuse_disturbances("the vector env")
        single_action_space, single_observation_space, observation = task_spaces(self._scenario)
        self.batch(single_action_space, single_observation_space, parallel)
        self._low, self._high = single_action_space.low, single_action_space.high
        self._observations = np.tile(observation, (self.num_envs, 1))
        self._action_names = f"(num_envs = {self.num_envs}, {action_names(self._scenario.nominal)})"
        if true_factors is not None and true_plants is not None:
            raise BadInput("true_factors and true_plants: give one of them, not both")
        self._plants: PlantGroups | None = None  # stacked once for every step
        if true_factors is not None:
            self._plants = PlantGroups(self._vary(true_factors))
        if true_plants is not None:
            self._plants = PlantGroups(self._own_plants(true_plants))

    @property
    def nominal_model(self) -> NominalModel:
        """The nominal model, the only view of the system a learner should use."""
        return self._scenario.nominal

    def reset(
        self, *, seed: int | list[int] | None = None, options: dict[str, Any] | None = None
    ) -> tuple[npt.NDArray[np.float32], dict[str, Any]]:
        if options:
            raise BadInput(f"options: the vector env takes none, got {sorted(options)}")
        self.take_seed(seed, self._scenario)
        return self._observations.copy(), self._reset_info()

    def step(
        self, actions: Any
    ) -> tuple[npt.NDArray[np.float32], Array, npt.NDArray[np.bool_], npt.NDArray[np.bool_], dict[str, Any]]:
        c = check_action(actions, (self.num_envs, *self._high.shape), self._action_names, what="actions")
        applied = np.clip(c, self._low, self._high)
        if self._plants is None:
            trials = self._scenario.run(applied, parallel=self.parallel)
            noise = draw_noise(self._scenario, self.np_random, self._streams, self.num_envs)
            final_info = trial_infos(self._scenario.measure(trials.final, trials.status, noise=noise), applied, c)
            if isinstance(trials, ExternalTrials):  # what the external plant logged, one dict per env
                final_info["plant"] = np.array(trials.logs, dtype=object)
        else:  # each env's trial started and measured as a single env with its plant does
            q, status = self._scenario.run_groups(applied, self._plants, parallel=self.parallel)
            noise = draw_noise(self._scenario, self.np_random, self._streams, self.num_envs)
            final_info = trial_infos(self._scenario.measure_configurations(q, status, noise=noise), applied, c)
        rewards = np.asarray(reward(final_info), dtype=np.float64)
        everyone = np.ones(self.num_envs, dtype=np.bool_)
        final_obs = np.empty(self.num_envs, dtype=object)
        final_obs[:] = list(self._observations.copy())
        info = {
            "final_obs": final_obs,
            "_final_obs": everyone,
            "final_info": {**final_info, **{f"_{key}": everyone for key in final_info}},
            "_final_info": everyone,
            **self._reset_info(),
        }
        return self._observations.copy(), rewards, everyone.copy(), np.zeros(self.num_envs, dtype=np.bool_), info

    def _vary(self, true_factors: Any) -> list[Plant]:
        """One true plant per env: the config's with its two parameters scaled by a row of
        ``true_factors``."""
        plant = self._scenario.plant
        names = f"(num_envs = {self.num_envs}, ({', '.join(plant.factor_names)}))"
        factors = check_action(true_factors, (self.num_envs, 2), names, what="true_factors")
        plants = []
        for i, row in enumerate(factors):
            try:  # the plant checks each ratio against FACTOR_RANGE, naming it with the value given
                plants.append(plant.with_true_factors(row))
            except ValueError as error:
                raise BadInput(f"true_factors[{i}]: {error}") from None
        return plants

    def _own_plants(self, plants: Sequence[Plant]) -> list[Plant]:
        """One given true plant per env, of the config's plant's kind (a car with or without servos,
        on whichever kernel each needs)."""
        plants = list(plants)
        if len(plants) != self.num_envs:
            raise BadInput(f"true_plants: one plant per env is needed ({self.num_envs}), got {len(plants)}")
        kind = self._scenario.plant.kind
        for plant in plants:
            if not isinstance(plant, Plant) or plant.kind != kind:
                raise BadInput(f"true_plants: every entry must be a Plant of kind {kind.name!r}, got {plant!r}")
        return plants

    def _reset_info(self) -> dict[str, Any]:
        everyone = np.ones(self.num_envs, dtype=np.bool_)
        start = np.tile(self._scenario.start, (self.num_envs, 1))
        goal = np.tile(self._scenario.goal, (self.num_envs, 1))
        return {"q_start": start, "_q_start": everyone, "q_goal": goal, "_q_goal": everyone.copy()}
