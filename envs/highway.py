r"""parking-v0's tasks as the library's configs, for its car as an external plant
(:mod:`~ilc_steering.envs.highway_plant`).

**Tasks** (:func:`parking_task`, :func:`highway_config`): parking-v0's start and goal for a seed,
as the library's configurations; the goal's heading is written the way nearer the start's, and
the task frame is the one :func:`~ilc_steering.core.robots.car.frame_angle` puts both in. A goal
whose heading differs from the start's by more than :data:`MAX_TURN` cannot be served by one
chart and is refused by name. ``python -m ilc_steering.envs.highway --seed 7`` writes a config.
"""

from __future__ import annotations

import argparse
import json
import sys
from functools import lru_cache
from math import pi
from typing import Any

import numpy as np
import numpy.typing as npt

from ilc_steering.config.steering import check_name
from ilc_steering.core.integrate import OK
from ilc_steering.core.profiles import InputProfile
from ilc_steering.core.robots.car import rotate
from ilc_steering.envs.highway_plant import STEERING, inside_lot, nominal_map, parking_task

__all__ = ["PROFILES", "choose_frame", "highway_config", "main", "nominal_path"]

Array = npt.NDArray[np.float64]

PROFILES: tuple[tuple[tuple[float, ...], tuple[float, ...]], ...] = (
    ((15.0,), ()),
    ((10.0, 10.0), (2.0,)),
    ((10.0, 15.0), (2.0,)),
    ((10.0, 10.0), (4.0,)),
    ((8.0, 8.0, 8.0), (-2.0, 2.0)),
)
"""The input profiles a task may take, as ``(pieces [s], v1_fixed [m/s])`` (whole 0.2 s action steps):
one stroke whose speed is learned, or that stroke followed by fixed ones (forward at 2 or 4 m/s, or
back and forth at 2 m/s); :func:`choose_frame` takes the one whose nominal path steers least."""
RAMP = 3.0
"""[s] the trapezoid's ramp: the speed rises from rest and falls back to it at both ends of each piece."""
V2_TERMS = 4
"""``q``: one spare coefficient of ``v2`` beyond ``n - 1 = 3``."""
FRAME_GRID = np.radians(1.0)
"""[rad] the spacing of the task frames :func:`choose_frame` tries."""
CHART_SLACK = np.radians(10.0)
"""[rad] how far inside the chart's edge (``|theta| = pi/2``, task frame) the nominal path must stay."""
STEERING_USE = 1.0
"""The largest fraction of the ±45° stop the nominal path may use."""
STEERING_SPARE = 0.1
"""The fraction of the stop a profile's path leaves spare for :func:`choose_frame` to take it before
the later (longer) profiles."""
PATH_MARGIN = 1.5
"""[m] how far inside the lot's walls the car's outline must stay along a task's nominal path: the
learned paths stray from it, and a trial whose outline comes within
:data:`~ilc_steering.envs.highway_plant.WALL_MARGIN` of a wall is a failed one."""


def _profile(pieces: tuple[float, ...], v1_fixed: tuple[float, ...]) -> Any:
    from ilc_steering.core.trapezoid import TrapezoidProfile

    return TrapezoidProfile(pieces, v1_fixed, V2_TERMS, RAMP)


def nominal_path(start: Array, goal: Array, frame: float, profile: InputProfile) -> Array:
    """The nominal car's path (world configurations ``(S, 4)``) of the nominal solution from ``start`` to
    ``goal`` with ``profile`` in the task frame rotated by ``frame`` [rad], without a steering stop."""
    from ilc_steering.core.nominal import NominalModel
    from ilc_steering.core.robots.car import CarPlant
    from ilc_steering.core.simulate import simulate

    model = nominal_map()
    q0, q1 = rotate(start, frame), rotate(goal, frame)
    nominal = NominalModel(4, profile, model.to_chained(q0), model.to_chained(q1), model, STEERING)
    trials = simulate(CarPlant(model, model), profile, q0[None], nominal.solve()[None], 1 / 32, record=True)
    if trials.states is None or trials.status[0] != OK:
        return np.full((1, 4), np.inf)
    return rotate(trials.states[0], -frame)


def choose_frame(start: Array, goal: Array) -> tuple[float, int, float]:
    """The task frame [rad] and the profile (an index of :data:`PROFILES`) for a task, and the
    steering angle [rad] its nominal path (:func:`nominal_path`) needs: for each profile in turn,
    the frame whose path needs the least steering while it stays :data:`CHART_SLACK` inside the
    chart and the car's outline :data:`PATH_MARGIN` inside the lot's walls; the first profile whose path keeps
    :data:`STEERING_SPARE` of the stop spare, else the one that steers least (``inf``: no frame
    keeps any path in)."""
    edge = pi / 2 - CHART_SLACK
    low, high = max(start[2], goal[2]) - edge, min(start[2], goal[2]) + edge
    best = (0.5 * (start[2] + goal[2]), 0, np.inf)
    with np.errstate(all="ignore"):  # a path that blows up is left out below
        for index, (pieces, v1_fixed) in enumerate(PROFILES):
            profile = _profile(pieces, v1_fixed)
            mine = (best[0], index, np.inf)
            for frame in np.arange(low, high + 1e-12, FRAME_GRID):
                path = nominal_path(start, goal, float(frame), profile)
                theta = path[:, 2] - frame
                inside = bool(np.all(np.abs(theta) < edge) and np.all(inside_lot(path, PATH_MARGIN)))
                steering = float(np.max(np.abs(path[:, 3])))
                if inside and steering < mine[2]:
                    mine = (float(frame), index, steering)
            if mine[2] <= (1 - STEERING_SPARE) * STEERING:
                return mine  # the simplest profile that steers well inside the stop
            if mine[2] < best[2]:
                best = mine
    return best


