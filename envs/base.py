"""What every steering env shares: what it is handed, checked where it enters, and its frames.

:class:`SteeringEnv` is the base of the three envs a user makes one at a time
(``ChainedSteering-v0``, ``CyclicSteering-v0``, ``SegmentedSteering-v0``): :meth:`SteeringEnv.open`
loads the config of the kind the env steps (:func:`open_config`) and checks the render mode and
the trajectory flag; :meth:`SteeringEnv.render` draws the env's :meth:`~SteeringEnv.scene`. The
checks are functions, for the vector envs and the wrappers too: the config of a kind, a flag, the
render mode, an action (:func:`check_action`). Each is a one-line
:class:`~ilc_steering.errors.BadInput` naming what was handed and what to give instead.
"""

from __future__ import annotations

import reprlib
from pathlib import Path
from typing import Any, ClassVar, Literal

import gymnasium as gym
import numpy as np
import numpy.typing as npt

from ilc_steering.config import SteeringConfig, load_config
from ilc_steering.envs.frames import Scene, draw_scene
from ilc_steering.errors import BadInput

__all__ = ["Kind", "SteeringEnv", "check_action", "check_flag", "check_render_mode", "open_config"]

Array = npt.NDArray[np.float64]
Kind = Literal["one-trial", "cyclic", "segmented"]
"""What an env steps: one trial from start to goal, a cycle of waypoints, a manoeuvre of segments."""


def open_config(config: str | Path | SteeringConfig, kind: Kind, env: str) -> SteeringConfig:
    """``config`` loaded (:func:`~ilc_steering.config.load_config`), refused unless it is a task of
    ``kind``, the message naming ``env`` (the env that was asked) and the env to use instead."""
    loaded = load_config(config)
    name = loaded.name
    if kind == "one-trial" and loaded.is_cyclic:
        raise BadInput(f"{name}: a cyclic config (task.waypoints); use ilc_steering/CyclicSteering-v0 for it")
    if kind == "cyclic" and not loaded.is_cyclic:
        raise BadInput(f"{name}: {env} needs task.waypoints; use ChainedSteering-v0 for start/goal")
    if kind == "segmented" and not loaded.is_segmented:
        raise BadInput(
            f"{name}: {env} needs task.segments beside task.start; use ilc_steering/ChainedSteering-v0 for one segment"
        )
    return loaded


def check_action(action: Any, shape: tuple[int, ...], names: str, what: str = "action") -> Array:
    """``action`` as float64 of exactly ``shape``, or ``BadInput`` saying what is wrong: it must be
    real numbers (integers or floats; not complex, text, dates, booleans or a masked array),
    finite and within the float64 range."""
    if isinstance(action, np.ma.MaskedArray):
        raise BadInput(f"{what} must be a plain array of {names}, not a masked array")
    try:
        raw = np.asarray(action)
    except (TypeError, ValueError) as error:
        raise BadInput(f"{what} must be numeric {names}: {error}") from None
    if raw.dtype.kind == "O":
        try:
            raw = np.asarray(action, dtype=np.float64)
        except OverflowError:
            raise BadInput(f"{what} has a value beyond the float64 range") from None
        except (TypeError, ValueError):
            raise BadInput(f"{what} must be numeric {names}, got {reprlib.repr(action)}") from None
    if raw.dtype.kind not in "iuf":
        raise BadInput(f"{what} must be numeric {names} (real integers or floats), got dtype {raw.dtype}")
    c = np.asarray(raw, dtype=np.float64)
    if c.shape != shape:
        raise BadInput(f"{what} must have shape {shape} = {names}, got shape {c.shape}")
    finite = np.isfinite(c)
    if not np.all(finite):
        if c.ndim == 1:
            raise BadInput(f"{what} must be finite, got {c.tolist()}")
        rows = np.flatnonzero(~finite.all(axis=-1))
        raise BadInput(f"{what} must be finite; rows {rows[:10].tolist()} are not ({rows.size} in all)")
    return c


def check_flag(value: Any, name: str, none: bool = False) -> Any:
    """``value`` if it is ``True`` or ``False`` (or ``None``, with ``none``): a string such as ``"no"``
    would read as true."""
    if not (isinstance(value, (bool, np.bool_)) or (none and value is None)):
        allowed = "True, False or None" if none else "True or False"
        raise BadInput(f"{name} must be {allowed}, got {value!r:.80}")
    return None if value is None else bool(value)


def check_render_mode(render_mode: str | None, metadata: dict[str, Any]) -> str | None:
    """``render_mode`` if the env offers it (``metadata["render_modes"]``) or ``None``."""
    if render_mode is not None and render_mode not in metadata["render_modes"]:
        raise BadInput(f"render_mode must be one of {metadata['render_modes']} or None, got {render_mode!r}")
    return render_mode


class SteeringEnv(gym.Env[Any, Any]):
    """The base of the envs a user makes one at a time: its ``metadata``, its config opened by
    kind (:meth:`open`), and ``render()`` of the frame its subclass describes (:meth:`scene`)."""

    metadata: dict[str, Any] = {"render_modes": ["rgb_array"], "render_fps": 4}
    kind: ClassVar[Kind]
    """What the env steps."""

    config: SteeringConfig
    record_trajectory: bool

    def open(self, config: str | Path | SteeringConfig, render_mode: str | None, record_trajectory: bool) -> None:
        """Check the render mode and the trajectory flag, and load ``config``, of this env's kind."""
        self.render_mode = check_render_mode(render_mode, self.metadata)
        self.record_trajectory = check_flag(record_trajectory, "record_trajectory")
        self.config = open_config(config, self.kind, type(self).__name__)

    def render(self) -> npt.NDArray[np.uint8] | None:
        """An RGB frame ``(480, 480, 3)`` of :meth:`scene`; ``None`` (and a warning) without
        ``render_mode="rgb_array"``."""
        if self.render_mode is None:
            gym.logger.warn("render() needs render_mode='rgb_array' at construction; returning None")
            return None
        return draw_scene(self.scene())

    def scene(self) -> Scene:
        """What ``render()`` draws, as a :class:`~ilc_steering.envs.frames.Scene` (to draw it otherwise)."""
        raise NotImplementedError
