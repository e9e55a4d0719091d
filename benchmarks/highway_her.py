"""HER on its home turf: SB3's SAC + ``HerReplayBuffer`` trained in highway-env's ``parking-v0``, its learning curve.

As highway-env intends: closed loop, its own reward, its own episodes (ended by its success test,
a crash or 100 steps, RL Zoo's ``max_episode_length``), at the settings of SB3's own HER example
for parking-v0 (SAC, ``MultiInputPolicy``, nets [256, 256, 256], batch 256, buffer 1e6, learning
rate 1e-3, gamma 0.95, HER ``future`` with 4 sampled goals; the example trains 2e5 steps). Every
``--every`` environment steps each training seed's deterministic policy is run on parking-v0's
resets for the goal seeds 0-19 (the goals ILC's benchmark serves) and scored at parking-v0's own
success test, at 10 cm / 0.05 rad and at 1 cm / 0.01 rad (the rear axle's position and the
heading, as ILC is scored), at the episode's last step: success against environment steps spent.

    python benchmarks/highway_her.py [--quick] [--seeds 0,1,2] [--steps 60000] [--every 5000] [--out DIR]
    python benchmarks/highway_her.py --zoo-cost 300     # CPU per step of RL Zoo's TQC setting, measured

**Resumable, and a resume is the same computation.** Each chunk of ``--every`` steps starts from
the last checkpoint on disk (the model, its optimizers and the replay buffer, under ``--models``,
in a folder named by the fingerprint below, its step count checked),
its random generators seeded from (seed, chunk), and its incomplete last episode cut
(``truncate_last_trajectory``), in one process or after a restart alike; a chunk's point of the
curve is written (``OUT/her_curve/seed{S}_{steps}.json``) with its settings' fingerprint, and a
folder holding points of other settings is refused. The table ``highway_her.{csv,json,md}`` and
``highway_her.png`` are rewritten from the points after each chunk.
"""

from __future__ import annotations

import hashlib
import json
import os
import sys
import time
import warnings
from dataclasses import asdict, dataclass
from pathlib import Path
from statistics import median
from typing import Any

import gymnasium as gym
import numpy as np

from ilc_steering.arguments import Parser
from ilc_steering.engine.provenance import record_made
from ilc_steering.output import write_atomic
from ilc_steering.tables import markdown_table, write_results

__all__ = ["SETTINGS", "Args", "evaluate", "main"]

TESTS = {"10cm": (0.10, 0.05), "1cm": (0.01, 0.01)}
"""[m], [rad]: the tests besides parking-v0's own."""
EPISODE = 100
"""Steps per episode (RL Zoo's ``max_episode_length`` for parking-v0)."""
SETTINGS: dict[str, Any] = {
    "algorithm": "SAC",
    "buffer_size": 1_000_000,
    "batch_size": 256,
    "learning_rate": 1e-3,
    "gamma": 0.95,
    "net_arch": [256, 256, 256],
    "n_sampled_goal": 4,
    "goal_selection_strategy": "future",
}
"""SB3's HER example for highway-env's parking (its documentation's ``HerReplayBuffer`` page)."""
QUICK: dict[str, Any] = {**SETTINGS, "buffer_size": 10_000, "batch_size": 64, "net_arch": [64, 64]}
ZOO: dict[str, Any] = {
    "algorithm": "TQC",
    "buffer_size": 1_000_000,
    "batch_size": 1024,
    "learning_rate": 1e-3,
    "gamma": 0.95,
    "tau": 0.05,
    "net_arch": [512, 512, 512],
    "n_critics": 2,
    "n_sampled_goal": 4,
    "goal_selection_strategy": "future",
}
"""RL Zoo's parking-v0 setting (``hyperparams/tqc.yml``), whose cost ``--zoo-cost`` measures."""


