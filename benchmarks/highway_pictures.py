"""highway-env's own rendering of the first and the last trial of a run on one parking-v0 goal.

Runs ``run --learner LEARNER`` on the packaged ``highway_parking`` task (parking-v0 seed 4), or with
``--seed N`` on the task the library generates for parking-v0 seed N (a manoeuvre of several
segments where one chart cannot serve it: seed 12's), then replays the logged actions of its first
and last trials (every segment's, back to back) in a fresh ``parking-v0`` with
``render_mode="rgb_array"``, its window fixed on the whole lot, and saves the frame at the trial's end
with the car's path over the trial drawn on it (white; the dot is the start):

    python benchmarks/highway_pictures.py [--quick] [--seed N] [--learner robust_ilc] [--trials 8] [--out DIR]

writes ``highway_first_trial[_seedN].png`` and ``highway_last_trial[_seedN].png`` (committed in
``results/highway``).
"""

from __future__ import annotations

import os
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ilc_steering.arguments import Parser
from ilc_steering.engine.provenance import record_made

__all__ = ["Args", "main"]


@dataclass(frozen=True)
class Args:
    quick: bool = False
    """Two trials: checks that the script runs (CI)."""
    learner: str = "robust_ilc"
    """``run --learner``."""
    trials: int = 8
    """Trials of the run."""
    out: Path = Path("results/highway")
    """Where the pictures go."""
    seed: int | None = None
    """parking-v0's seed: the library's generated task for it (None: the packaged ``highway_parking``)."""


VIEW = {"screen_width": 800, "screen_height": 450, "scaling": 10.5}
"""A window that holds the whole lot (69 m by 41 m, :data:`ilc_steering.envs.highway_lot.WALLS`)."""


def frame(seed: int, actions: list[list[float]]) -> tuple[Any, Any]:
    """highway-env's frame at the end of ``actions`` replayed from parking-v0 ``seed``'s reset, its
    window fixed on the lot's centre, and the car's path over the whole trial in that frame's pixels
    (every step's position, highway-env's own ``WorldSurface.pos2pix``)."""
    from types import SimpleNamespace

    import gymnasium as gym
    import highway_env

    gym.register_envs(highway_env)
    env = gym.make("parking-v0", render_mode="rgb_array", config={"offscreen_rendering": True, **VIEW})
    env.reset(seed=seed)
    parking: Any = env.unwrapped  # highway-env's ParkingEnv: its car and its viewer
    path = [parking.vehicle.position.copy()]
    for action in actions:
        env.step(np.array(action, dtype=np.float64))
        path.append(parking.vehicle.position.copy())
    env.render()  # makes the viewer, then fix its window (it follows the car otherwise)
    viewer = parking.viewer
    viewer.observer_vehicle = SimpleNamespace(position=np.zeros(2))
    image = env.render()
    pixels = np.array([viewer.sim_surface.pos2pix(x, y) for x, y in path], dtype=np.float64)
    env.close()
    return image, pixels


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
        image, pixels = frame(seed, record.plant["actions"])
        figure = plt.figure(figsize=(image.shape[1] / 100, image.shape[0] / 100), dpi=100)
        axes = figure.add_axes((0.0, 0.0, 1.0, 1.0))
        axes.imshow(image)
        axes.plot(pixels[:, 0], pixels[:, 1], color="white", linewidth=1.2)
        axes.plot(*pixels[0], "o", color="white", markersize=4)
        axes.set_axis_off()
        figure.savefig(path, dpi=100)
        plt.close(figure)
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
    record_made(cli.out, __file__, sys.argv[1:])
