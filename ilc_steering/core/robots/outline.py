"""The drawing's primitives, in metres, for configurations one at a time or in batches ``(..., 2)``:
a box, a heading and its normal, a segment, and the car of Fig. 1 (which the car, the trailer and
the unicycle draw with).
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

__all__ = [
    "BODY_FRONT",
    "BODY_HALF_WIDTH",
    "BODY_REAR",
    "WHEEL_HALF_LENGTH",
    "box",
    "car_outline",
    "direction",
    "segment",
]

Array = npt.NDArray[np.float64]

# Proportions of the drawn car, in wheelbases (the paper's car: 0.2 m between the axles).
BODY_REAR, BODY_FRONT, BODY_HALF_WIDTH, WHEEL_HALF_LENGTH = -0.3, 1.3, 0.35, 0.2


def box(origin: Array, heading: Array, normal: Array, size: float, back: float, ahead: float) -> Array:
    """The closed rectangle ``(..., 5, 2)`` [m] from ``back`` to ``ahead`` along ``heading`` and
    ``BODY_HALF_WIDTH`` to each side, in units of ``size`` [m] from ``origin`` (each ``(..., 2)``)."""
    along = np.array([back, ahead, ahead, back, back])[:, None]
    side = (np.array([-1.0, -1.0, 1.0, 1.0, -1.0]) * BODY_HALF_WIDTH)[:, None]
    return origin[..., None, :] + size * (along * heading[..., None, :] + side * normal[..., None, :])


def direction(angle: Array) -> tuple[Array, Array]:
    """The unit vector ``(..., 2)`` at ``angle`` [rad] and the one a quarter turn left of it."""
    heading = np.stack([np.cos(angle), np.sin(angle)], axis=-1)
    return heading, np.stack([-heading[..., 1], heading[..., 0]], axis=-1)


def segment(middle: Array, half: Array) -> Array:
    """The segment ``(..., 2, 2)`` from ``middle - half`` to ``middle + half``."""
    return np.stack([middle - half, middle + half], axis=-2)


def car_outline(q: Array, wheelbase: float) -> tuple[Array, Array, Array]:
    """The body polygon ``(..., 5, 2)``, rear wheel ``(..., 2, 2)`` and front wheel ``(..., 2, 2)`` [m]
    of a car at ``q = (x, y, theta, phi)`` (or configurations ``(..., 4)``) with the given
    ``wheelbase`` [m]."""
    q = np.asarray(q, dtype=np.float64)
    theta, phi = q[..., 2], q[..., 3]
    heading, normal = direction(theta)
    rear = q[..., :2]
    body = box(rear, heading, normal, wheelbase, BODY_REAR, BODY_FRONT)
    half = WHEEL_HALF_LENGTH * wheelbase
    front = rear + wheelbase * heading
    steered, _ = direction(theta + phi)
    return body, segment(rear, half * heading), segment(front, half * steered)
