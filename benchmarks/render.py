"""Milliseconds per ``env.render()`` frame (``rgb_array``): the numpy rasterizer against matplotlib.

In one run, for each case (an env and a packaged config), the env takes a few trials (the nominal
open-loop solution with every coefficient perturbed by 10%, seeded), so that its frame has paths
and the robot drawn along the last of them; then, in alternation on that same scene:

- ``env.render()``, drawn by :func:`ilc_steering.envs.frames.draw_scene` (the numpy rasterizer);
- the frame as the envs drew it before: matplotlib's Agg canvas, 480 x 480 px at 80 dpi, with the
  figures' own helpers (``draw_waypoints``, ``draw_trial``, ``setup_workspace``), the reference.

Times are medians over ``repeats`` of the wall time and, beside it, of the process's CPU time
(on a machine shared with other work, the wall time also counts the waits for a core); the
speed-up is the reference's median wall time over the raster's, timed in the same run. The ink
(the fraction of pixels that are not near white) of both frames is reported beside them, as a
check that both draw about as much.

    python benchmarks/render.py [--quick] [--out DIR]

writes ``render.json``, ``render.csv`` and ``render.md`` to ``DIR`` (committed in ``results/benchmarks``).
"""

from __future__ import annotations

import os
import platform
import sys
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import numpy.typing as npt

import ilc_steering  # noqa: F401  (registers the envs)
from ilc_steering.arguments import Parser
from ilc_steering.engine.provenance import record_made
from ilc_steering.envs.frames import HEIGHT, SNAPSHOTS, WIDTH, Scene
from ilc_steering.envs.rendering import draw_trial, draw_waypoints, setup_workspace
from ilc_steering.output import check_output_dir
from ilc_steering.tables import markdown_table, write_results

__all__ = ["CASES", "Args", "MatplotlibFrame", "main"]

STEERING, CYCLIC = "ilc_steering/ChainedSteering-v0", "ilc_steering/CyclicSteering-v0"
CASES: tuple[tuple[str, str], ...] = (
    (STEERING, "forward_parking"),
    (STEERING, "unicycle_parking"),
    (STEERING, "trailer_bay"),
    (STEERING, "chained_perturbed"),
    (CYCLIC, "cyclic_home_goal"),
)
"""(env id, config) of every row."""
TARGET_MS = 5.0
"""The raster's budget per frame [ms]."""


@dataclass(frozen=True)
class Args:
    quick: bool = False
    """The car and the cyclic env only, few repeats: checks that the script runs (CI)."""
    repeats: int = 30
    """Timing repeats of each frame; medians are reported."""
    trials: int = 3
    """Trials (segments, for the cyclic env) before the frames are timed."""
    seed: int = 0
    """Seed of the perturbed trials."""
    out: Path = Path("results/benchmarks")
    """Folder for the JSON, CSV and Markdown results."""


QUICK = {"repeats": 3}


class MatplotlibFrame:
    """The envs' frames as they were drawn before the raster: an off-screen matplotlib figure of
    ``WIDTH`` x ``HEIGHT`` pixels at 80 dpi, fixed margins, drawn with the figures' helpers."""

    def __init__(self) -> None:
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure

        dpi = 80
        self.figure = Figure(figsize=(WIDTH / dpi, HEIGHT / dpi), dpi=dpi)
        self.canvas: Any = FigureCanvasAgg(self.figure)  # matplotlib's canvas methods are untyped
        self.ax = self.figure.add_subplot()
        self.figure.subplots_adjust(left=0.15, right=0.96, bottom=0.11, top=0.9)

    def __call__(self, scene: Scene) -> npt.NDArray[np.uint8]:
        """The ``(HEIGHT, WIDTH, 3)`` uint8 frame of ``scene``."""
        ax = self.ax
        ax.clear()
        draw_waypoints(ax, scene.waypoints, scene.robot, scene.names)
        for i, q in enumerate(scene.paths):
            draw_trial(ax, q, scene.robot, snapshots=SNAPSHOTS if i == len(scene.paths) - 1 else 0)
        setup_workspace(ax, None if scene.robot.has_pose else scene.waypoints.shape[1], scene.title)
        self.canvas.draw()
        return np.array(self.canvas.buffer_rgba())[..., :3]


def wall_and_cpu(fn: Callable[[], Any]) -> tuple[float, float]:
    """The wall and CPU seconds of one call of ``fn``."""
    wall, cpu = time.perf_counter(), time.process_time()
    fn()
    return time.perf_counter() - wall, time.process_time() - cpu


def ink(frame: npt.NDArray[np.uint8]) -> float:
    """The fraction of pixels that are not near white (a channel below 240)."""
    return float(np.mean(np.any(frame < 240, axis=-1)))


