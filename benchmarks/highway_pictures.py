"""highway-env's own rendering of the first and the last trial of a run on one parking-v0 goal.

Runs ``run --learner LEARNER`` on the packaged ``highway_parking`` task (parking-v0 seed 4), or with
``--seed N`` on the task the library generates for parking-v0 seed N (a manoeuvre of several
segments where one chart cannot serve it: seed 12's), then replays the logged actions of its first
and last trials (every segment's, back to back) in a fresh ``parking-v0`` with
``render_mode="rgb_array"`` and its trajectory display on, and saves the frame at the trial's end:

    python benchmarks/highway_pictures.py [--quick] [--seed N] [--learner robust_ilc] [--trials 8] [--out DIR]

writes ``highway_first_trial[_seedN].png`` and ``highway_last_trial[_seedN].png`` (committed in
``docs/highway``).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ilc_steering.arguments import Parser

__all__ = ["Args", "main"]


@dataclass(frozen=True)
class Args:
    quick: bool = False
    """Two trials: checks that the script runs (CI)."""
    learner: str = "robust_ilc"
    """``run --learner``."""
    trials: int = 8
    """Trials of the run."""
    out: Path = Path("docs/highway")
    """Where the pictures go."""
    seed: int | None = None
    """parking-v0's seed: the library's generated task for it (None: the packaged ``highway_parking``)."""


def frame(seed: int, actions: list[list[float]]) -> Any:
    """highway-env's frame at the end of ``actions`` replayed from parking-v0 ``seed``'s reset,
    the car's recent path drawn (``show_trajectories``)."""
    import gymnasium as gym
    import highway_env

    gym.register_envs(highway_env)
    config = {"show_trajectories": True, "offscreen_rendering": True}
    env = gym.make("parking-v0", render_mode="rgb_array", config=config)
    env.reset(seed=seed)
    for action in actions:
        env.step(np.array(action, dtype=np.float64))
    image = env.render()
    env.close()
    return image


def main(args: Args) -> list[Path]:
    # highway-env turns its viewer off under SDL's "dummy" driver (a black frame); "offscreen" draws
    if os.environ.get("SDL_VIDEODRIVER", "dummy") == "dummy":
        os.environ["SDL_VIDEODRIVER"] = "offscreen"
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ilc_steering.config import load_config
    from ilc_steering.envs.highway import highway_config
    from ilc_steering.runner import run_ilc

    trials = 2 if args.quick else args.trials
    task = "highway_parking" if args.seed is None else load_config(highway_config(args.seed, trials=trials))
    result = run_ilc(task, trials=trials, learner=args.learner)
    seed = result.config.plant.seed  # type: ignore[attr-defined]
    tag = "" if args.seed is None else f"_seed{args.seed}"
    args.out.mkdir(parents=True, exist_ok=True)
    written = []
    for name, record in (("first", result.trials[0]), ("last", result.trials[-1])):
        assert record.plant is not None
        path = args.out / f"highway_{name}_trial{tag}{'_quick' if args.quick else ''}.png"
        plt.imsave(path, frame(seed, record.plant["actions"]))
        print(f"wrote {path}: trial {record.trial}, {record.cartesian_error:.3g} m, {record.orientation_error:.3g} rad")
        written.append(path)
    return written


if __name__ == "__main__":
    parser = Parser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--learner", default=Args.learner)
    parser.add_argument("--trials", type=int, default=Args.trials)
    parser.add_argument("--out", type=Path, default=Args.out)
    parser.add_argument("--seed", type=int, default=None, help="parking-v0's seed (default: the packaged task's, 4)")
    cli = parser.parse_args()
    main(Args(cli.quick, cli.learner, cli.trials, cli.out, cli.seed))