@dataclass(frozen=True)
class Args:
    quick: bool = False
    """One seed, two chunks of 150 steps (at most ``steps``), a small network, two goals: that the
    script runs (CI, < 1 min)."""
    seeds: tuple[int, ...] = (0, 1, 2)
    """Training seeds."""
    steps: int = 60_000
    """Environment steps of training per seed."""
    every: int = 5_000
    """Steps between two points of the curve (a chunk: checkpointed, resumable)."""
    goals: tuple[int, ...] = tuple(range(20))
    """parking-v0's reset seeds evaluated: the goals."""
    out: Path = Path("results/highway")
    """Where the curve's points and tables go."""
    models: Path = Path("results/highway_her")
    """Where the checkpoints go (not committed: hundreds of MB)."""
    zoo_cost: int = 0
    """If > 0: measure RL Zoo's TQC setting's CPU seconds per step over this many steps, and stop."""


def _env() -> gym.Env[Any, Any]:
    import highway_env

    gym.register_envs(highway_env)
    return gym.wrappers.TimeLimit(gym.make("parking-v0"), max_episode_steps=EPISODE)


def _algorithm(settings: dict[str, Any]) -> Any:
    if settings["algorithm"] == "TQC":
        from sb3_contrib import TQC

        return TQC
    from stable_baselines3 import SAC

    return SAC


def _model(env: gym.Env[Any, Any], settings: dict[str, Any], seed: int) -> Any:
    from stable_baselines3 import HerReplayBuffer

    algorithm = _algorithm(settings)
    extra = {"tau": settings["tau"]} if "tau" in settings else {}
    policy: dict[str, Any] = {"net_arch": settings["net_arch"]}
    if "n_critics" in settings:
        policy["n_critics"] = settings["n_critics"]
    return algorithm(
        "MultiInputPolicy",
        env,
        buffer_size=settings["buffer_size"],
        batch_size=settings["batch_size"],
        learning_rate=settings["learning_rate"],
        gamma=settings["gamma"],
        replay_buffer_class=HerReplayBuffer,
        replay_buffer_kwargs={
            "n_sampled_goal": settings["n_sampled_goal"],
            "goal_selection_strategy": settings["goal_selection_strategy"],
        },
        policy_kwargs=policy,
        seed=seed,
        device="cpu",
        verbose=0,
        **extra,
    )


def _rear_axle(vehicle_position: Any, heading: float) -> np.ndarray:
    from ilc_steering.envs.highway_plant import LENGTH

    return np.asarray(vehicle_position, dtype=np.float64) - 0.5 * LENGTH * np.array([np.cos(heading), np.sin(heading)])


def evaluate(model: Any, goals: tuple[int, ...]) -> list[dict[str, Any]]:
    """The deterministic policy's last step on each goal seed: parking-v0's success, the errors and the tests."""
    env = _env()
    rows = []
    for goal in goals:
        obs, _ = env.reset(seed=goal)
        success, steps, done = False, 0, False
        while not done:
            action, _ = model.predict(obs, deterministic=True)
            obs, _, terminated, truncated, info = env.step(action)
            success, steps, done = bool(info["is_success"]), steps + 1, terminated or truncated
        vehicle = env.unwrapped.vehicle  # type: ignore[attr-defined]
        target = vehicle.goal
        error = float(
            np.linalg.norm(_rear_axle(vehicle.position, vehicle.heading) - _rear_axle(target.position, target.heading))
        )
        turn = float(abs(np.angle(np.exp(1j * (vehicle.heading - target.heading)))))
        row = {"goal": goal, "success": success, "cartesian_error": error, "orientation_error": turn, "steps": steps}
        row.update({name: error <= cm and turn <= rad for name, (cm, rad) in TESTS.items()})
        row["crashed"] = bool(vehicle.crashed)
        rows.append(row)
    env.close()
    return rows


def fingerprint(settings: dict[str, Any], every: int, goals: tuple[int, ...]) -> str:
    """What makes two points the same computation: the settings, the chunk, the goals and the versions."""
    import highway_env
    import stable_baselines3
    import torch

    versions = {
        "stable_baselines3": stable_baselines3.__version__,
        "torch": torch.__version__,
        "highway_env": getattr(highway_env, "__version__", "?"),
        "gymnasium": gym.__version__,
        "numpy": np.__version__,
    }
    data = json.dumps({"settings": settings, "every": every, "goals": list(goals), **versions}, sort_keys=True)
    return hashlib.sha256(data.encode()).hexdigest()[:16]