def prepared_env(env_id: str, config: str, args: Args) -> Any:
    """The env after ``args.trials`` perturbed trials (segments), rendering ``rgb_array``."""
    env: Any = gym.make(env_id, config=config, render_mode="rgb_array")
    env.reset(seed=args.seed)
    models = getattr(env.unwrapped, "nominal_models", None) or [env.unwrapped.nominal_model]
    rng = np.random.default_rng(args.seed)
    for k in range(args.trials):
        c = models[k % len(models)].solve()
        env.step(c * (1.0 + 0.1 * rng.standard_normal(c.size)))
    return env


def measure(env_id: str, config: str, args: Args) -> dict[str, Any]:
    env = prepared_env(env_id, config, args)
    scene = env.unwrapped.scene()
    reference = MatplotlibFrame()
    raster, old = env.render(), reference(scene)  # matplotlib's first draw (fonts, caches) outside the timing
    if raster.shape != old.shape or raster.dtype != old.dtype:
        raise RuntimeError(f"{config}: frames differ in shape or type: {raster.shape} {old.shape}")
    new, old_times = [], []
    for _ in range(args.repeats):  # in alternation: a machine that slows down slows both alike
        new.append(wall_and_cpu(env.render))
        old_times.append(wall_and_cpu(lambda: reference(scene)))
    env.close()
    (new_ms, new_cpu_ms), (old_ms, old_cpu_ms) = (1e3 * np.median(np.array(t), axis=0) for t in (new, old_times))
    return {
        "env": env_id.split("/")[-1],
        "config": config,
        "paths": len(scene.paths),
        "raster_ms": float(new_ms),
        "raster_cpu_ms": float(new_cpu_ms),
        "raster_min_ms": 1e3 * min(wall for wall, _ in new),
        "matplotlib_ms": float(old_ms),
        "matplotlib_cpu_ms": float(old_cpu_ms),
        "speedup": float(old_ms / new_ms),
        "raster_ink": ink(raster),
        "matplotlib_ink": ink(old),
        "within_target": bool(new_ms <= TARGET_MS),
    }


def machine() -> dict[str, Any]:
    import matplotlib

    return {
        "platform": platform.platform(),
        "processor": platform.processor() or platform.machine(),
        "cpus": os.cpu_count(),
        "load_average": os.getloadavg(),
        "python": platform.python_version(),
        "numpy": np.__version__,
        "matplotlib": matplotlib.__version__,
    }


def report(rows: list[dict[str, Any]], args: Args, m: dict[str, Any]) -> str:
    table = [
        [
            r["env"],
            r["config"],
            str(r["paths"]),
            f"{r['raster_ms']:.2f}",
            f"{r['raster_cpu_ms']:.2f}",
            f"{r['raster_min_ms']:.2f}",
            f"{r['matplotlib_ms']:.1f}",
            f"{r['matplotlib_cpu_ms']:.1f}",
            f"{r['speedup']:.0f}x",
            f"{r['raster_ink']:.3f} / {r['matplotlib_ink']:.3f}",
        ]
        for r in rows
    ]
    header = [
        "env",
        "config",
        "paths drawn",
        "raster [ms / frame]",
        "raster, CPU [ms]",
        "raster, fastest [ms]",
        "matplotlib [ms / frame]",
        "matplotlib, CPU [ms]",
        "speed-up",
        "ink, raster / matplotlib",
    ]
    text = (
        f"`env.render()` (`rgb_array`, {WIDTH} x {HEIGHT} px) after {args.trials} perturbed trials: the numpy "
        f"rasterizer against the matplotlib Agg frame of the same scene, medians of {args.repeats} frames each, "
        f"timed in alternation in one run (budget: {TARGET_MS:g} ms per frame).\n\n"
    )
    text += markdown_table(header, table, [False, False, True, True, True, True, True, True, True, True])
    load = ", ".join(f"{v:.2f}" for v in m["load_average"])
    text += (
        f"\n{m['cpus']} CPUs ({m['processor']}), load average {load} at the end of the run, "
        f"Python {m['python']}, numpy {m['numpy']}, matplotlib {m['matplotlib']}.\n"
    )
    return text


def main(args: Args) -> list[dict[str, Any]]:
    if args.quick:
        args = Args(**{**asdict(args), **QUICK, "quick": True})
    out = check_output_dir(args.out, "--out")
    cases = [c for c in CASES if c[1] in ("forward_parking", "cyclic_home_goal")] if args.quick else list(CASES)
    rows = [measure(env_id, config, args) for env_id, config in cases]
    m = machine()
    text = report(rows, args, m)
    write_results(rows, out, "render", text, {"args": {k: str(v) for k, v in asdict(args).items()}, "machine": m})
    print(text)
    return rows


def parse(argv: list[str] | None = None) -> Args:
    parser = Parser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="the car and the cyclic env, few repeats (CI)")
    parser.add_argument("--repeats", type=int, default=Args.repeats, help="timing repeats; medians are reported")
    parser.add_argument("--out", type=Path, default=Args.out, help="folder for the results")
    ns = parser.parse_args(argv)
    return Args(quick=ns.quick, repeats=ns.repeats, out=ns.out)


if __name__ == "__main__":
    arguments = parse()
    main(arguments)
    record_made(arguments.out, __file__, sys.argv[1:])
