"""``CyclicSteeringEnv``: steer around a cycle of waypoints without ever resetting the robot (section 6)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any, ClassVar

import gymnasium as gym
import numpy as np
import numpy.typing as npt
from gymnasium.wrappers import TimeLimit

from ilc_steering.boxes import action_box
from ilc_steering.config import SteeringConfig
from ilc_steering.core.nominal import NominalModel
from ilc_steering.envs.base import Kind, SteeringEnv, check_action
from ilc_steering.envs.frames import Scene, TrialView
from ilc_steering.envs.scenario import Scenario
from ilc_steering.envs.trials import reward, trial_info
from ilc_steering.errors import BadInput

__all__ = ["CyclicSteeringEnv", "check_cycles", "make_cyclic_env"]

Array = npt.NDArray[np.float64]


class CyclicSteeringEnv(SteeringEnv):
    r"""Drive a robot around a repeating cycle of waypoints, one segment per step, never resetting it.

    ## Description

    The cycle is ``q_0^d (home) -> q_1^d -> ... -> q_{r-1}^d -> q_0^d``, each segment of fixed
    duration (section 6 of Oriolo, Panzieri, Ulivi 1998). Each step drives one segment from
    wherever the robot really is to the next waypoint, with the input profile of eqs. 15-17 for
    that segment. The robot is never put back: the next segment starts from the true final
    state of this one, including a steering servo command wound past the stop.

    ## Action Space

    The coefficients ``c = (c11, c21..c2q)`` of the current segment, in physical units, in
    ``Box(-b, b, (1 + q,), float32)`` with ``b`` from ``task.action_bound`` or 10 times the
    largest ``nominal_models[l].action_scale()`` over the segments. With ``nu < 1`` or a start
    far off home, ``c11`` is smaller than nominal and ``c2`` grows as ``1 / c11**(n-2)``: widen
    the box. Out-of-bound values are clipped; a wrong shape or a non-finite value raises
    ``ValueError``. All segments need the same ``q``.

    ## Observation Space

    ``Box(-inf, inf, (n + r,), float64)``: the *measured* configuration at the start of the next
    segment in chained coordinates (nominal map, task frame; float64 because the learner's
    feedforward uses it), then a one-hot vector of that segment's index. Gymnasium's checker
    warns about the infinite bounds: the measured state has no finite bound.

    ## Rewards

    Minus the weighted error at the waypoint reached, as for ``ChainedSteeringEnv``.

    ## Starting State

    Home, ``q_0^d``, or ``options={"start": q}`` (world configuration; ``z`` for a chained plant),
    the off-home start the cyclic scheme exists for.

    ## Episode End

    Never terminated. Truncated after the configured number of cycles by ``TimeLimit``: the
    registered ``ilc_steering/CyclicSteering-v0`` sets ``max_episode_steps = cycles * r`` with
    ``cycles`` from ``learning.trials`` or the ``cycles`` argument.

    ## Info

    ``step`` returns ``segment`` (the index ``l - 1`` of the segment driven), ``waypoint`` (the
    index ``l`` of the waypoint reached, ``r`` being home again, as in the paper), ``cycle``
    (from 1), ``waypoint_error`` and ``error`` (``z_l^d - z_l``, eq. 40's epsilon), ``error_norm``,
    ``q_final``, ``z_final``, ``left_chart``, ``action``, ``clipped`` and, for the car,
    ``cartesian_error`` [m] and ``orientation_error`` [rad], all measured, and the true errors
    (``true_error_norm``, ``true_cartesian_error``, ``true_orientation_error``); with ``record_trajectory=True``,
    ``trajectory``, the segment's :class:`~ilc_steering.core.trajectory.Trajectory` (time from
    the segment's start).

    ## Rendering

    ``render_mode="rgb_array"``: ``render()`` returns a ``(480, 480, 3)`` uint8 frame with the
    waypoint cars (home, q1, ...), the paths of the last cycle's segments and the car at
    eight instants along the last one, drawn off-screen by the package's numpy rasterizer.

    ## Arguments

    ``config``: a cyclic config (``task.waypoints``), as a YAML path, a packaged name
    (``"cyclic_home_goal"``, ``"cyclic_pickup_dropoff"``) or a :class:`SteeringConfig`.
    ``render_mode``: ``None`` or ``"rgb_array"``. ``record_trajectory``: put each segment's
    trajectory in ``info`` (off by default). ``measurement_noise``: as for ``ChainedSteeringEnv``;
    the observation is then the noisy measurement, while the robot goes on from its true state.
    ``env.unwrapped.nominal_models`` is the learner's view, one model per segment.

    ## Version History

    * v0: Initial version.

    ## Example

    >>> import gymnasium as gym
    >>> import ilc_steering
    >>> env = gym.make("ilc_steering/CyclicSteering-v0", config="cyclic_home_goal", cycles=2)
    >>> obs, info = env.reset(seed=0)
    >>> steps = 0
    >>> truncated = False
    >>> while not truncated:
    ...     model = env.unwrapped.nominal_models[info["segment"]]
    ...     obs, reward, terminated, truncated, info = env.step(model.solve())
    ...     steps += 1
    >>> steps, info["cycle"], info["waypoint"]
    (4, 2, 2)
    """

    kind: ClassVar[Kind] = "cyclic"

    def __init__(
        self,
        config: str | Path | SteeringConfig = "cyclic_home_goal",
        render_mode: str | None = None,
        record_trajectory: bool = False,
        measurement_noise: float | Sequence[float] | None = None,
    ) -> None:
        self.open(config, render_mode, record_trajectory)
        self._scenario = Scenario.from_config(self.config, measurement_noise)
        self._scenario.refuse_disturbances("the cyclic env")
        models = self._scenario.nominals
        size = models[0].profile.num_coefficients  # the same for every segment (checked by the config)
        box = action_box(self._scenario.action_high)
        self.action_space = box
        self._high = box.high
        self.num_segments = len(models)
        n = models[0].dimension
        self.observation_space = gym.spaces.Box(-np.inf, np.inf, shape=(n + self.num_segments,), dtype=np.float64)
        self._action_names = f"(c11, c21..c2{size - 1})"
        self._x = self._scenario.x_start.copy()
        self._segment = 0
        self._cycle = 1
        names = ["home", *(f"q{l}" for l in range(1, self.num_segments))]
        self._view = TrialView.of(self._scenario, names)

    @property
    def nominal_models(self) -> list[NominalModel]:
        """One nominal model per segment: the only view of the system a learner should use."""
        return self._scenario.nominals

    def _observation(self, z: Array | None = None) -> Array:
        """The measured chained state (``z``, when a trial just measured it) and the segment one-hot."""
        if z is None:
            z = self._scenario.to_chained(self._scenario.plant.configuration(self._x))
        return np.concatenate([z, np.eye(self.num_segments)[self._segment]])

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[Array, dict[str, Any]]:
        super().reset(seed=seed)
        if seed is not None:  # an external plant's own scatter follows the env's seed
            self._scenario.reseed(seed)
        if options is not None and not isinstance(options, dict):
            raise BadInput(f"options must be a dict such as {{'start': q}} or None, got {type(options).__name__}")
        unknown = sorted(set(options or {}) - {"start"})
        if unknown:
            raise BadInput(f"options: unknown key {unknown[0]!r}; the cyclic env takes 'start' (a configuration)")
        start = self._scenario.waypoints[0] if not options else self._check_start(options["start"])
        self._x = self._scenario.plant.initial_state(self._scenario.to_task(np.asarray(start, dtype=np.float64)))
        self._segment, self._cycle = 0, 1
        self._view.clear()
        return self._observation(), {"q": np.asarray(start, dtype=np.float64).copy(), "segment": 0, "cycle": 1}

    def _check_start(self, start: Any) -> Array:
        names = "(" + ", ".join(self._scenario.kind.coordinate_labels(self._scenario.waypoints.shape[1])) + ")"
        q = check_action(start, self._scenario.waypoints[0].shape, names, what="options['start']")
        try:
            self._scenario.check_start(q)
        except ValueError as error:
            raise BadInput(f"options['start']: {error}") from None
        return q

    def step(self, action: Any) -> tuple[Array, float, bool, bool, dict[str, Any]]:
        c = check_action(action, self._high.shape, self._action_names)
        applied = np.clip(c, -self._high, self._high)
        leg = self._segment
        record = self.record_trajectory or self.render_mode is not None
        trial = self._scenario.run(applied[None], x0=self._x[None], record=record, leg=leg)
        self._x = trial.final[0]
        noise = self._scenario.draw_noise(self.np_random, 1)
        info = trial_info(self._scenario.measure(trial.final, trial.status, leg=leg, noise=noise), applied, c)
        info.update(waypoint_error=info["error"], segment=leg, waypoint=leg + 1, cycle=self._cycle)
        if record:
            trajectory = self._scenario.trajectory(trial, applied[None], leg=leg)
            self._view.add(trajectory, info, keep=self.num_segments)
            if self.record_trajectory:
                info["trajectory"] = trajectory
        self._segment = (leg + 1) % self.num_segments
        self._cycle += self._segment == 0
        return self._observation(info["z_final"]), float(reward(info)), False, False, info

    def scene(self) -> Scene:
        """What ``render()`` draws, as a :class:`~ilc_steering.envs.frames.Scene` (to draw it otherwise)."""
        if self._view.count == 0:
            return self._view.scene(f"{self.config.name}: before the first segment")
        cycle, waypoint = self._cycle - (self._segment == 0), self._segment or self.num_segments
        return self._view.scene(f"{self.config.name}: cycle {cycle}, reached waypoint {waypoint}")


def check_cycles(cycles: Any) -> None:
    """``ValueError`` unless ``cycles`` is a whole number >= 1 or ``None`` (the config's ``learning.trials``)."""
    if cycles is not None and (isinstance(cycles, bool) or not isinstance(cycles, (int, np.integer)) or cycles < 1):
        raise BadInput(f"cycles must be a whole number >= 1 or None, got {cycles!r}")


def make_cyclic_env(
    config: str | Path | SteeringConfig = "cyclic_home_goal",
    cycles: int | None = None,
    render_mode: str | None = None,
    record_trajectory: bool = False,
    measurement_noise: float | Sequence[float] | None = None,
) -> gym.Env[Array, npt.NDArray[np.float32]]:
    """The registered entry point: a :class:`CyclicSteeringEnv` truncated after ``cycles`` cycles
    (default: the config's ``learning.trials``) through ``TimeLimit``."""
    check_cycles(cycles)
    env = CyclicSteeringEnv(config, render_mode, record_trajectory, measurement_noise)
    count = env.config.learning.trials if cycles is None else int(cycles)
    return TimeLimit(env, max_episode_steps=count * env.num_segments)