def _chunk(seed: int, chunk: int, args: Args, settings: dict[str, Any], mark: str) -> dict[str, Any]:
    """Train seed ``seed``'s chunk ``chunk`` (from 1) from its last checkpoint; save, evaluate."""
    from stable_baselines3.common.utils import set_random_seed

    env = _env()
    stem = args.models / mark / f"seed{seed}"  # a checkpoint of these settings and versions only
    chunk_seed = seed * 100_003 + chunk
    set_random_seed(chunk_seed)
    if chunk == 1:
        model = _model(env, settings, seed)
    else:
        model = _algorithm(settings).load(stem.with_suffix(".zip"), env=env, device="cpu")
        with warnings.catch_warnings():  # "the last trajectory will be truncated": the chunk before ended mid-episode
            warnings.simplefilter("ignore")
            model.load_replay_buffer(stem.with_suffix(".buffer.pkl"), truncate_last_traj=True)
    if model.num_timesteps != (chunk - 1) * args.every:
        _refuse(
            f"{stem}.zip holds {model.num_timesteps} steps, not the {(chunk - 1) * args.every} its curve's last "
            "point was made after: it is another run's checkpoint"
        )
    model.set_random_seed(chunk_seed)
    start = time.process_time()
    model.learn(total_timesteps=args.every, reset_num_timesteps=False)
    cpu = time.process_time() - start
    stem.parent.mkdir(parents=True, exist_ok=True)
    model.save(stem.with_suffix(".zip"))
    model.save_replay_buffer(stem.with_suffix(".buffer.pkl"))
    rows = evaluate(model, args.goals)
    env.close()
    return {"seed": seed, "steps": chunk * args.every, "cpu_seconds": cpu, "goals": rows}


def _refuse(problem: str) -> None:
    print(f"highway_her.py: error: {problem} (see highway_her.py --help)", file=sys.stderr)
    raise SystemExit(2)


def _points(curve: Path, mark: str) -> list[dict[str, Any]]:
    points = [json.loads(p.read_text()) for p in sorted(curve.glob("seed*.json"))]
    other = [p for p in points if p.get("fingerprint") != mark]
    if other:
        _refuse(
            f"{curve} holds points of other settings or versions "
            f"(fingerprint {other[0].get('fingerprint')} != {mark}): give another --out"
        )
    return sorted(points, key=lambda p: (p["seed"], p["steps"]))


def _write(points: list[dict[str, Any]], args: Args, name: str, settings: dict[str, Any]) -> str:
    rows = [
        {
            "seed": p["seed"],
            "steps": p["steps"],
            "cpu_seconds_per_1000_steps": 1000 * p["cpu_seconds"] / args.every,
            **{("episode_steps" if key == "steps" else key): value for key, value in g.items()},
        }
        for p in points
        for g in p["goals"]
    ]
    by_steps: dict[int, list[dict[str, Any]]] = {}
    for p in points:
        by_steps.setdefault(p["steps"], []).append(p)
    n = len(args.goals)
    lines = []
    for steps, group in sorted(by_steps.items()):
        count = {key: [sum(g[key] for g in p["goals"]) for p in group] for key in ("success", "10cm", "1cm", "crashed")}
        lines.append(
            [
                f"{steps:,}",
                str(len(group)),
                *[" ".join(f"{c}/{n}" for c in count[key]) for key in ("success", "10cm", "1cm", "crashed")],
                f"{median(1000 * p['cpu_seconds'] / args.every for p in group):.0f}",
            ]
        )
    header = ["env steps", "seeds", "parking-v0 success", "10 cm / 0.05 rad", "1 cm / 0.01 rad", "crashes"]
    table = markdown_table([*header, "CPU s per 1000 steps"], lines, [True] * 7)
    markdown = (
        f"# SAC + HER in parking-v0 ({'--quick: ' if args.quick else ''}SB3's HER example for parking), "
        f"evaluated on goal seeds {list(args.goals)}\n\n{table}\n"
        "Each cell: one count per training seed, in seed order (goals of the deterministic policy at "
        "the episode's last step). `python benchmarks/highway_her.py`.\n"
    )
    write_results(rows, args.out, name, markdown, {"quick": args.quick, "settings": settings, "every": args.every})
    _figure(by_steps, n, args.out / f"{name}.png")
    return table


