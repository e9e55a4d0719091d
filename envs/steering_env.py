"""``ChainedSteeringEnv``: one episode is one trial of the paper's learning scheme."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
import numpy.typing as npt

from ilc_steering.config import SteeringConfig
from ilc_steering.core.external import ExternalTrials
from ilc_steering.core.nominal import NominalModel
from ilc_steering.envs.base import Kind, SteeringEnv, check_action
from ilc_steering.envs.frames import Scene, TrialView
from ilc_steering.envs.scenario import Scenario
from ilc_steering.envs.trials import action_names, reward, task_spaces, trial_info
from ilc_steering.errors import BadInput

__all__ = ["ChainedSteeringEnv"]


class ChainedSteeringEnv(SteeringEnv):
    r"""Steer a nonholonomic robot to a goal in one trial of fixed duration ``T``.

    ## Description

    The robot (the car-like robot of eq. 3, a unicycle, a car towing a trailer, or the chained
    form of eq. 1; ``plant.model``) starts at the task's
    start configuration. The action is the coefficient vector ``c = (c11, c21, ..., c2q)`` of the
    input profile of eqs. 15-17: ``v1`` is ``c11`` on the first piece and fixed on the others,
    ``v2(t) = sum_j c2j (t - t_{i-1})**(j-1)`` on piece ``i``. For the car, the controller turns
    ``v`` into wheel speed and steering rate with the *nominal* eqs. 4-5, while the simulated car
    has the *true*, perturbed geometry. One ``step`` runs the whole trial and the episode ends:
    each episode is one iteration of iterative learning control (Oriolo, Panzieri, Ulivi 1998).

    The car may also carry perturbations outside any geometry the controller could assume, each
    a config key, off (0) by default (:class:`~ilc_steering.core.plants.CarPlant`):
    ``plant.steering_offset`` [rad], a misaligned wheel whose true angle exceeds the measured one
    by this constant; ``plant.steering_lag`` [s], the time constant of a first-order steering
    servo (the wheel follows the commanded angle, and the controller measures the wheel);
    ``plant.speed_lag`` [s], the time constant of a first-order drive servo (the wheel speed
    follows ``u1``, from rest). A lag must be 0 or at least ``simulation.max_step``. Section 5's
    lab robot adds ``plant.steering_backlash`` [rad], play in the steering linkage, and
    ``plant.encoder_pulses``, pulses per wheel turn from which the controller dead-reckons the
    pose it uses in eqs. 4-5 (``configs/experiment_forward.yaml``, ``experiment_parallel.yaml``).

    ## Action Space

    ``Box(-action_bound, action_bound, (1 + q,), float32)`` in physical units: ``c11`` [m/s for the
    car], ``c2j`` [1/(m s^j) for the car]. The bound is ``task.action_bound`` from the config, or
    10 times ``nominal_model.action_scale()``, a per-coefficient scale of the nominal open-loop
    solution that is never zero. Out-of-bound values are *clipped* (``info["clipped"]`` says
    so); a wrong shape or a non-finite value raises ``ValueError``.
    For RL, wrap the env in ``RescaleAction(env, np.float32(-1), np.float32(1))`` (float32
    limits keep the rescaled box free of precision warnings); Gymnasium's checker otherwise warns
    that the physical box is not normalized, which is intended.

    ## Observation Space

    The task, constant within a scenario: ``Box(-b, b, (2n,), float32)`` with
    ``b = 10 (max |z| + 1)`` over the start and goal below.

    | Index | Observation | Unit | Min | Max |
    |-------|-------------|------|-----|-----|
    | 0..n-1 | start ``z(0)`` in chained coordinates (nominal map, task frame) | mixed | -b | b |
    | n..2n-1 | goal ``z^d`` in chained coordinates | mixed | -b | b |

    For the car (n = 4): ``z = (x [m], tan(phi)/(ell cos^3 theta) [1/m], tan(theta), y [m])``; for
    the unicycle (n = 3): ``z = (x, tan(theta), y)``; for the car-trailer (n = 5) the chained form
    of :mod:`ilc_steering.core.robots.car_trailer`, ending ``(tan(theta1), y1)``.

    ## Rewards

    Minus the weighted final error, as measured. A robot with a pose (car, unicycle, car-trailer:
    the trailer's pose): ``-(cartesian_error / 1 m +
    orientation_error / 1 rad)``. Chained plant: ``-||z^d - z(T)||``. A trial that left the chart
    (see Episode End) scores minus its error where it halted plus a penalty,
    ``ilc_steering.core.score.OFF_CHART_PENALTY`` (1000), so that halting early never pays.

    ## Starting State

    The task's start configuration, exactly (the paper's exact reinitialization).

    ## Episode End

    Every episode ends after its one step: ``terminated=True``, ``truncated=False``.
    A trial that drives the car within ``1e-3`` rad of ``|theta|`` or ``|phi| = pi/2`` (where
    eqs. 4-5 break down; the car-trailer also of its hitch angle ``|delta| = pi/2``, the
    jackknife) stops there; ``info["left_chart"]`` is then ``True``.

    ## Info

    ``step`` returns ``q_final`` (world frame), ``z_final``, ``error`` (``z^d - z(T)``, the
    learning error of eqs. 33-34), ``error_norm``, ``left_chart``, ``action`` (as applied, after
    clipping), ``clipped`` and, for the car, ``cartesian_error`` [m] and ``orientation_error``
    [rad]. These are *measured*: with ``measurement_noise``, the final configuration is measured
    with Gaussian errors of that standard deviation, drawn from ``self.np_random`` (seeded by
    ``reset(seed=...)``). The same errors of the true configuration are in ``true_error_norm``
    and, for the car, ``true_cartesian_error`` and ``true_orientation_error``: for scoring, not
    for learning (:func:`~ilc_steering.loop.run_trials` keeps them from the learner).
    With ``record_trajectory=True`` it also holds ``trajectory``, the trial's
    :class:`~ilc_steering.core.trajectory.Trajectory` (``t``, ``q(t)``, ``u1(t)``, ``u2(t)`` at
    every integrator step). ``reset`` returns ``q_start`` and ``q_goal``.

    ## Rendering

    ``render_mode="rgb_array"``: ``render()`` returns a ``(480, 480, 3)`` uint8 frame of the
    workspace with the start (grey) and goal (green, dashed) cars, the last trial's path and the
    car with its steered front wheel at eight instants along it, drawn off-screen by the package's
    numpy rasterizer (:mod:`ilc_steering.envs.raster`; no display, no matplotlib).

    ## Arguments

    ``config``: a YAML path, a packaged config name (``"forward_parking"``,
    ``"forward_parking_saturated"``, ``"parallel_parking"``, ...), or a :class:`SteeringConfig`.
    ``render_mode``: ``None`` or ``"rgb_array"``. ``record_trajectory``: put each trial's
    trajectory in ``info`` (off by default: recording costs memory and time on the fast path).
    ``measurement_noise``: the standard deviation of the final configuration's measurement, one
    number for every coordinate or one per coordinate (car: x [m], y [m], theta [rad], phi [rad];
    chained: z); ``None`` (the default) takes the config's ``simulation.measurement_noise``.
    ``start_error`` and ``parameter_jitter``: non-repetitive disturbances, drawn anew for every
    trial from ``self.np_random``: the standard deviation of the start configuration (imperfect
    homing; per coordinate as ``measurement_noise``), and the relative standard deviation of the
    true plant's two parameters (log-normal factors on a car's wheelbase and wheel radius, on the
    chained form's gains); ``None`` takes the config's ``simulation.start_error`` and
    ``simulation.parameter_jitter``. The learner sees neither; the true errors are what is scored.

    The learner's view of the system is ``env.unwrapped.nominal_model``
    (:class:`~ilc_steering.core.nominal.NominalModel`); the true plant stays inside the env.

    ## Version History

    * v0: Initial version.

    ## Example

    >>> import gymnasium as gym
    >>> import ilc_steering
    >>> env = gym.make("ilc_steering/ChainedSteering-v0", config="forward_parking")
    >>> obs, info = env.reset(seed=0)
    >>> c = env.unwrapped.nominal_model.solve()
    >>> obs, reward, terminated, truncated, info = env.step(c)
    >>> terminated, truncated, bool(info["cartesian_error"] < 0.1)
    (True, False, True)
    """

    kind: ClassVar[Kind] = "one-trial"

    def __init__(
        self,
        config: str | Path | SteeringConfig = "forward_parking",
        render_mode: str | None = None,
        record_trajectory: bool = False,
        measurement_noise: float | Sequence[float] | None = None,
        start_error: float | Sequence[float] | None = None,
        parameter_jitter: float | None = None,
    ) -> None:
        self.open(config, render_mode, record_trajectory)
        self._scenario = Scenario.from_config(self.config, measurement_noise, start_error, parameter_jitter)
        action_space, observation_space, self._observation = task_spaces(self._scenario)
        self.observation_space = observation_space
        self.action_space = action_space
        self._low, self._high = action_space.low, action_space.high
        self._action_names = action_names(self._scenario.nominal)
        self._view = TrialView.of(self._scenario, ["start", "goal"])

    @property
    def nominal_model(self) -> NominalModel:
        """The nominal model, the only view of the system a learner should use."""
        return self._scenario.nominal

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[npt.NDArray[np.float32], dict[str, Any]]:
        super().reset(seed=seed)
        if seed is not None:  # an external plant's own scatter follows the env's seed
            self._scenario.reseed(seed)
        if options:  # a trial starts where the task says; start_error draws its homing errors
            raise BadInput(
                f"options: the one-trial env takes none, got {sorted(map(str, options))}; its trials start at "
                "task.start (simulation.start_error draws imperfect homing), the cyclic env takes {'start': q}"
            )
        info = {"q_start": self._scenario.start.copy(), "q_goal": self._scenario.goal.copy()}
        return self._observation.copy(), info

    def step(self, action: Any) -> tuple[npt.NDArray[np.float32], float, bool, bool, dict[str, Any]]:
        c = check_action(action, self._high.shape, self._action_names)
        applied = np.clip(c, self._low, self._high)
        record = self.record_trajectory or self.render_mode is not None
        x0, plant = self._scenario.draw_disturbance(self.np_random)
        trials = self._scenario.run(applied[None], None if x0 is None else x0[None], record, plant=plant)
        noise = self._scenario.draw_noise(self.np_random, 1)
        info = trial_info(self._scenario.measure(trials.final, trials.status, noise=noise), applied, c)
        if isinstance(trials, ExternalTrials):  # what the external plant logged (its own actions, a crash)
            info["plant"] = trials.logs[0]
        if record:
            trajectory = self._scenario.trajectory(trials, applied[None])
            self._view.add(trajectory, info, keep=1)
            if self.record_trajectory:
                info["trajectory"] = trajectory
        return self._observation.copy(), float(reward(info)), True, False, info

    def scene(self) -> Scene:
        """What ``render()`` draws, as a :class:`~ilc_steering.envs.frames.Scene` (to draw it otherwise)."""
        count = self._view.count
        return self._view.scene(f"{self.config.name}: " + (f"trial {count}" if count else "before the first trial"))
