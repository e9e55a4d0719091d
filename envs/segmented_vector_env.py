"""``SegmentedSteeringVectorEnv``: ``num_envs`` trials of a manoeuvre per ``step``, one batched call per segment."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
from gymnasium.vector import AutoresetMode

from ilc_steering.config import SteeringConfig
from ilc_steering.core.integrate import OK
from ilc_steering.core.nominal import NominalModel
from ilc_steering.envs.base import check_action
from ilc_steering.envs.manoeuvre import Manoeuvre, at_edge, summary
from ilc_steering.envs.scenario import Scenario
from ilc_steering.envs.segment_views import SegmentView
from ilc_steering.envs.trials import reward, trial_info
from ilc_steering.envs.vector_base import SteeringVectorEnv, draw_noise
from ilc_steering.errors import BadInput

__all__ = ["SegmentedSteeringVectorEnv"]

Array = npt.NDArray[np.float64]


class SegmentedSteeringVectorEnv(SteeringVectorEnv):
    """``num_envs`` copies of :class:`~ilc_steering.envs.segmented_env.SegmentedSteeringEnv`, stepped together.

    Made by ``gym.make_vec("ilc_steering/SegmentedSteering-v0", num_envs=N,
    vectorization_mode="vector_entry_point", config=...)``. Each ``step`` takes actions of shape
    ``(N, sum_k (1 + q_k))`` (every segment's coefficients, as the scalar env's) and runs ``N``
    whole trials of the manoeuvre: segment ``k`` of every trial that goes on to it in one call of
    the compiled integrator (on all cores from
    :data:`~ilc_steering.envs.steering_vector_env.PARALLEL_FROM` trials up), each from where its own
    trial's segment ``k - 1`` ended, by the scalar env's rules (:mod:`~ilc_steering.envs.manoeuvre`):
    a trial whose segment left its chart runs none of its later segments, a segment that would start
    off its chart or that the plant refuses is not run, and the trial counts once. The plant must be
    simulated: an external plant (one robot) cannot drive ``N`` trials at once; use
    ``vectorization_mode="sync"`` for it.

    Every episode is one step long, so the env resets in the same step
    (``metadata["autoreset_mode"] = AutoresetMode.SAME_STEP``) and every step is a trial: the
    returned observation is the next episode's (the task, which never changes), and the trial's
    own results are in ``info["final_info"]`` (each trial's ``segments`` an entry of an object
    array) and ``info["final_obs"]``, exactly as ``SyncVectorEnv`` of the scalar env in the same
    mode gives them (tested, bit for bit). ``measurement_noise`` is the scalar env's; a segment's
    noise is drawn in one call from the vector env's ``np_random``, or, after ``reset(seed=[s_0,
    ..., s_N-1])``, env ``i``'s from a stream seeded as the scalar env's ``reset(seed=s_i)`` (so
    env ``i`` measures what that env would). ``num_envs`` is at most
    :data:`~ilc_steering.envs.steering_vector_env.MAX_ENVS`.

    Examples
    --------
    >>> import gymnasium as gym
    >>> import ilc_steering
    >>> envs = gym.make_vec("ilc_steering/SegmentedSteering-v0", num_envs=3,
    ...                     vectorization_mode="vector_entry_point", config="segmented_parking")
    >>> obs, info = envs.reset(seed=0)
    >>> c = np.concatenate([view.nominal_model.solve() for view in envs.unwrapped.segment_views()])
    >>> obs, rewards, terminations, truncations, info = envs.step(np.tile(c, (3, 1)))
    >>> terminations.tolist(), [len(s) for s in info["final_info"]["segments"]]
    ([True, True, True], [2, 2, 2])
    >>> bool(info["final_info"]["cartesian_error"].max() < 0.2)
    True
    """

    metadata: dict[str, Any] = {"render_modes": [], "autoreset_mode": AutoresetMode.SAME_STEP}
    """No render mode: render a ``SegmentedSteeringEnv`` instead."""

    def __init__(
        self,
        num_envs: int,
        config: str | Path | SteeringConfig = "segmented_parking",
        render_mode: str | None = None,
        parallel: bool | None = None,
        measurement_noise: float | Sequence[float] | None = None,
    ) -> None:
        self.open(num_envs, config, "segmented", "the segmented vector env", render_mode)
        self._manoeuvre = Manoeuvre.build(self.config, measurement_noise)
        if self._manoeuvre.segments[0].external is not None:
            raise BadInput(
                f"{self.config.name}: plant.model {self.config.plant.model} is one external robot, which cannot "
                "drive num_envs trials at once; use vectorization_mode='sync' for it"
            )
        self.batch(self._manoeuvre.action_space, self._manoeuvre.observation_space, parallel)
        self._observations = np.tile(self._manoeuvre.observation, (self.num_envs, 1))
        self._action_names = f"(num_envs = {self.num_envs}, {self._manoeuvre.action_names})"

    def segment_views(self) -> list[SegmentView]:
        """Each segment's one-trial view, for the learner of that segment (the nominal models only)."""
        return list(self._manoeuvre.views)

    @property
    def nominal_model(self) -> NominalModel:
        """The last segment's nominal model (the one that ends at the goal)."""
        return self._manoeuvre.views[-1].nominal_model

    def reset(
        self, *, seed: int | list[int] | None = None, options: dict[str, Any] | None = None
    ) -> tuple[npt.NDArray[np.float32], dict[str, Any]]:
        if options:
            raise BadInput(f"options: the segmented vector env takes none, got {sorted(map(str, options))}")
        self.take_seed(seed)
        return self._observations.copy(), self._reset_info()

    def step(
        self, actions: Any
    ) -> tuple[npt.NDArray[np.float32], Array, npt.NDArray[np.bool_], npt.NDArray[np.bool_], dict[str, Any]]:
        m, count = self._manoeuvre, self.num_envs
        c = check_action(actions, (count, *m.action_space.shape), self._action_names, what="actions")
        infos: list[list[dict[str, Any]]] = [[] for _ in range(count)]
        x: Array | None = None
        halted = np.zeros(count, dtype=np.bool_)
        for k, (scenario, view, requested) in enumerate(zip(m.segments, m.views, m.split(c))):
            applied = np.clip(requested, *m.boxes[k])
            x0 = None if x is None else m.carry(x, k)
            noise = draw_noise(scenario, self.np_random, self._streams, count)
            refused: list[str | None] = [None] * count
            if x0 is not None:
                for j in np.flatnonzero(~halted):
                    refused[j] = m.refusal(k, x0[j : j + 1])
            ran = ~halted & np.array([r is None for r in refused])
            x, status = self._run(k, scenario, applied, x0, ran, refused)
            q = np.array(scenario.plant.configuration(x), dtype=np.float64)  # a copy: x goes on to segment k + 1
            edge = status != OK  # halted, or not run: read at the chart's edge if past it
            q[edge] = at_edge(scenario, q[edge])
            measured = scenario.measure_configurations(q, status, noise=noise)
            for i in range(count):
                row = {key: value[i : i + 1] for key, value in measured.items()}
                z_start = (
                    m.measured_start(scenario, infos[i][-1]["q_final"]) if k else view.nominal_model.z_start.copy()
                )
                info = {**trial_info(row, applied[i], requested[i]), "z_start": z_start, "ran": bool(ran[i])}
                infos[i].append({**info, **({"refused": refused[i]} if refused[i] else {})})
            halted = ~ran | measured["left_chart"]
        return self._batched([summary(trial) for trial in infos])

    def _run(
        self,
        k: int,
        scenario: Scenario,
        applied: Array,
        x0: Array | None,
        ran: npt.NDArray[np.bool_],
        refused: list[str | None],
    ) -> tuple[Array, npt.NDArray[np.int64]]:
        """Segment ``k`` of the trials in ``ran`` in one call, from ``x0`` (``None``: the start): every
        trial's plant state after it ``(N, nx)`` (a trial not run stays at ``x0``) and status (not run: 1).
        Where the plant refuses the batch past the first segment, each trial is run alone, as the scalar
        env runs it, and the one refused is marked in ``ran`` and ``refused`` (segment 0 raises)."""
        count = self.num_envs
        final = np.empty((count, scenario.x_start.shape[0])) if x0 is None else np.array(x0, dtype=np.float64)
        status = np.ones(count, dtype=np.int64)
        index = np.flatnonzero(ran)
        if not index.size:
            return final, status
        start = None if x0 is None else np.ascontiguousarray(x0[index])
        try:
            trials = scenario.run(np.ascontiguousarray(applied[index]), start, parallel=self.parallel)
        except ValueError:
            if not k or x0 is None:
                raise
            for i in index:  # which of them the plant refuses: each alone, as the scalar env runs it
                try:
                    one = scenario.run(applied[i : i + 1], np.ascontiguousarray(x0[i : i + 1]))
                except ValueError as error:
                    ran[i] = False
                    refused[i] = f"segment {k} refused: {type(error).__name__}: {error}"
                    continue
                final[i], status[i] = one.final[0], one.status[0]
            return final, status
        final[index], status[index] = trials.final, trials.status
        return final, status

    def _batched(
        self, trials: list[dict[str, Any]]
    ) -> tuple[npt.NDArray[np.float32], Array, npt.NDArray[np.bool_], npt.NDArray[np.bool_], dict[str, Any]]:
        """The step's results from each trial's ``info``: batched as ``SyncVectorEnv`` batches its
        envs' (through ``VectorEnv._add_info``, the base class's rule for it), in the same step."""
        rewards = np.array([float(reward(info)) for info in trials], dtype=np.float64)
        reset = self._reset_info()
        batched: dict[str, Any] = {}
        for i, info in enumerate(trials):
            batched = self._add_info(batched, {"final_obs": self._observations[i].copy(), "final_info": info}, i)
            batched = self._add_info(batched, {key: value[i] for key, value in reset.items() if key[0] != "_"}, i)
        everyone = np.ones(self.num_envs, dtype=np.bool_)
        return self._observations.copy(), rewards, everyone, np.zeros(self.num_envs, dtype=np.bool_), batched

    def _reset_info(self) -> dict[str, Any]:
        everyone = np.ones(self.num_envs, dtype=np.bool_)
        start = np.tile(self._manoeuvre.segments[0].start, (self.num_envs, 1))
        goal = np.tile(self._manoeuvre.segments[-1].goal, (self.num_envs, 1))
        return {"q_start": start, "_q_start": everyone, "q_goal": goal, "_q_goal": everyone.copy()}
