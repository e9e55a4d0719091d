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
from ilc_steering.envs.highway_plant import MAX_TURN, STEERING, inside_lot, nominal_map, parking_task

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


def choose_frame(
    start: Array, goal: Array, grid: float = FRAME_GRID, profiles: int = len(PROFILES)
) -> tuple[float, int, float]:
    """The task frame [rad] and the profile (an index of :data:`PROFILES`) for a task, and the
    steering angle [rad] its nominal path (:func:`nominal_path`) needs: for each profile in turn,
    the frame whose path needs the least steering while it stays :data:`CHART_SLACK` inside the
    chart and the car's outline :data:`PATH_MARGIN` inside the lot's walls; the first profile whose path keeps
    :data:`STEERING_SPARE` of the stop spare, else the one that steers least (``inf``: no frame
    keeps any path in). ``grid`` [rad] spaces the frames tried, ``profiles`` tries the first few only."""
    edge = pi / 2 - CHART_SLACK
    low, high = max(start[2], goal[2]) - edge, min(start[2], goal[2]) + edge
    best = (0.5 * (start[2] + goal[2]), 0, np.inf)
    with np.errstate(all="ignore"):  # a path that blows up is left out below
        for index, (pieces, v1_fixed) in enumerate(PROFILES[:profiles]):
            profile = _profile(pieces, v1_fixed)
            mine = (best[0], index, np.inf)
            for frame in np.arange(low, high + 1e-12, grid):
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
def _task(seed: int) -> tuple[Array, list[Array], list[tuple[float, int, float]]]:
    """parking-v0 ``seed``'s waypoints (start, the via points, goal; world) and each segment's frame,
    profile and steering, once per process: one segment in the frame :func:`choose_frame` finds
    when one chart serves the goal within :data:`STEERING_USE` of the stop, else the two segments
    :func:`~ilc_steering.envs.highway_segments.choose_via` finds (``ValueError`` naming the seed
    when it finds none)."""
    from ilc_steering.envs.highway_segments import choose_via

    start, goal = parking_task(seed, one_chart=False)
    one = None
    if abs(goal[2] - start[2]) <= MAX_TURN:
        one = choose_frame(start, goal)
        if one[2] <= STEERING_USE * STEERING:
            return start, [goal], [one]
    try:
        via, end, legs = choose_via(start, goal, choose_frame, STEERING_USE)
    except ValueError as error:
        turn = f"its goal's heading is {np.degrees(abs(goal[2] - start[2])):.0f}° from the start's"
        needs = turn if one is None else f"its one-chart path needs {np.degrees(one[2]):.0f}° of steering"
        raise ValueError(f"parking-v0 seed {seed}: {needs}, and {error}") from None
    return start, [via, end], legs


def _direction(a: Array, b: Array, frame: float, index: int) -> str:
    """``forward`` or ``reverse``: the sign of ``v1`` on the learned piece of the segment ``a -> b``
    in ``frame`` with profile ``index`` (eq. 12: ``z1`` is ``x`` in the task frame)."""
    pieces, v1_fixed = PROFILES[index]
    travel = rotate(b, frame)[0] - rotate(a, frame)[0] - sum(v * (d - RAMP) for v, d in zip(v1_fixed, pieces[1:]))
    return "forward" if travel > 0 else "reverse"


def highway_config(seed: int, name: str | None = None, trials: int = 15) -> dict[str, Any]:
    """The config (as a mapping for :func:`~ilc_steering.config.load_config`) of parking-v0 ``seed``'s
    task, to 1 cm / 0.01 rad: one segment in the frame :func:`choose_frame` finds, or a manoeuvre of
    two (``task.via``, ``task.segments``: each its frame, profile and direction) where one chart cannot
    serve the goal; ``ValueError`` naming the seed when neither can, and a ``ParameterError`` (a
    ``ValueError``) for a ``name`` its loader would refuse (it names files)."""
    if name is not None:
        check_name(name)
    start, ends, legs = _task(seed)
    learning = {"nu_a": 1.0, "nu_b": 1.0, "trials": trials, "tolerance": {"cartesian": 0.01, "orientation": 0.01}}
    config: dict[str, Any] = {
        "name": name or f"highway_parking_seed{seed}",
        "plant": {"model": "highway_parking", "seed": seed},
    }
    segments = []
    for a, b, (frame, index, _) in zip([start, *ends[:-1]], ends, legs):
        pieces, v1_fixed = PROFILES[index]
        segments.append(
            {
                "pieces": list(pieces),
                "v1_fixed": list(v1_fixed),
                "v2_terms": V2_TERMS,
                "v1_shape": "trapezoid",
                "ramp": RAMP,
                "frame": frame,
                "direction": _direction(a, b, frame, index),
            }
        )
    if len(ends) == 1:
        task = {"start": start.tolist(), "goal": ends[0].tolist(), **segments[0]}
        del task["direction"]
    else:
        task = {"start": start.tolist(), "via": [q.tolist() for q in ends[:-1]], "goal": ends[-1].tolist()}
        task["segments"] = segments
    return {**config, "task": task, "learning": learning}


_KEYS = (
    ("pieces", "Delta_i [s], whole 0.2 s action steps"),
    ("v1_fixed", "v1 on pieces 2..p [m/s]"),
    ("v2_terms", "q"),
    ("v1_shape", "the speed rises from rest and falls back to it"),
    ("ramp", "[s]"),
    ("frame", "[rad] the task frame with the least steering (choose_frame)"),
    ("direction", "the sign of v1: forward or reverse (checked against the nominal solution)"),
)


def _yaml(config: dict[str, Any]) -> str:
    task, learning = config["task"], config["learning"]
    seed = config["plant"]["seed"]
    lines = [
        f"# parking-v0 (highway-env) seed {seed}: its start and goal, read by",
        f"# python -m ilc_steering.envs.highway --seed {seed}",
        f"name: {json.dumps(config['name'])}",  # a JSON string is a YAML string, whatever it holds
        "plant:",
        '  model: highway_parking   # highway-env\'s car steps the trials (pip install "ilc-steering[highway]")',
        f"  seed: {seed}                  # parking-v0's reset seed: the start and goal below",
        "task:",
        f"  start: {task['start']!r}   # rear axle x [m], y [m], theta [rad], phi [rad]",
    ]
    if "via" in task:
        lines.append("  via:                      # the waypoints between, chosen by highway_segments.choose_via")
        lines += [f"    - {q!r}" for q in task["via"]]
    lines.append(f"  goal:  {task['goal']!r}    # parking-v0's spot, the rear axle L/2 behind its centre")
    if "segments" in task:
        lines.append("  segments:                 # one per segment: start -> via -> goal, each its chart")
        for segment in task["segments"]:
            rows = [f"{key}: {json.dumps(segment[key])}   # {note}" for key, note in _KEYS]
            lines += [f"    - {rows[0]}", *(f"      {row}" for row in rows[1:])]
    else:
        lines += [f"  {key}: {json.dumps(task[key])}   # {note}" for key, note in _KEYS if key in task]
    lines += [
        "learning:",
        f"  nu_a: {learning['nu_a']}                 # gain of eq. 33",
        f"  nu_b: {learning['nu_b']}                 # gain of eq. 34",
        f"  trials: {learning['trials']}",
        "  tolerance: {cartesian: 0.01, orientation: 0.01}   # [m], [rad], at every waypoint",
        "",
    ]
    return "\n".join(lines)


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
