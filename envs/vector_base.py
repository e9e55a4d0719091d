"""What every batched steering env shares: ``num_envs`` trials a ``step``, in one compiled call.

:class:`SteeringVectorEnv` is the base of the three batched envs (the ``vector_entry_point`` of
``ChainedSteering-v0``, ``CyclicSteering-v0`` and ``SegmentedSteering-v0``): :meth:`~SteeringVectorEnv.open`
checks ``num_envs`` and the render mode and loads the config of the env's kind,
:meth:`~SteeringVectorEnv.batch` sets the batched spaces and whether a step runs on every core, and
:meth:`~SteeringVectorEnv.take_seed` takes ``reset``'s seed: an int for the env's one stream, or a list
of one seed per env (:func:`seed_streams`), from which :func:`draw_noise` draws each trial's
measurement error as that env alone would.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
from gymnasium import spaces
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from ilc_steering.config import SteeringConfig
from ilc_steering.envs.base import Kind, check_flag, check_render_mode, open_config
from ilc_steering.envs.scenario import Scenario
from ilc_steering.errors import BadInput

__all__ = ["MAX_ENVS", "PARALLEL_FROM", "SteeringVectorEnv", "check_num_envs", "draw_noise", "seed_streams"]

Array = npt.NDArray[np.float64]

MAX_ENVS = 100_000
"""The most envs a vector env holds (checked before anything is allocated)."""
PARALLEL_FROM = 64
"""Batches of at least this many trials run on all cores (numba ``prange``); the results are
bitwise the same either way, since every trial runs the same compiled code."""


def check_num_envs(num_envs: Any) -> int:
    """``num_envs`` as an int in ``[1, MAX_ENVS]``; ``ValueError`` before anything is allocated."""
    if isinstance(num_envs, bool) or not isinstance(num_envs, (int, np.integer)) or not 1 <= num_envs <= MAX_ENVS:
        raise BadInput(f"num_envs must be an integer in [1, {MAX_ENVS}], got {num_envs!r:.40}")
    return int(num_envs)


def seed_streams(seed: Any, num_envs: int) -> tuple[int | None, list[np.random.Generator] | None]:
    """A vector env's ``reset(seed=...)``: an int or ``None`` seeds its one stream; a list of
    ``num_envs`` seeds gives env ``i`` a stream of its own, seeded as a single env's ``reset(seed=s_i)``
    seeds its ``np_random`` (so env ``i`` draws what that env would). Returns the seed of the vector
    env's own ``np_random`` (the first of a list) and the streams (``None`` without a list)."""
    if not isinstance(seed, (list, tuple)):
        return seed, None
    if len(seed) != num_envs:
        raise BadInput(f"seed: a list needs one seed per env ({num_envs}), got {len(seed)}")
    if not all(isinstance(s, (int, np.integer)) and not isinstance(s, bool) and s >= 0 for s in seed):
        raise BadInput(f"seed: every seed of a list must be an integer >= 0, got {list(seed)!r:.80}")
    return int(seed[0]), [seeding.np_random(int(s))[0] for s in seed]


def draw_noise(
    scenario: Scenario, rng: np.random.Generator, streams: list[np.random.Generator] | None, count: int
) -> Array | None:
    """Measurement errors of ``count`` trials: from ``rng`` in one call, or one row from each stream."""
    if streams is None or scenario.noise is None:
        return scenario.draw_noise(rng, count)
    return np.concatenate([scenario.draw_noise(stream, 1) for stream in streams])


class SteeringVectorEnv(VectorEnv[Any, Any, Any]):
    """The base of the batched steering envs: what they are handed, checked where it enters."""

    metadata: dict[str, Any] = {"render_modes": [], "autoreset_mode": AutoresetMode.SAME_STEP}
    """No render mode: render the env of one trial instead."""

    def open(
        self, num_envs: Any, config: str | Path | SteeringConfig, kind: Kind, env: str, render_mode: str | None
    ) -> None:
        """Check ``num_envs`` and ``render_mode`` and load ``config``, a task of ``kind`` (``env``
        names this env in a refusal); the env draws from its one stream until ``reset`` is given a list."""
        self.num_envs = check_num_envs(num_envs)
        self._streams: list[np.random.Generator] | None = None
        self.render_mode = check_render_mode(render_mode, self.metadata)
        self.config = open_config(config, kind, env)

    def batch(self, action_space: spaces.Box, observation_space: spaces.Box, parallel: bool | None) -> None:
        """One trial's spaces, batched over the envs; ``parallel`` (None: from :data:`PARALLEL_FROM` envs)."""
        self.single_action_space = action_space
        self.single_observation_space = observation_space
        self.action_space = batch_space(action_space, self.num_envs)
        self.observation_space = batch_space(observation_space, self.num_envs)
        parallel = check_flag(parallel, "parallel", none=True)
        self.parallel = self.num_envs >= PARALLEL_FROM if parallel is None else parallel

    def take_seed(self, seed: Any, scenario: Scenario | None = None) -> None:
        """``reset``'s ``seed``: the env's ``np_random`` and, for a list, a stream per env; an int seed
        replaces a list's streams; ``scenario``'s external plant, if any, reseeded with it."""
        first, streams = seed_streams(seed, self.num_envs)
        VectorEnv.reset(self, seed=first)
        if first is not None and scenario is not None:  # an external plant's own scatter follows the env's seed
            scenario.reseed(first)
        if streams is not None or first is not None:
            self._streams = streams