@lru_cache(maxsize=64)
def _task(seed: int) -> tuple[Array, Array, float, int, float]:
    """:func:`parking_task` and :func:`choose_frame` of ``seed``, once per process."""
    start, goal = parking_task(seed)
    return (start, goal, *choose_frame(start, goal))


def highway_config(seed: int, name: str | None = None, trials: int = 15) -> dict[str, Any]:
    """The config (as a mapping for :func:`~ilc_steering.config.load_config`) of parking-v0 ``seed``'s
    task, to 1 cm / 0.01 rad, in the frame :func:`choose_frame` finds; ``ValueError`` naming the seed
    when one chart cannot serve it (the turn, or a nominal path past :data:`STEERING_USE` of the stop),
    and a ``ParameterError`` (a ``ValueError``) for a ``name`` its loader would refuse (it names files)."""
    if name is not None:
        check_name(name)
    start, goal, frame, index, steering = _task(seed)
    pieces, v1_fixed = PROFILES[index]
    if steering > STEERING_USE * STEERING:
        needs = (
            "no frame keeps its path in the chart and the lot"
            if steering == np.inf
            else (f"its nominal path needs {np.degrees(steering):.0f}° of steering in the best frame")
        )
        raise ValueError(
            f"parking-v0 seed {seed}: this task cannot serve it in one chart: {needs} "
            f"(the car stops at 45°; it needs a waypoint)"
        )
    return {
        "name": name or f"highway_parking_seed{seed}",
        "plant": {"model": "highway_parking", "seed": seed},
        "task": {
            "start": start.tolist(),
            "goal": goal.tolist(),
            "pieces": list(pieces),
            "v1_fixed": list(v1_fixed),
            "v2_terms": V2_TERMS,
            "v1_shape": "trapezoid",
            "ramp": RAMP,
            "frame": frame,
        },
        "learning": {
            "nu_a": 1.0,
            "nu_b": 1.0,
            "trials": trials,
            "tolerance": {"cartesian": 0.01, "orientation": 0.01},
        },
    }


def _yaml(config: dict[str, Any]) -> str:
    task, learning = config["task"], config["learning"]
    return "\n".join(
        [
            f"# parking-v0 (highway-env) seed {config['plant']['seed']}: its start and goal, read by",
            f"# python -m ilc_steering.envs.highway --seed {config['plant']['seed']}",
            f"name: {json.dumps(config['name'])}",  # a JSON string is a YAML string, whatever it holds
            "plant:",
            '  model: highway_parking   # highway-env\'s car steps the trials (pip install "ilc-steering[highway]")',
            f"  seed: {config['plant']['seed']}                  # parking-v0's reset seed: the start and goal below",
            "task:",
            f"  start: {task['start']!r}   # rear axle x [m], y [m], theta [rad], phi [rad]",
            f"  goal:  {task['goal']!r}    # parking-v0's spot, the rear axle L/2 behind its centre",
            f"  pieces: {task['pieces']!r}          # Delta_i [s], whole 0.2 s action steps",
            f"  v1_fixed: {task['v1_fixed']!r}        # v1 on pieces 2..p [m/s]",
            f"  v2_terms: {task['v2_terms']}               # q",
            "  v1_shape: trapezoid       # the speed rises from rest and falls back to it",
            f"  ramp: {task['ramp']}                 # [s]",
            f"  frame: {task['frame']!r}   # [rad] the task frame with the least steering (choose_frame)",
            "learning:",
            f"  nu_a: {learning['nu_a']}                 # gain of eq. 33",
            f"  nu_b: {learning['nu_b']}                 # gain of eq. 34",
            f"  trials: {learning['trials']}",
            "  tolerance: {cartesian: 0.01, orientation: 0.01}   # [m], [rad]",
            "",
        ]
    )


def main(argv: list[str] | None = None) -> int:
    """``python -m ilc_steering.envs.highway --seed N [--name NAME]``: print parking-v0 seed N's config."""
    parser = argparse.ArgumentParser(description="print the config of parking-v0's task for a seed")
    parser.add_argument("--seed", type=int, required=True)
    parser.add_argument("--name", default=None)
    args = parser.parse_args(argv)
    try:
        print(_yaml(highway_config(args.seed, args.name)), end="")
    except ValueError as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
