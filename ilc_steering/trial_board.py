"""TensorBoard event files of a learning run: one scalar per trial, the same tags for every learner.

The trial loop writes them where it is asked to (:func:`~ilc_steering.loop.run_trials`'s
``tensorboard=``; ``ilc-steering run`` and ``ilc-steering compare`` take ``--tensorboard DIR``), so
the paper's ILC, a black-box optimizer and an RL algorithm on one scenario write the same tags
(:data:`TAGS`) against the same x axis, the trial's number (TensorBoard's step), and lie on one
chart. The writer is TensorBoard's own, ``tensorboard.summary.Writer``, which needs numpy only
(neither TensorFlow nor torch): the ``tensorboard`` extra installs it.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import gymnasium as gym

from ilc_steering.agents.registry import METHODS
from ilc_steering.core.scatter import HOLD
from ilc_steering.core.score import Tolerance, true_cost, within_tolerance
from ilc_steering.envs.base import SteeringEnv
from ilc_steering.errors import BadInput
from ilc_steering.output import check_output_dir, injective_name

__all__ = ["EXTRA", "TAGS", "TrialBoard", "check_tensorboard", "require_tensorboard", "run_folder"]

EXTRA = 'pip install "ilc-steering[tensorboard]"'
"""How to install the writer."""

ERRORS = (
    "cartesian_error",
    "orientation_error",
    "error_norm",
    "true_cartesian_error",
    "true_orientation_error",
    "true_error_norm",
)
"""The ``info`` keys written as they are, where the env reports them (a chained plant has no pose errors)."""

TAGS = {
    "trial/cartesian_error": "Cartesian error as measured [m]",
    "trial/orientation_error": "orientation error as measured [rad]",
    "trial/error_norm": "||z^d - z(T)|| as measured (chained coordinates)",
    "trial/true_cartesian_error": "Cartesian error of the true final configuration [m]",
    "trial/true_orientation_error": "orientation error of the true final configuration [rad]",
    "trial/true_error_norm": "||z^d - z(T)|| of the true final configuration",
    "trial/cost": "the true cost compare scores: Cartesian [m] + orientation [rad] error (a chained plant: the "
    "error norm), plus the off-chart penalty",
    "trial/reward": "the env's reward: minus the measured cost",
    "trial/left_chart": "1 if the trial left the chart of eqs. 4-5, else 0",
    "trial/within_tolerance": "1 if the trial's true errors meet the config's learning.tolerance, else 0",
    "trial/converged": "1 if the last hold trials (a cyclic task: cycles) were all within the tolerance, else 0",
}
"""Every tag a run may write, with its description (TensorBoard shows it beside the chart)."""


def require_tensorboard(option: str = "tensorboard") -> None:
    """``BadInput`` naming ``option`` and the extra to install when TensorBoard's writer cannot be
    imported: checked before any trial runs."""
    try:
        from tensorboard.summary import Writer  # noqa: F401
    except ImportError:
        raise BadInput(f"{option} needs the tensorboard extra, which is not installed: {EXTRA}") from None


def check_tensorboard(folder: Path | None, option: str = "--tensorboard") -> None:
    """A run's ``--tensorboard`` folder (``None``: not asked for) checked before any trial: the extra
    installed, the folder writable (created if needed); ``BadInput`` naming ``option`` otherwise."""
    if folder is not None:
        require_tensorboard(option)
        check_output_dir(folder, option)


def run_folder(root: str | os.PathLike[str], scenario: str, learner: str, seed: int, prior: str = "nominal") -> Path:
    """The folder of one run's event files under ``root`` (``--tensorboard DIR``), named so that a
    user finds it in TensorBoard's list of runs: ``<scenario>/<learner>_seed<seed>``, and
    ``_prior-<prior>`` after it for a comparison's condition other than ``nominal``. A user's
    ``module:attr`` learner is written as :func:`~ilc_steering.output.injective_name` writes it."""
    label = f"{injective_name(learner, METHODS)}_seed{seed}" + ("" if prior == "nominal" else f"_prior-{prior}")
    return Path(root) / scenario / label


class TrialBoard:
    """The event files of one run in ``folder`` (its own: event files left there by an earlier run
    are removed, so a rerun replaces its points): :meth:`write` adds one point per tag per trial.

    ``tolerance`` (a config's ``learning.tolerance``) adds ``trial/within_tolerance`` and
    ``trial/converged``: the last ``hold`` trials all within it, the rule of ``run``'s verdict.
    ``option`` names the folder in an error (``--tensorboard``)."""

    def __init__(
        self,
        folder: str | os.PathLike[str],
        tolerance: Tolerance | None = None,
        hold: int = HOLD,
        option: str = "tensorboard",
    ) -> None:
        if isinstance(hold, bool) or not isinstance(hold, int) or hold < 1:
            raise BadInput(f"hold must be a whole number of trials >= 1, got {hold!r}")
        require_tensorboard(option)
        from tensorboard.summary import Writer

        path = check_output_dir(Path(folder), option)
        for old in path.glob("events.out.tfevents.*"):
            if old.is_file():
                old.unlink()
        self.folder = path
        self._writer = Writer(str(path))
        self._tolerance = tolerance
        self._hold = hold
        self._streak = 0

    @classmethod
    def of_env(cls, folder: str | os.PathLike[str], env: gym.Env[Any, Any], hold: int = HOLD) -> TrialBoard:
        """The board of a run on ``env``: with the tolerance of its config where it is one of the
        library's envs (a cyclic env's ``hold`` cycles are ``hold`` times its segments' trials)."""
        owner = env.unwrapped
        if not isinstance(owner, SteeringEnv):
            return cls(folder, None, hold)
        config = owner.config
        segments = len(config.task.waypoints) if config.is_cyclic else 1  # type: ignore[union-attr]
        return cls(folder, config.learning.tolerance, hold * segments)

    def write(self, trial: int, info: Mapping[str, Any], reward: float) -> None:
        """Trial ``trial``'s (from 1) points: its errors, cost, reward and, with a tolerance, whether
        it met it and whether the run has held it."""
        points = {f"trial/{key}": float(info[key]) for key in ERRORS if key in info}
        if "true_error_norm" in info:
            points["trial/cost"] = float(true_cost(info))
        points["trial/reward"] = float(reward)
        points["trial/left_chart"] = float(bool(info["left_chart"]))
        if self._tolerance is not None:
            met = within_tolerance(self._tolerance, info)
            self._streak = self._streak + 1 if met else 0
            points["trial/within_tolerance"] = float(met)
            points["trial/converged"] = float(self._streak >= self._hold)
        for tag, value in points.items():
            self._writer.add_scalar(tag, value, trial, description=TAGS[tag])
        self._writer.flush()  # a run is watched as it goes: a trial may take minutes on a robot

    def close(self) -> None:
        """Flush and close the event file."""
        self._writer.close()
