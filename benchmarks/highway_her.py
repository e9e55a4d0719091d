"""HER on its home turf: SB3's TQC + HerReplayBuffer trained in highway-env's ``parking-v0``.

As highway-env intends: closed loop, its own reward, its own episodes (ended by its success test,
a crash or 100 steps, RL Zoo's ``max_episode_length``), with RL Zoo's parking-v0 hyperparameters
(``hyperparams/tqc.yml``: TQC, ``MultiInputPolicy``, buffer 1e6, batch 1024, gamma 0.95, learning
rate 1e-3, tau 0.05, HER ``future`` with 4 sampled goals, ``net_arch=[512, 512, 512]``,
2 critics, 1e5 steps). Each training seed's policy is then run deterministically on parking-v0's
resets for the goal seeds 0-19 (the goals ILC's benchmark uses) and scored at parking-v0's own
success test, at 10 cm / 0.05 rad and at 1 cm / 0.01 rad (the rear axle's position and the
heading, as ILC is scored), at the episode's last step. The environment steps it spent are its
training steps.

    python benchmarks/highway_her.py [--quick] [--seeds 0,1,2] [--timesteps 100000] [--out DIR]

Resumable per training seed: each writes ``OUT/her_cells/seed{S}_steps{N}.json`` when it is done
(its model under ``results/highway_her``), and a second call skips the seeds written. Writes
``highway_her.{csv,json,md}`` in ``OUT`` (``docs/highway``), with the time per 1000 steps.
"""

from __future__ import annotations

import json
import os
import time
from dataclasses import dataclass
from pathlib import Path
from statistics import mean
from typing import Any

import gymnasium as gym
import numpy as np

from ilc_steering.arguments import Parser
from ilc_steering.output import write_atomic
from ilc_steering.tables import markdown_table, write_results

__all__ = ["Args", "main"]

TESTS = {"10cm": (0.10, 0.05), "1cm": (0.01, 0.01)}
"""[m], [rad]: the tests besides parking-v0's own."""
EPISODE = 100
"""Steps per episode (RL Zoo's ``max_episode_length`` for parking-v0)."""


@dataclass(frozen=True)
class Args:
    quick: bool = False
    """One seed, 200 steps, a small network, one goal: checks that the script runs (CI, < 1 min)."""
    seeds: tuple[int, ...] = (0, 1, 2)
    """Training seeds."""
    timesteps: int = 100_000
    """Environment steps of training per seed (RL Zoo's 1e5)."""
    goals: tuple[int, ...] = tuple(range(20))
    """parking-v0's reset seeds evaluated: the goals."""
    out: Path = Path("docs/highway")
    """Where the tables go."""
    models: Path = Path("results/highway_her")
    """Where the trained models go (not committed)."""


def _env() -> gym.Env[Any, Any]:
    import highway_env

    gym.register_envs(highway_env)
    return gym.wrappers.TimeLimit(gym.make("parking-v0"), max_episode_steps=EPISODE)


def _model(env: gym.Env[Any, Any], seed: int, quick: bool) -> Any:
    from sb3_contrib import TQC
    from stable_baselines3 import HerReplayBuffer

    return TQC(
        "MultiInputPolicy",
        env,
        buffer_size=1_000_000,
        batch_size=64 if quick else 1024,
        gamma=0.95,
        learning_rate=1e-3,
        tau=0.05,
        learning_starts=100,
        replay_buffer_class=HerReplayBuffer,
        replay_buffer_kwargs={"goal_selection_strategy": "future", "n_sampled_goal": 4},
        policy_kwargs={"net_arch": [64, 64] if quick else [512, 512, 512], "n_critics": 2},
        seed=seed,
        device="cpu",
        verbose=0,
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
    return rows


def _train(seed: int, args: Args, timesteps: int, goals: tuple[int, ...]) -> dict[str, Any]:
    env = _env()
    model = _model(env, seed, args.quick)
    start = time.perf_counter()
    model.learn(total_timesteps=timesteps)
    seconds = time.perf_counter() - start
    args.models.mkdir(parents=True, exist_ok=True)
    model.save(args.models / f"tqc_her_seed{seed}_steps{timesteps}")
    rows = evaluate(model, goals)
    return {
        "seed": seed,
        "timesteps": timesteps,
        "train_seconds": seconds,
        "seconds_per_1000_steps": 1000 * seconds / timesteps,
        "goals": rows,
    }


def main(args: Args) -> list[dict[str, Any]]:
    seeds, timesteps, goals = args.seeds, args.timesteps, args.goals
    if args.quick:
        seeds, timesteps, goals = (0,), 200, (4,)
    os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
    import torch

    torch.set_num_threads(1)  # the machine is shared; more threads than cores cost 100x here (measured)
    cells = args.out / "her_cells"
    cells.mkdir(parents=True, exist_ok=True)
    results = []
    for seed in seeds:
        path = cells / f"seed{seed}_steps{timesteps}{'_quick' if args.quick else ''}.json"
        if path.is_file():
            results.append(json.loads(path.read_text()))
            continue
        result = _train(seed, args, timesteps, goals)
        write_atomic(path, json.dumps(result))
        results.append(result)
    rows = [
        {"seed": r["seed"], "timesteps": r["timesteps"], "seconds_per_1000_steps": r["seconds_per_1000_steps"], **g}
        for r in results
        for g in r["goals"]
    ]
    summary = []
    for r in results:
        goal_rows = r["goals"]
        summary.append(
            [
                str(r["seed"]),
                f"{r['timesteps']:,}",
                f"{sum(g['success'] for g in goal_rows)}/{len(goal_rows)}",
                f"{sum(g['10cm'] for g in goal_rows)}/{len(goal_rows)}",
                f"{sum(g['1cm'] for g in goal_rows)}/{len(goal_rows)}",
                f"{mean(g['cartesian_error'] for g in goal_rows):.3g}",
                str(sum(g["crashed"] for g in goal_rows)),
                f"{r['seconds_per_1000_steps']:.1f}",
            ]
        )
    header = ["seed", "env steps", "parking-v0 success", "10 cm / 0.05 rad", "1 cm / 0.01 rad", "mean error [m]"]
    table = markdown_table([*header, "crashes", "s per 1000 steps"], summary, [False] + [True] * 7)
    markdown = (
        f"# TQC + HER in parking-v0 ({'--quick: ' if args.quick else ''}RL Zoo's hyperparameters), "
        f"evaluated on goal seeds {list(goals)}\n\n{table}"
    )
    write_results(rows, args.out, "highway_her" + ("_quick" if args.quick else ""), markdown, {"quick": args.quick})
    print(table)
    return rows


if __name__ == "__main__":
    parser = Parser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--seeds", default=",".join(map(str, Args.seeds)))
    parser.add_argument("--timesteps", type=int, default=Args.timesteps)
    parser.add_argument("--out", type=Path, default=Args.out)
    cli = parser.parse_args()
    main(Args(cli.quick, tuple(int(s) for s in cli.seeds.split(",")), cli.timesteps, Args.goals, cli.out))
