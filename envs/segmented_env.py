r"""``SegmentedSteeringEnv``: a manoeuvre of several segments, run back to back in one trial.

**Design.** A manoeuvre is ``start -> via[0] -> ... -> goal`` (``task.via``, ``task.segments``;
:class:`~ilc_steering.config.SegmentedTaskConfig`), each segment a one-trial task of its own: its
profile (eqs. 15-17), its chart (``frame``, the task frame it is steered in) and its direction of
travel (``forward`` or ``reverse``, the sign of ``c11``, checked on loading). The config builds each
segment as the one-trial config it is (``config.segment_configs()``), so every rule of a one-trial
task is checked once, per segment, where it is checked today, and each segment's
:class:`~ilc_steering.envs.scenario.Scenario` is the one the one-trial env would build.

One trial is one ``step``: the segments run back to back on the same plant, nothing reset between
them; segment ``k + 1`` starts from the plant state segment ``k`` really ended in (rotated from
frame ``k`` to frame ``k + 1``). Every trial counts once, whatever its segments, and every waypoint
is counted: the trial's errors are the worst over the segments' ends.

The learner is one learner per segment (:class:`~ilc_steering.segmented.SegmentedLearner`), each
built by the usual factory from its own segment's view (:meth:`SegmentedSteeringEnv.segment_views`: the one-trial env's
nominal model, action box and observation), and each handed its own segment's ``info``. So every
existing learner runs unchanged: it sees exactly a one-trial env. One stacked vector for all
segments would have needed a stacked nominal model (``K n`` errors, a block ``W``) that no learner
knows. Segment ``k + 1`` starts where segment ``k`` really ended, which moves while segment ``k``
learns; its ``info`` says where (``z_start``, measured, in its own chart), and the learner re-bases
the error to the via point on the nominal model (:func:`~ilc_steering.segmented.rebased`, eq. 23,
the cyclic law's eq. 39 moved to the error; from the raw error, segment ``k + 1`` took segment
``k``'s miss for its own: 5-6 trials to 5e-4 on ``segmented_parking``, 2-4 alone).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
import numpy.typing as npt

from ilc_steering.config import SteeringConfig
from ilc_steering.core.external import ExternalTrials
from ilc_steering.core.integrate import OK
from ilc_steering.core.nominal import NominalModel
from ilc_steering.core.trajectory import Trajectory
from ilc_steering.envs.base import Kind, SteeringEnv, check_action
from ilc_steering.envs.frames import Scene, TrialView
from ilc_steering.envs.manoeuvre import Manoeuvre, at_edge, summary
from ilc_steering.envs.segment_views import Carried, SegmentTask, SegmentView
from ilc_steering.envs.trials import reward, trial_info
from ilc_steering.errors import BadInput

__all__ = ["Carried", "SegmentTask", "SegmentView", "SegmentedSteeringEnv"]

Array = npt.NDArray[np.float64]


def _joined(trajectories: Sequence[Trajectory]) -> Trajectory:
    """The segments' trajectories (each in the world frame, its time from its own start) as one: the
    times run on from one segment into the next, whose first sample (the last one's end) is dropped."""
    t, q, u = [trajectories[0].t], [trajectories[0].q], [trajectories[0].u]
    for trajectory in trajectories[1:]:
        t.append(t[-1][-1] + trajectory.t[1:])
        q.append(trajectory.q[1:])
        u.append(trajectory.u[1:])
    return Trajectory(np.concatenate(t), np.concatenate(q), np.concatenate(u), any(x.left_chart for x in trajectories))


class SegmentedSteeringEnv(SteeringEnv):
    r"""Steer a robot through a manoeuvre of several segments in one trial (see the module's design).

    ## Description

    The robot starts at ``task.start`` and runs segment ``k`` (waypoint ``k`` to ``k + 1``) with
    the input profile of eqs. 15-17 in the segment's own task frame, from the state the last
    segment ended in. One ``step`` is one trial: every segment, back to back.

    ## Action Space

    The segments' coefficient vectors ``(c11, c21..c2q)`` concatenated, each in its segment's box
    (10 times its nominal model's ``action_scale()``): ``Box(-b, b, (sum_k (1 + q_k),), float32)``,
    but a segment's ``c11`` keeps the sign of its ``direction`` (the learned piece's: ``[0, b]``
    forward, ``[-b, 0]`` reverse; a segment's view keeps the one-trial env's symmetric box, where its
    nominal solution is checked). Out-of-bound values are clipped; a wrong shape or a non-finite
    value raises ``ValueError``.

    ## Observation Space

    The segments' one-trial observations (their start and goal ``z`` in their own charts)
    concatenated, constant.

    ## Rewards

    Minus the weighted error at the worst waypoint (``ChainedSteeringEnv``'s reward of it).

    ## Starting State

    ``task.start``, exactly.

    ## Episode End

    After its one step: ``terminated=True``. A segment that leaves its chart ends the trial there;
    the later segments are not run (``ran=False``) and each is measured where the robot halted,
    ``left_chart``. The trial counts once, failed. So does a segment that would start off its own
    chart (the carried heading, wrapped to ``(-pi, pi]``, refused by the plant's
    ``check_configuration``) or that the plant refuses after an earlier one drove it (a
    ``ValueError``): it is not run, and its ``info`` says why (``refused``).

    ## Info

    ``segments``: one ``info`` per segment, as the one-trial env's for its waypoint, without the
    true errors, and ``z_start``: where the segment began, in its chart's chained coordinates
    (measured: the last segment's measured end; segment 0: ``task.start``) and ``ran`` (``False``:
    an earlier segment halted, this one was not run and must not be learned from); at the top, the worst
    ``error_norm``, ``cartesian_error``, ``orientation_error`` over the waypoints (measured and
    ``true_``), ``left_chart`` and ``clipped`` of any segment, ``q_final`` and ``z_final`` at the
    goal, ``error`` (every segment's, concatenated) and ``action``; with ``record_trajectory=True``,
    ``trajectories``, one per segment run, and ``trajectory``, them joined (time running on).

    ## Rendering

    ``render_mode="rgb_array"``: the waypoints and the last trial's segments, ``(480, 480, 3)``.

    ## Arguments

    ``config``: a manoeuvre config (``task.segments``), a path, a packaged name or a
    :class:`SteeringConfig`. ``render_mode``, ``record_trajectory``, ``measurement_noise``: as for
    ``ChainedSteeringEnv``. ``env.unwrapped.segment_views()`` is each segment's learner's view.

    ## Version History

    * v0: Initial version.

    ## Example

    >>> import gymnasium as gym
    >>> import numpy as np
    >>> import ilc_steering
    >>> env = gym.make("ilc_steering/SegmentedSteering-v0", config="segmented_parking")
    >>> obs, info = env.reset(seed=0)
    >>> c = np.concatenate([view.nominal_model.solve() for view in env.unwrapped.segment_views()])
    >>> obs, reward, terminated, truncated, info = env.step(c)
    >>> len(info["segments"]), terminated, bool(info["cartesian_error"] < 0.2)
    (2, True, True)
    """

    kind: ClassVar[Kind] = "segmented"

    def __init__(
        self,
        config: str | Path | SteeringConfig = "segmented_parking",
        render_mode: str | None = None,
        record_trajectory: bool = False,
        measurement_noise: float | Sequence[float] | None = None,
    ) -> None:
        self.open(config, render_mode, record_trajectory)
        self._manoeuvre = Manoeuvre.build(self.config, measurement_noise)
        self._segments = self._manoeuvre.segments
        self._views = self._manoeuvre.views
        self.action_space = self._manoeuvre.action_space
        self.observation_space = self._manoeuvre.observation_space
        self._observation = self._manoeuvre.observation
        waypoints = np.array(self.config.task.waypoints, dtype=np.float64)  # type: ignore[union-attr]
        names = ["start", *(f"via{i}" for i in range(len(waypoints) - 2)), "goal"]
        model = self._segments[0].nominal
        self._view = TrialView(waypoints, model.chained_map, names, self._segments[0].kind.has_pose)

    def segment_views(self) -> list[SegmentView]:
        """Each segment's one-trial view, for the learner of that segment (the nominal models only)."""
        return list(self._views)

    @property
    def nominal_model(self) -> NominalModel:
        """The last segment's nominal model (the one that ends at the goal)."""
        return self._views[-1].nominal_model

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[npt.NDArray[np.float32], dict[str, Any]]:
        super().reset(seed=seed)
        if options:
            raise BadInput(f"options: the segmented env takes none, got {sorted(map(str, options))}")
        if seed is not None:  # an external plant's own scatter (each segment's frame of the one car)
            for scenario in self._segments:
                scenario.reseed(seed)
        return self._observation.copy(), {
            "q_start": self._segments[0].start.copy(),
            "q_goal": self._segments[-1].goal.copy(),
        }

    def step(self, action: Any) -> tuple[npt.NDArray[np.float32], float, bool, bool, dict[str, Any]]:
        m = self._manoeuvre
        c = check_action(action, m.action_space.shape, m.action_names)
        record = self.record_trajectory or self.render_mode is not None
        pieces = m.split(c)
        infos: list[dict[str, Any]] = []
        trajectories = []
        x: Array | None = None
        halted = False
        for k, (scenario, view, requested) in enumerate(zip(self._segments, self._views, pieces)):
            applied = np.clip(requested, *m.boxes[k])
            x0 = None if x is None else m.carry(x, k)[None]
            noise = scenario.draw_noise(self.np_random, 1)
            z_start = view.nominal_model.z_start if not k else m.measured_start(scenario, infos[-1]["q_final"])
            refused = None if halted or x0 is None else m.refusal(k, x0)
            trials = None
            if not (halted or refused):
                if k and isinstance(scenario.external, Carried):  # the same car goes on, no reset
                    scenario.external.carry_on()
                try:  # once the car has driven, whatever refuses a segment fails the trial, counted
                    trials = scenario.run(applied[None], x0, record)
                except ValueError as error:
                    if not k:
                        raise
                    refused = f"segment {k} refused: {type(error).__name__}: {error}"
            if trials is None:  # not run: measured where the robot halted, off its chart (at the edge if past it)
                q = at_edge(scenario, scenario.plant.configuration(x0))  # type: ignore[arg-type]
                measured = scenario.measure_configurations(q, np.ones(1, dtype=np.int64), noise=noise)
                infos.append({**trial_info(measured, applied, requested), "z_start": z_start, "ran": False})
                infos[-1].update({"refused": refused} if refused else {})
                x, halted = x0[0], True  # type: ignore[index]
                continue
            q = scenario.plant.configuration(trials.final)
            if trials.status[0] != OK:  # halted (its chart, a wall): read at the chart's edge if past it
                q = at_edge(scenario, q)
            measured = scenario.measure_configurations(q, trials.status, noise=noise)
            infos.append({**trial_info(measured, applied, requested), "z_start": z_start, "ran": True})
            if isinstance(trials, ExternalTrials):  # what the external plant logged (its actions, a crash)
                infos[-1]["plant"] = trials.logs[0]
            x = trials.final[0]
            halted = infos[-1]["left_chart"]
            if record:
                trajectories.append(scenario.trajectory(trials, applied[None]))
        info = summary(infos)
        if record:
            for trajectory in trajectories:
                self._view.add(trajectory, info, keep=len(trajectories))
            if self.record_trajectory:
                info["trajectories"] = trajectories
                info["trajectory"] = _joined(trajectories)
        return self._observation.copy(), float(reward(info)), True, False, info

    def scene(self) -> Scene:
        """What ``render()`` draws, as a :class:`~ilc_steering.envs.frames.Scene`."""
        count = self._view.count
        return self._view.scene(f"{self.config.name}: " + ("last trial" if count else "before the first trial"))
