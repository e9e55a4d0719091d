"""``ResidualAction``: RL actions in ``[-1, 1]`` as residuals around the nominal solution."""

from __future__ import annotations

import math
from numbers import Real
from typing import Any

import gymnasium as gym
import numpy as np
import numpy.typing as npt

from ilc_steering.boxes import RESIDUAL_SCALE, SearchBox, residual_box
from ilc_steering.envs.base import check_action
from ilc_steering.errors import BadInput

__all__ = ["MAX_SCALE", "ResidualAction"]

Array = npt.NDArray[np.float64]


MAX_SCALE = 100.0
"""The largest ``scale`` [units of ``action_scale()``]: ten times the env's own box, past which every
action is clipped by the env (``info["clipped"]``) and the box means nothing."""


class ResidualAction(SearchBox, gym.utils.RecordConstructorArgs):
    r"""Actions ``a`` in ``[-1, 1]^d`` for the coefficients ``c = c0 + s * a`` around the nominal solution.

    ``c0`` is the nominal model's open-loop solution ``model.solve()`` (clipped to the env's action
    box) and ``s = scale * model.action_scale()`` [physical units of ``c``]. With the default
    ``scale`` (:data:`~ilc_steering.boxes.RESIDUAL_SCALE`, 0.3) this is exactly the box the
    comparison's black-box and RL methods search under ``prior="nominal"``
    (:meth:`~ilc_steering.agents.base.LearnerContext.search_box`), so ``a = 0`` is the nominal
    solution, the first trial of every learner there, and the true solution of every packaged task
    lies within ``|a_i| < 0.7``. An RL policy whose output starts near 0 thus starts at the
    nominal solution, where ``RescaleAction`` would centre it at ``c = 0``, far from any solution.

    On the cyclic env (``ilc_steering/CyclicSteering-v0``) each segment has its own nominal model,
    so ``c0`` and ``s`` are those of the segment the next ``step`` drives: the wrapper follows the
    segment through ``info["segment"]`` of ``reset`` and ``step``. On the segmented env
    (``ilc_steering/SegmentedSteering-v0``), whose one step drives every segment, ``c0`` and ``s``
    are the segments' own, end to end (a segment's ``c11`` keeps the sign of its direction).

    Actions outside ``[-1, 1]`` are clipped to it; a wrong shape or a non-finite value raises
    ``ValueError``. ``c`` outside the env's own action box is clipped by the env
    (``info["clipped"]``); the default box, 10 times ``action_scale()``, leaves room for ``scale``
    up to 9.

    Parameters
    ----------
    env
        A ``ChainedSteering-v0``, ``CyclicSteering-v0`` or ``SegmentedSteering-v0`` env from
        ``gym.make`` or an instance of their classes, under wrappers that keep its physical action
        box (``ValueError`` otherwise).
    scale
        Half-width of the box per coefficient, in units of ``NominalModel.action_scale()``: a
        number in ``(0, MAX_SCALE]``. The default, :data:`~ilc_steering.boxes.RESIDUAL_SCALE`, is the
        comparison's box.

    Attributes
    ----------
    centre, half
        ``c0`` and ``s`` of the next step [physical units].
    centres, halves
        ``(segments, d)``: ``c0`` and ``s`` of every segment (one row for a one-trial env).

    Examples
    --------
    >>> import gymnasium as gym
    >>> import numpy as np
    >>> import ilc_steering
    >>> from ilc_steering.envs import ResidualAction
    >>> env = ResidualAction(gym.make("ilc_steering/ChainedSteering-v0", config="forward_parking"))
    >>> env.action_space
    Box(-1.0, 1.0, (4,), float32)
    >>> obs, info = env.reset(seed=0)
    >>> obs, reward, terminated, truncated, info = env.step(np.zeros(4, dtype=np.float32))
    >>> bool(np.array_equal(info["action"], env.unwrapped.nominal_model.solve()))
    True
    >>> round(info["true_cartesian_error"], 3)  # the nominal solution on the 10 % larger car
    0.1
    """

    def __init__(self, env: gym.Env[Any, Any], scale: float = RESIDUAL_SCALE) -> None:
        if not isinstance(env, gym.Env):
            raise BadInput(
                f"ResidualAction wraps one env from gym.make, got {type(env).__name__}; for make_vec, "
                "pass wrappers=[ResidualAction] with vectorization_mode='sync' or 'async'"
            )
        if (
            isinstance(scale, bool)
            or not isinstance(scale, Real)
            or not math.isfinite(scale)
            or not 0 < scale <= MAX_SCALE
        ):
            raise BadInput(f"scale must be a number in (0, {MAX_SCALE:g}] [units of action_scale()], got {scale!r:.80}")
        gym.utils.RecordConstructorArgs.__init__(self, scale=scale)  # the spec records the wrapper (check_env)
        unwrapped: Any = env.unwrapped
        models = getattr(unwrapped, "nominal_models", None) or [getattr(unwrapped, "nominal_model", None)]
        if models[0] is None:
            raise BadInput(
                "ResidualAction needs an ilc_steering env (ChainedSteering-v0, CyclicSteering-v0 or "
                f"SegmentedSteering-v0), got {type(unwrapped).__name__}, which has no nominal model"
            )
        if env.action_space != unwrapped.action_space:
            raise BadInput(
                f"ResidualAction must wrap the env's own action box {unwrapped.action_space}, got "
                f"{env.action_space}: put it below no other action wrapper"
            )
        views = getattr(unwrapped, "segment_views", None)
        if callable(views):  # one trial drives every segment: one box, the segments' boxes end to end
            parts = [residual_box(view.nominal_model, view.action_space) for view in views()]
            low, high = (np.asarray(bound, dtype=np.float64) for bound in (env.action_space.low, env.action_space.high))
            centre = np.clip(np.concatenate([centre for centre, _ in parts]), low, high)  # c11's sign kept
            boxes = [(centre, np.concatenate([half for _, half in parts]))]
        else:
            boxes = [residual_box(model, env.action_space) for model in models]
        ratio = float(scale) / RESIDUAL_SCALE  # 1.0 exactly by default: the comparison's box, bit for bit
        self.centres: Array = np.array([centre for centre, _ in boxes])
        self.halves: Array = np.array([half * ratio for _, half in boxes])
        self.scale = float(scale)
        if not (np.all(np.isfinite(self.halves)) and np.all(np.isfinite(self.centres))):
            raise BadInput(f"scale {scale:g}: the box's half-widths overflow; give a smaller scale")
        SearchBox.__init__(self, env, self.centres[0], self.halves[0])

    def action(self, action: Any) -> Array:
        """``c = c0 + s * clip(a, -1, 1)``; ``ValueError`` for a wrong shape or a non-finite ``a``."""
        size = self.centre.size
        return super().action(check_action(action, (size,), f"a in [-1, 1]^{size}"))

    def _at(self, segment: int) -> None:
        self.centre, self.half = self.centres[segment], self.halves[segment]

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[Any, dict[str, Any]]:
        observation, info = self.env.reset(seed=seed, options=options)
        self._at(int(info.get("segment", 0)))
        return observation, info

    def step(self, action: Any) -> tuple[Any, Any, bool, bool, dict[str, Any]]:
        observation, reward, terminated, truncated, info = self.env.step(self.action(action))
        self._at((int(info.get("segment", -1)) + 1) % len(self.centres))
        return observation, reward, terminated, truncated, info