def _figure(by_steps: dict[int, list[dict[str, Any]]], n: int, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 3.5))
    steps = sorted(by_steps)
    for key, label in (("success", "parking-v0's success"), ("10cm", "10 cm / 0.05 rad"), ("1cm", "1 cm / 0.01 rad")):
        shares = [[sum(g[key] for g in p["goals"]) / n for p in by_steps[s]] for s in steps]
        ax.plot(steps, [median(s) for s in shares], marker="o", label=label)
    ax.set_xlabel("environment steps per seed")
    ax.set_ylabel(f"share of the {n} goals (median over seeds)")
    ax.set_ylim(-0.02, 1.02)
    ax.legend(loc="upper left")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def zoo_cost(steps: int, out: Path) -> float:
    """CPU seconds per environment step of RL Zoo's TQC setting, over ``steps`` steps after its first 100."""
    env = _env()
    model = _model(env, {**ZOO, "buffer_size": 10_000}, 0)  # the buffer's size does not change a step's cost
    model.learning_starts = 100
    model.learn(total_timesteps=100)
    start = time.process_time()
    model.learn(total_timesteps=steps, reset_num_timesteps=False)
    per_step = (time.process_time() - start) / steps
    text = (
        f"RL Zoo's parking-v0 setting ({json.dumps(ZOO)}): {per_step:.3f} CPU s per environment step "
        f"over {steps} steps after the first 100 (`python benchmarks/highway_her.py --zoo-cost {steps}`, "
        "one torch thread)\n"
    )
    out.mkdir(parents=True, exist_ok=True)
    write_atomic(out / "highway_her_zoo_cost.txt", text)
    print(text, end="")
    return per_step


def main(args: Args) -> list[dict[str, Any]]:
    os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
    import torch

    torch.set_num_threads(1)  # the machine is shared; more threads than cores cost 100x here (measured)
    if args.zoo_cost:
        zoo_cost(args.zoo_cost, args.out)
        return []
    settings = QUICK if args.quick else SETTINGS
    if args.quick:
        args = Args(True, (0,), min(args.steps, 300), 150, (4, 13), args.out, args.models / "quick")
    if args.every < 1 or args.steps < args.every or args.steps % args.every:
        _refuse(f"--steps {args.steps} is not a positive multiple of --every {args.every}")
    name = "highway_her" + ("_quick" if args.quick else "")
    curve = args.out / (name + "_curve")
    curve.mkdir(parents=True, exist_ok=True)
    mark = fingerprint(settings, args.every, args.goals)
    points = _points(curve, mark)
    done = {(p["seed"], p["steps"]) for p in points}
    for seed in args.seeds:
        for chunk in range(1, args.steps // args.every + 1):
            if (seed, chunk * args.every) in done:
                continue
            if chunk > 1 and not (args.models / mark / f"seed{seed}.zip").is_file():
                _refuse(
                    f"seed {seed}'s checkpoint after {(chunk - 1) * args.every} steps is missing under "
                    f"{args.models / mark}: its curve cannot be continued as the same computation"
                )
            point = {**_chunk(seed, chunk, args, settings, mark), "fingerprint": mark}
            write_atomic(curve / f"seed{seed}_{chunk * args.every:07d}.json", json.dumps(point))
            points = _points(curve, mark)
            print(_write(points, args, name, settings), flush=True)
    table = _write(_points(curve, mark), args, name, settings)
    print(table)
    return [asdict(args)]


if __name__ == "__main__":
    parser = Parser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--seeds", default=",".join(map(str, Args.seeds)))
    parser.add_argument("--steps", type=int, default=Args.steps)
    parser.add_argument("--every", type=int, default=Args.every)
    parser.add_argument("--out", type=Path, default=Args.out)
    parser.add_argument("--models", type=Path, default=Args.models)
    parser.add_argument("--zoo-cost", type=int, default=0, metavar="STEPS")
    cli = parser.parse_args()
    try:
        seeds = tuple(int(s) for s in cli.seeds.split(","))
    except ValueError:
        parser.error(f"--seeds must be whole numbers separated by commas, got {cli.seeds!r}")
    main(Args(cli.quick, seeds, cli.steps, cli.every, Args.goals, cli.out, cli.models, cli.zoo_cost))
    record_made(cli.out, __file__, sys.argv[1:])
    sys.exit(0)
