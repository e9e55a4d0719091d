r"""Manoeuvres of two segments for parking-v0's goals that one chart cannot serve.

A goal whose heading is too far from the start's (:data:`~ilc_steering.envs.highway_plant.MAX_TURN`),
or whose one-chart path would need more than the ±45° stop or leave the lot, is served by a
waypoint between: start -> via -> goal, each segment in its own chart (task frame) and direction of
travel (:mod:`~ilc_steering.envs.segmented_env`). :func:`choose_via` searches a small family of
waypoints a driver would take:

- *back up, then in*: the via point in the aisle, ``d`` metres back from the spot along its heading
  and ``l`` to the side, turned ``a`` from the spot's heading; the first segment, often a reverse,
  brings the car there, the last drives it in nose first (parking-v0's spots face the wall, and
  the goal's heading is the spot's);
- *a turn first* (a three-point turn for a car facing away from the spot): the same points, the via
  heading halfway round from the start's to the goal's;

and keeps the one whose two nominal paths (:func:`~ilc_steering.envs.highway_paths.choose_frame`, each
segment its frame and profile) steer least, each within the stop and with the car's outline
:data:`~ilc_steering.envs.highway_paths.PATH_MARGIN` inside the lot's walls. When none of this family serves,
a wider one (:data:`WIDE`: via points up to 10 m to the side, turned up to 60°) is searched. A coarse pass (frames every
:data:`COARSE_GRID`, the first profiles) ranks the candidates; the best :data:`REFINE` are then
chosen by :func:`~ilc_steering.envs.highway_paths.choose_frame` in full.
"""

from __future__ import annotations

from itertools import product
from math import pi

import numpy as np
import numpy.typing as npt

from ilc_steering.envs.highway_paths import STEERING_USE, choose_frame
from ilc_steering.envs.highway_plant import MAX_TURN, STEERING
from ilc_steering.errors import BadInput

__all__ = ["ANGLES", "BACK", "SIDE", "WIDE", "Leg", "choose_via", "via_candidates"]

Array = npt.NDArray[np.float64]
Leg = tuple[float, int, float]
"""A segment's ``(frame [rad], profile index, steering [rad])``, as
:func:`~ilc_steering.envs.highway_paths.choose_frame` gives."""

BACK = (6.0, 10.0, 14.0)
"""[m] how far back from the spot, into the aisle, the via points lie (parking-v0's spots face the
wall: the car drives in nose first)."""
SIDE = (-6.0, 0.0, 6.0)
"""[m] how far to the side of the spot's axis."""
ANGLES = tuple(np.radians([-45.0, 0.0, 45.0]))
"""[rad] the via heading's turn from the spot's (back up, then in) or from halfway round (a turn first).
A coarse family: 54-72 candidates a goal."""
WIDE = ((4.0, 8.0, 12.0, 16.0), (-10.0, -5.0, 0.0, 5.0, 10.0), tuple(np.radians([-60.0, -30.0, 0.0, 30.0, 60.0])))
"""``(back, side, angles)``: the wider family :func:`choose_via` searches when none of :data:`BACK`,
:data:`SIDE`, :data:`ANGLES` keeps both segments within the stop and the lot (parking-v0 seeds 24 and
30: turns of 151° and 175° near the lot's middle need a via point 10 m to the side). About 220
candidates: four times the cost, so it is searched second."""
COARSE_GRID = np.radians(6.0)
"""[rad] the frame spacing of the coarse pass."""
COARSE_PROFILES = 3
"""The coarse pass tries the first few profiles of :data:`~ilc_steering.envs.highway_paths.PROFILES` only."""
REFINE = 6
"""Candidates the coarse pass hands to the full search."""


def _near(theta: float, reference: float) -> float:
    """``theta`` written within ``pi`` of ``reference`` [rad]."""
    return float(theta + 2 * pi * np.round((reference - theta) / (2 * pi)))


def via_candidates(
    start: Array, goal: Array, family: tuple[tuple[float, ...], ...] = (BACK, SIDE, ANGLES)
) -> list[Array]:
    """The via points (world configurations, wheels straight) of ``family`` (``(back, side, angles)``)
    :func:`choose_via` tries, each heading written the way nearer the start's, and the goal's heading
    then the way nearer the via's; only those whose two turns are each within :data:`MAX_TURN`."""
    out = []
    gx, gy, gtheta = goal[0], goal[1], goal[2]
    halfway = [0.5 * (start[2] + _near(gtheta, start[2])), 0.5 * (start[2] + _near(gtheta, start[2])) + pi]
    for d, side, angle in product(*family):
        x = gx - d * np.cos(gtheta) - side * np.sin(gtheta)
        y = gy - d * np.sin(gtheta) + side * np.cos(gtheta)
        for heading in (gtheta + angle, *(h + angle for h in halfway)):
            theta = _near(heading, start[2])
            if abs(theta - start[2]) <= MAX_TURN and abs(_near(gtheta, theta) - theta) <= MAX_TURN:
                out.append(np.array([x, y, theta, 0.0]))
    return out


def choose_via(start: Array, goal: Array) -> tuple[Array, Array, list[Leg]]:
    """The via point (world), the goal (its heading the way nearer the via's) and each segment's
    frame, profile and steering for a two-segment manoeuvre, from the driver's family first, then
    :data:`WIDE`; ``ValueError`` when no candidate keeps both nominal paths within the stop and the lot."""
    for family in ((BACK, SIDE, ANGLES), WIDE):
        best = _best_via(start, goal, family)
        if best is not None and best[0] <= STEERING_USE * STEERING:
            return best[1], best[2], best[3]
    raise BadInput("no via point of the search keeps both segments within the ±45° stop and inside the lot")


def _best_via(
    start: Array, goal: Array, family: tuple[tuple[float, ...], ...]
) -> tuple[float, Array, Array, list[Leg]] | None:
    """The candidate of ``family`` whose two segments steer least: ``(steering, via, goal, legs)``."""
    scored: list[tuple[float, int, Array, Array]] = []
    for via in via_candidates(start, goal, family):
        end = goal.copy()
        end[2] = _near(goal[2], via[2])
        legs = [choose_frame(a, b, COARSE_GRID, COARSE_PROFILES) for a, b in ((start, via), (via, end))]
        worst = max(leg[2] for leg in legs)
        if np.isfinite(worst):
            scored.append((worst, len(scored), via, end))
    scored.sort(key=lambda row: (row[0], row[1]))
    best: tuple[float, Array, Array, list[Leg]] | None = None
    for _, _, via, end in scored[:REFINE]:
        legs = [choose_frame(start, via), choose_frame(via, end)]
        worst = max(leg[2] for leg in legs)
        if best is None or worst < best[0]:
            best = (worst, via, end, legs)
    return best
