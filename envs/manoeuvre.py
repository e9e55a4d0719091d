"""A manoeuvre's parts and the rules of one of its trials, shared by ``SegmentedSteering-v0``
(:class:`~ilc_steering.envs.segmented_env.SegmentedSteeringEnv`) and its vector entry point
(:class:`~ilc_steering.envs.segmented_vector_env.SegmentedSteeringVectorEnv`), so the two step
one trial by the same rules: each segment's scenario, view and box (:class:`Manoeuvre`), how a
state is carried into the next segment's frame, when a segment may not start, where it is
measured to have begun, and the trial's ``info`` from its segments' (:func:`summary`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import gymnasium as gym
import numpy as np
import numpy.typing as npt

from ilc_steering.config import SteeringConfig
from ilc_steering.core.external import is_external
from ilc_steering.core.plants import CHART_MARGIN
from ilc_steering.core.robots.car import rotate
from ilc_steering.core.score import TRUE_KEYS
from ilc_steering.envs.scenario import Scenario
from ilc_steering.envs.segment_views import Carried, SegmentTask, SegmentView
from ilc_steering.envs.trials import action_names, task_spaces
from ilc_steering.errors import BadInput

__all__ = ["WORST", "Manoeuvre", "at_edge", "summary", "wrapped"]

Array = npt.NDArray[np.float64]

WORST = ("error_norm", "cartesian_error", "orientation_error", *TRUE_KEYS)
"""The errors of a trial that are the worst over its segments' ends (every waypoint counted)."""


def at_edge(scenario: Scenario, q_task: Array) -> Array:
    """Configurations in a segment's task frame, a heading past its chart read at the chart's edge
    (as ``Scenario.measure`` reads a noisy one), where the chained map is defined."""
    q = np.array(q_task, dtype=np.float64)
    if scenario.kind.has_pose:
        q = wrapped(q)
        edge = np.pi / 2 - CHART_MARGIN
        q[..., 2:] = np.clip(q[..., 2:], -edge, edge)
    return q


def wrapped(x: Array) -> Array:
    """A state with a pose (``x, y, theta`` first) with ``theta`` wrapped to ``(-pi, pi]``."""
    out = np.array(x, dtype=np.float64)
    out[..., 2] = np.angle(np.exp(1j * out[..., 2]))
    return out


def _turns_with_frame(scenario: Scenario, angle: float = 0.5) -> bool:
    """Whether the plant's state turns with the task frame as ``rotate`` turns it (``x, y, theta``
    first): its configuration and the controller's estimate of a turned state are the turned ones.
    A lab robot's dead-reckoned estimate, further along its state, does not turn."""
    q = scenario.to_task(scenario.start)
    x, plant = scenario.plant.initial_state(q), scenario.plant
    turned = rotate(x, angle)
    return bool(
        np.allclose(plant.configuration(turned), rotate(plant.configuration(x), angle))
        and np.allclose(plant.estimate(turned), rotate(plant.estimate(x), angle))
    )


