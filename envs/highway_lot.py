"""parking-v0's lot: its walls, the car's outline, and whether the outline keeps inside
(:mod:`~ilc_steering.envs.highway_plant` checks every trial against it, before and after it is sent)."""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt

__all__ = ["LENGTH", "WALLS", "WALL_MARGIN", "WIDTH", "inside_lot", "outline"]

Array = npt.NDArray[np.float64]

LENGTH = 5.0
"""[m] highway-env's ``Vehicle.LENGTH``: the nominal wheelbase (``tests/test_highway.py`` checks it)."""
WIDTH = 2.0
"""[m] highway-env's ``Vehicle.WIDTH``: the car's outline is ``LENGTH`` x ``WIDTH`` about its centre."""
WALLS = (34.5, 20.5)
"""[m] the inner faces of parking-v0's walls (a 70 m x 42 m lot, walls 1 m thick, ``add_walls``):
``|x| <= 34.5``, ``|y| <= 20.5`` in the world frame."""
WALL_MARGIN = 0.5
"""[m] how far inside the walls the car's outline must stay in every trial: one action step at 2.5 m/s."""


def outline(q: Array) -> Array:
    """The corners ``(..., 4, 2)`` [m] of the car's ``LENGTH`` x ``WIDTH`` outline at world
    configurations ``q`` ``(..., 4)`` (rear axle, heading): highway-env's centre is ``L/2`` ahead."""
    q = np.asarray(q, dtype=np.float64)
    c, s = np.cos(q[..., 2])[..., None], np.sin(q[..., 2])[..., None]
    along = np.array([0.0, LENGTH, LENGTH, 0.0])  # from the rear axle, the car's centre L/2 ahead of it
    across = 0.5 * WIDTH * np.array([-1.0, -1.0, 1.0, 1.0])
    x = q[..., 0:1] + c * along - s * across
    y = q[..., 1:2] + s * along + c * across
    return np.stack([x, y], axis=-1)


def inside_lot(q: Array, margin: float = WALL_MARGIN) -> Any:
    """Whether the car's outline at world configurations ``q`` ``(..., 4)`` is ``margin`` [m]
    inside the lot's walls (:data:`WALLS`), for each configuration."""
    corners = np.abs(outline(q))
    return np.all((corners[..., 0] <= WALLS[0] - margin) & (corners[..., 1] <= WALLS[1] - margin), axis=-1)
