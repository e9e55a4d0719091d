r"""parking-v0's tasks as the library's configs, for its car as an external plant
(:mod:`~ilc_steering.envs.highway_plant`).

**Tasks** (:func:`highway_config`): parking-v0's start and goal for a seed
(:func:`~ilc_steering.envs.highway_plant.parking_task`), as the library's configurations. A goal
one chart serves within :data:`~ilc_steering.envs.highway_paths.STEERING_USE` of the stop is one
segment in the frame and profile :func:`~ilc_steering.envs.highway_paths.choose_frame` picks from
its nominal path; any other goal (one facing more than
:data:`~ilc_steering.envs.highway_plant.MAX_TURN` away, or whose one-chart path steers too far or
leaves the lot) is a manoeuvre of two segments through the via point
:func:`~ilc_steering.envs.highway_segments.choose_via` finds, and is refused by name only when it
finds none. ``python -m ilc_steering.envs.highway --seed 7`` writes a config.
"""

from __future__ import annotations

import json
import sys
from functools import lru_cache
from typing import Any

import numpy as np
import numpy.typing as npt

from ilc_steering.arguments import Parser
from ilc_steering.config.steering import check_name
from ilc_steering.core.robots.car import rotate
from ilc_steering.envs.highway_paths import (
    PATH_MARGIN,
    PROFILES,
    RAMP,
    STEERING_USE,
    V2_TERMS,
    choose_frame,
    nominal_path,
    task_profile,
)
from ilc_steering.envs.highway_plant import MAX_TURN, STEERING, parking_task
from ilc_steering.envs.highway_segments import choose_via
from ilc_steering.errors import BadInput

__all__ = ["PATH_MARGIN", "PROFILES", "choose_frame", "highway_config", "main", "nominal_path", "task_profile"]

Array = npt.NDArray[np.float64]


@lru_cache(maxsize=64)
def _task(seed: int) -> tuple[Array, list[Array], list[tuple[float, int, float]]]:
    """parking-v0 ``seed``'s waypoints (start, the via points, goal; world) and each segment's frame,
    profile and steering, once per process: one segment in the frame :func:`choose_frame` finds
    when one chart serves the goal within :data:`STEERING_USE` of the stop, else the two segments
    :func:`~ilc_steering.envs.highway_segments.choose_via` finds (``ValueError`` naming the seed
    when it finds none)."""
    start, goal = parking_task(seed, one_chart=False)
    one = None
    if abs(goal[2] - start[2]) <= MAX_TURN:
        one = choose_frame(start, goal)
        if one[2] <= STEERING_USE * STEERING:
            return start, [goal], [one]
    try:
        via, end, legs = choose_via(start, goal)
    except ValueError as error:
        turn = f"its goal's heading is {np.degrees(abs(goal[2] - start[2])):.0f}° from the start's"
        needs = turn if one is None else f"its one-chart path needs {np.degrees(one[2]):.0f}° of steering"
        raise BadInput(f"parking-v0 seed {seed}: {needs}, and {error}") from None
    return start, [via, end], legs


def _direction(a: Array, b: Array, frame: float, index: int) -> str:
    """``forward`` or ``reverse``: the sign of ``v1`` on the learned piece of the segment ``a -> b``
    in ``frame`` with profile ``index`` (eq. 12: ``z1`` is ``x`` in the task frame)."""
    travel = rotate(b, frame)[0] - rotate(a, frame)[0] - task_profile(*PROFILES[index]).fixed_displacement
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
    ("direction", "of the learned (first) piece, the sign of c11; the fixed pieces keep theirs"),
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
    parser = Parser(
        prog="python -m ilc_steering.envs.highway", description="print the config of parking-v0's task for a seed"
    )
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