@dataclass(frozen=True)
class Manoeuvre:
    """A manoeuvre config's segments, built once: each segment's :class:`Scenario` (one plant for
    all), its learner's :class:`SegmentView`, its action box ``(low, high)`` (a segment's ``c11``
    keeping the sign of its ``direction``), and the spaces of the whole trial."""

    config: SteeringConfig
    segments: tuple[Scenario, ...]
    views: tuple[SegmentView, ...]
    boxes: tuple[tuple[npt.NDArray[Any], npt.NDArray[Any]], ...]  # each segment's (low, high), float32
    action_space: gym.spaces.Box
    observation_space: gym.spaces.Box
    observation: npt.NDArray[np.float32]
    action_names: str

    @classmethod
    def build(cls, config: SteeringConfig, measurement_noise: float | Sequence[float] | None) -> Manoeuvre:
        """The manoeuvre of ``config`` (a segmented config), refused in one line where its plant cannot
        drive it: an external plant without ``carry_on()``, segments in several frames for a plant
        whose state does not turn with the frame."""
        plant = config.plant.plant()  # one car for every segment
        if is_external(plant) and not isinstance(plant, Carried):
            raise BadInput(
                f"{config.name}: plant.model {config.plant.model} resets for every trial and cannot go "
                "on from where a segment left it (an external plant needs carry_on() for a manoeuvre)"
            )
        segments = tuple(Scenario.from_config(c, measurement_noise, plant=plant) for c in config.segment_configs())
        for scenario in segments:
            scenario.refuse_disturbances("the segmented env")
        if len({s.frame for s in segments}) > 1 and not _turns_with_frame(segments[0]):
            raise BadInput(
                f"{config.name}: segments in different frames need a plant whose state turns with the frame "
                "(x, y, theta first); a lab robot's dead-reckoned estimate does not: give every segment one frame"
            )
        views: list[SegmentView] = []
        boxes: list[tuple[npt.NDArray[Any], npt.NDArray[Any]]] = []
        legs = config.task.segments  # type: ignore[union-attr]
        for c, scenario, leg in zip(config.segment_configs(), segments, legs):
            action_space, observation_space, observation = task_spaces(scenario)
            low, high = action_space.low.copy(), action_space.high.copy()
            if leg.direction is not None:  # the learned piece's direction: c11 keeps its sign (eq. 12)
                (low if leg.direction == "forward" else high)[0] = 0.0
            boxes.append((low, high))
            task = SegmentTask(c.name, c.learning)
            views.append(SegmentView(task, scenario.nominal, action_space, observation_space, observation))
        low, high = (np.concatenate(bounds) for bounds in zip(*boxes))
        bound = np.concatenate([view.observation_space.high for view in views])
        return cls(
            config,
            segments,
            tuple(views),
            tuple(boxes),
            gym.spaces.Box(low, high, dtype=np.float32),
            gym.spaces.Box(-bound, bound, dtype=np.float32),
            np.concatenate([view.observation for view in views]),
            " + ".join(action_names(view.nominal_model) for view in views),
        )

    def split(self, c: Array) -> list[Array]:
        """The whole trial's coefficients ``(..., sum_k (1 + q_k))`` cut into each segment's."""
        sizes = [view.action_space.shape[0] for view in self.views]
        return np.split(c, np.cumsum(sizes)[:-1], axis=-1)

    def carry(self, x: Array, k: int) -> Array:
        """Plant states ``(..., nx)`` at the end of segment ``k - 1`` in segment ``k``'s frame, the heading
        wrapped to ``(-pi, pi]`` (a turn of the frame may carry it past ``pi``, where an external
        plant reads it wrapped)."""
        turn = self.segments[k].frame - self.segments[k - 1].frame
        return wrapped(rotate(x, turn)) if turn else x

    def refusal(self, k: int, x0: Array) -> str | None:
        """Why segment ``k`` cannot start from plant state ``x0`` ``(1, nx)`` (its frame), or ``None``:
        a start off its chart or past the plant's limits (``check_configuration``) is not run."""
        plant = self.segments[k].plant
        try:
            plant.check_configuration(plant.configuration(x0))
        except ValueError as error:
            return f"segment {k} would start off its chart: {error}"
        return None

    @staticmethod
    def measured_start(scenario: Scenario, q_world: Array) -> Array:
        """Where a segment began, in its own chained coordinates: the last segment's measured end
        (world frame), in this segment's frame, through the nominal map (at the chart's edge if past it)."""
        z: Array = scenario.to_chained(at_edge(scenario, scenario.to_task(q_world)))
        return z


def summary(infos: list[dict[str, Any]]) -> dict[str, Any]:
    """A trial's ``info`` from its segments' (in order): the worst waypoint's errors (NaN if any is,
    and then ``left_chart``: a NaN never hides behind a finite error), the goal's configuration, and
    each segment's own without the true errors."""
    last = infos[-1]
    worst = {key: np.array([i[key] for i in infos], dtype=np.float64) for key in WORST if key in last}
    info: dict[str, Any] = {key: float(np.max(values)) for key, values in worst.items()}
    info.update(
        q_final=last["q_final"],
        z_final=last["z_final"],
        error=np.concatenate([i["error"] for i in infos]),
        action=np.concatenate([i["action"] for i in infos]),
        left_chart=any(i["left_chart"] for i in infos) or not all(np.isfinite(v).all() for v in worst.values()),
        clipped=any(i["clipped"] for i in infos),
        segments=[{k: v for k, v in i.items() if k not in TRUE_KEYS} for i in infos],
    )
    logs = [i["plant"] for i in infos if "plant" in i]
    if logs:  # one log for the trial, as the one-trial env gives: every segment's actions, back to back
        info["plant"] = {
            **logs[-1],
            "actions": [a for log in logs for a in log["actions"]],
            "crashed": any(log.get("crashed", False) for log in logs),
            "left_lot": any(log.get("left_lot", False) for log in logs),
            "refused": any(log.get("refused", False) for log in logs),
            "segments_driven": sum(bool(log["actions"]) for log in logs),
        }
    return info
