"""Car trials per second: scalar ``env.step``, the batched vector env, and a solve_ivp reference.

In one run, for each paper task and on the same trials (the nominal open-loop solution with
every coefficient perturbed by 10%, seeded: the kind of trial an optimizer runs):

- ``solve_ivp(method="DOP853", rtol=atol=1e-8)``, one call per trial: the reference speed;
- ``env.step`` of :class:`~ilc_steering.envs.steering_env.ChainedSteeringEnv`, one trial per call,
  plain, with ``record_trajectory=True``, and followed by ``render()`` (``rgb_array``);
- ``env.step`` through ``gym.make`` (with the wrappers it adds: order enforcing, the passive
  checker), one trial per call;
- ``step`` of :class:`~ilc_steering.envs.steering_vector_env.ChainedSteeringVectorEnv` at
  each batch size ``N``, ``N`` trials per call, and at the largest ``N`` with a different true
  plant per trial (``true_factors``);
- the kernels alone at each ``N``: the batched car kernel (:mod:`ilc_steering.core.tangent`)
  and the one it replaced (``car_fields.ANGLE_KERNEL``), timed in alternation in the same
  run: the speed-up of the new one is their ratio;
- for every path, the largest final-state difference from ``solve_ivp`` at rtol = atol = 1e-12
  (restarted at every steering-limit crossing) over the first trials, and how far that reference
  is from itself at rtol = 1e-13;
- the peak memory traced (``tracemalloc``) during one call, and the process's peak RSS;
- numba's compile time: the first trial in a fresh process with an empty cache, and with the
  cache that run wrote; and the first ``ilc-steering run forward_parking`` with an empty cache
  (the whole command: interpreter, imports, compile, learning), then with the cache;
- a robustness map: ``ilc-steering sweep forward_parking`` (the paper's law on a 41 x 41 grid).

Times are medians over ``repeats``; speed-ups are against the reference timed in the same run.

    python benchmarks/throughput.py [--quick] [--out DIR]

writes ``throughput.json``, ``throughput.csv`` and ``throughput.md`` to ``DIR``.
"""

from __future__ import annotations

import os
import platform
import resource
import subprocess
import sys
import tempfile
import time
import tracemalloc
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from ilc_steering.arguments import Parser
from ilc_steering.config import load_config
from ilc_steering.core.grid import steps_per_span
from ilc_steering.core.integrate import integrate
from ilc_steering.core.reference import trial as car_trial
from ilc_steering.core.robots.car_fields import ANGLE_KERNEL
from ilc_steering.engine.provenance import record_made
from ilc_steering.envs.scenario import Scenario
from ilc_steering.envs.steering_env import ChainedSteeringEnv
from ilc_steering.envs.steering_vector_env import ChainedSteeringVectorEnv
from ilc_steering.envs.vector_base import PARALLEL_FROM
from ilc_steering.tables import markdown_table, median_seconds, write_results

TARGETS = {
    "gym_make_step_ms": 0.1,
    "batched_speedup_over_angles": 4.0,
    "batched_speedup_over_solve_ivp": 500.0,
    "first_run_s": 10.0,
    "sweep_41x41_s": 60.0,
    "error": 1e-9,
}


@dataclass(frozen=True)
class Args:
    quick: bool = False
    """Small batches, few trials and repeats: checks that the script runs (CI)."""
    repeats: int = 5
    """Timing repeats; medians are reported."""
    sizes: tuple[int, ...] = (1, 64, 1024, 8192)
    """Batch sizes N of the vector env."""
    tasks: tuple[str, ...] = ("forward_parking", "forward_parking_saturated", "parallel_parking")
    """Packaged car configs."""
    scalar_steps: int = 500
    """env.step calls per timing repeat."""
    render_steps: int = 20
    """env.step + render() calls per timing repeat."""
    reference_trials: int = 5
    """solve_ivp rtol=1e-8 trials per timing repeat."""
    accuracy_trials: int = 8
    """Trials compared with solve_ivp at rtol=1e-12, per task and path."""
    compile_time: bool = True
    """Also time numba's compilation and the first run in fresh processes (about 40 s)."""
    sweep_grid: int = 41
    """Points per axis of the timed robustness map."""
    seed: int = 0
    """Seed of the perturbed trials."""
    out: Path = Path("results/benchmarks")
    """Folder for the JSON, CSV and Markdown results."""


QUICK = {
    "repeats": 2,
    "sizes": (1, 64),
    "scalar_steps": 50,
    "render_steps": 2,
    "reference_trials": 1,
    "accuracy_trials": 2,
    "sweep_grid": 5,
}


def trial_actions(scenario: Scenario, count: int, seed: int) -> np.ndarray:
    """``count`` coefficient vectors: the nominal solution, each coefficient perturbed by 10%."""
    c = scenario.nominal.solve()
    return c * (1.0 + 0.1 * np.random.default_rng(seed).standard_normal((count, c.size)))


def solve_ivp_final(scenario: Scenario, c: np.ndarray, rtol: float) -> np.ndarray:
    """The final world configuration of one trial by ``solve_ivp`` DOP853 at ``rtol`` = atol."""
    final = car_trial(scenario.plant, scenario.profile, scenario.x_start, c, rtol)
    return scenario.to_world(scenario.plant.configuration(final))


def peak_traced_mb(fn: Any) -> float:
    tracemalloc.start()
    fn()
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    return peak / 2**20


def measure_task(name: str, args: Args) -> list[dict[str, Any]]:
    scenario = Scenario.from_config(load_config(name))
    trials = trial_actions(scenario, max(*args.sizes, args.scalar_steps, args.accuracy_trials), args.seed)
    k = args.accuracy_trials
    truth = np.array([solve_ivp_final(scenario, c, 1e-12) for c in trials[:k]])
    # How far the tight reference itself is from the truth: it can graze the steering limit.
    spread = float(np.abs(truth - np.array([solve_ivp_final(scenario, c, 1e-13) for c in trials[:k]])).max())

    def error(final: np.ndarray) -> float:
        return float(np.abs(final[:k] - truth[: len(final[:k])]).max())

    rows = []

    def row(path: str, n: int, seconds_per_call: float, err: float, memory_mb: float) -> None:
        per_trial = seconds_per_call / n
        rows.append(
            {
                "task": name,
                "path": path,
                "N": n,
                "trials_per_s": 1.0 / per_trial,
                "ms_per_trial": 1e3 * per_trial,
                "speedup": reference / per_trial,
                "max_error": err,
                "peak_traced_mb": memory_mb,
                "reference_spread": spread,
                "speedup_over_angles": float("nan"),
            }
        )

    ref = trials[: args.reference_trials]
    reference = median_seconds(lambda: [solve_ivp_final(scenario, c, 1e-8) for c in ref], args.repeats) / len(ref)
    ref_error = error(np.array([solve_ivp_final(scenario, c, 1e-8) for c in trials[:k]]))
    ref_memory = peak_traced_mb(lambda: solve_ivp_final(scenario, trials[0], 1e-8))
    row("solve_ivp DOP853 rtol=1e-8, per trial", 1, reference, ref_error, ref_memory)

    env = ChainedSteeringEnv(name)
    env.reset(seed=args.seed)
    env.step(trials[0])  # compile (or load the cache) outside the timing
    steps = trials[: args.scalar_steps]
    per_step = median_seconds(lambda: [env.step(c) for c in steps], args.repeats) / len(steps)
    scalar_final = np.array([env.step(c)[4]["q_final"] for c in trials[:k]])
    row("env.step, scalar", 1, per_step, error(scalar_final), peak_traced_mb(lambda: env.step(trials[0])))

    made = gym.make("ilc_steering/ChainedSteering-v0", config=name)
    made.reset(seed=args.seed)
    made.step(trials[0])  # the passive checker's first-step checks, outside the timing
    per_step = median_seconds(lambda: [made.step(c) for c in steps], args.repeats) / len(steps)
    row("env.step via gym.make", 1, per_step, error(np.array([made.step(c)[4]["q_final"] for c in trials[:k]])), 0.0)

    # What asking for pictures costs: a recorded trajectory, and a frame drawn after each trial.
    recording = ChainedSteeringEnv(name, record_trajectory=True)
    recording.reset(seed=args.seed)
    per_step = median_seconds(lambda: [recording.step(c) for c in steps], args.repeats) / len(steps)
    recorded = np.array([recording.step(c)[4]["trajectory"].q[-1] for c in trials[:k]])
    row(
        "env.step, record_trajectory",
        1,
        per_step,
        error(scenario.to_task(recorded)),
        peak_traced_mb(lambda: recording.step(trials[0])),
    )
    rendering = ChainedSteeringEnv(name, render_mode="rgb_array")
    rendering.reset(seed=args.seed)
    rendering.step(trials[0])
    rendering.render()  # the first frame (imports, the font's glyphs) outside the timing
    drawn = trials[: args.render_steps]
    per_step = median_seconds(lambda: [(rendering.step(c), rendering.render()) for c in drawn], args.repeats) / len(
        drawn
    )
    row(
        "env.step + render(), rgb_array",
        1,
        per_step,
        float("nan"),
        peak_traced_mb(lambda: (rendering.step(trials[0]), rendering.render())),
    )

    for n in args.sizes:
        envs = ChainedSteeringVectorEnv(n, name)
        envs.reset(seed=args.seed)
        batch = trials[:n]
        final = envs.step(batch)[4]["final_info"]["q_final"]  # also warms the parallel kernel
        seconds = median_seconds(lambda: envs.step(batch), args.repeats)  # noqa: B023
        row(f"vector env, N = {n}", n, seconds, error(final), peak_traced_mb(lambda: envs.step(batch)))  # noqa: B023
        new, old = kernel_calls(scenario, batch, n >= PARALLEL_FROM)
        new_s, old_s = alternating_medians(new, old, args.repeats)
        row(f"batched car kernel, N = {n}", n, new_s, error(scenario.to_world(new())), 0.0)
        row(f"angle kernel (before), N = {n}", n, old_s, error(scenario.to_world(old())), 0.0)
        rows[-2]["speedup_over_angles"] = old_s / new_s
    n = max(args.sizes)
    factors = np.exp(0.1 * np.random.default_rng(args.seed).standard_normal((n, 2)))
    plants = ChainedSteeringVectorEnv(n, name, true_factors=factors)
    plants.reset(seed=args.seed)
    plants.step(trials[:n])
    seconds = median_seconds(lambda: plants.step(trials[:n]), args.repeats)
    row(f"vector env, N = {n} plants (true_factors)", n, seconds, float("nan"), 0.0)
    return rows


def kernel_calls(scenario: Scenario, c: np.ndarray, parallel: bool) -> tuple[Any, Any]:
    """The batched car kernel and the angle kernel on the trials ``c``: callables returning the
    final configurations (task frame)."""
    profile = scenario.profile
    spans = np.asarray(profile.spans, dtype=np.float64)
    steps = steps_per_span(spans, scenario.max_step)
    v1, v2 = profile.polynomials(c)
    field, params = scenario.plant.kernel()
    x0 = np.ascontiguousarray(np.broadcast_to(scenario.x_start, (c.shape[0], scenario.x_start.size)))

    def run(angles: bool) -> np.ndarray:
        kernel = ANGLE_KERNEL if angles else field
        final = integrate(kernel, params, x0, spans, steps, v1, v2, parallel=parallel)[0]
        return scenario.plant.configuration(final)

    run(False), run(True)  # compile or load outside the timing
    return (lambda: run(False)), (lambda: run(True))


def alternating_medians(first: Any, second: Any, repeats: int) -> tuple[float, float]:
    """Median seconds of ``first()`` and ``second()``, called in alternation: a machine that
    slows down during the run slows both alike, so their ratio holds."""
    a, b = [], []
    for _ in range(max(repeats, 3)):
        a.append(median_seconds(first, 1))
        b.append(median_seconds(second, 1))
    return float(np.median(a)), float(np.median(b))


COMPILE_SNIPPET = """
import time
from ilc_steering.config import load_config
from ilc_steering.envs.scenario import Scenario
scenario = Scenario.from_config(load_config("forward_parking"))
c = scenario.nominal.solve()[None]
start = time.perf_counter(); scenario.run(c); serial = time.perf_counter() - start
c = c.repeat(64, axis=0)  # more than a block of lanes: the parallel kernel
start = time.perf_counter(); scenario.run(c, parallel=True); parallel = time.perf_counter() - start
print(serial, parallel)
"""


def compile_times() -> dict[str, float]:
    """Seconds of the first serial and first parallel call, cold (empty numba cache) and cached."""
    out = {}
    with tempfile.TemporaryDirectory() as cache:
        env = {**os.environ, "NUMBA_CACHE_DIR": cache}
        for state in ("cold", "cached"):
            # Run outside the checkout: from its root, the bare ilc_steering/ folder would shadow the install.
            done = subprocess.run(
                [sys.executable, "-c", COMPILE_SNIPPET], env=env, cwd=cache, capture_output=True, text=True
            )
            if done.returncode != 0:
                raise RuntimeError(f"compile-time probe failed:\n{done.stderr}")
            serial, parallel = map(float, done.stdout.split())
            out[f"{state}_serial_s"], out[f"{state}_parallel_s"] = serial, parallel
    with tempfile.TemporaryDirectory() as cache:
        env = {**os.environ, "NUMBA_CACHE_DIR": cache}
        for state in ("cold", "cached"):
            start = time.perf_counter()
            done = subprocess.run(
                [sys.executable, "-m", "ilc_steering", "run", "forward_parking"],
                env=env,
                cwd=cache,
                capture_output=True,
                text=True,
            )
            out[f"{state}_first_run_s"] = time.perf_counter() - start
            if done.returncode != 0:
                raise RuntimeError(f"ilc-steering run forward_parking failed:\n{done.stderr}")
    return out


def sweep_seconds(grid: int) -> float:
    """Wall time of ``ilc-steering sweep forward_parking --grid grid`` (the paper's law), compiled."""
    from ilc_steering.sweep.command import main as sweep
    from ilc_steering.sweep.rows import SweepArgs

    with tempfile.TemporaryDirectory() as folder:
        start = time.perf_counter()
        sweep(SweepArgs(grid=grid, out=Path(folder)))
        return time.perf_counter() - start


def machine() -> dict[str, Any]:
    import numba

    return {
        "platform": platform.platform(),
        "processor": platform.processor() or platform.machine(),
        "cpus": os.cpu_count(),
        "numba_threads": numba.get_num_threads(),
        "python": platform.python_version(),
        "numpy": np.__version__,
        "numba": numba.__version__,
    }


def report(rows: list[dict[str, Any]], extra: dict[str, Any]) -> str:
    table = [
        [
            r["task"],
            r["path"],
            f"{r['trials_per_s']:,.0f}",
            f"{r['ms_per_trial']:.4f}",
            f"{r['speedup']:.1f}x",
            f"{r['max_error']:.1e}",
            f"{r['peak_traced_mb']:.2f}",
        ]
        for r in rows
    ]
    header = [
        "task",
        "path",
        "trials / s",
        "ms / trial",
        "speed-up vs solve_ivp",
        "max final-state error",
        "peak traced memory [MB]",
    ]
    text = markdown_table(header, table, [False, False, True, True, True, True, True])
    spreads = {r["task"]: r["reference_spread"] for r in rows}
    text += "\nThe reference itself, rtol = 1e-12 against 1e-13 (max final-state difference): "
    text += ", ".join(f"{task} {value:.1e}" for task, value in spreads.items()) + ".\n"
    m = extra["machine"]
    text += (
        f"\n{m['cpus']} CPUs ({m['processor']}), {m['numba_threads']} numba threads, Python {m['python']}, "
        f"numpy {m['numpy']}, numba {m['numba']}. Peak RSS of the run: {extra['peak_rss_mb']:.0f} MB.\n"
    )
    if "compile" in extra:
        c = extra["compile"]
        text += (
            f"Compile time of the first trial: {c['cold_serial_s']:.1f} s serial + {c['cold_parallel_s']:.1f} s "
            f"parallel with an empty numba cache; {c['cached_serial_s']:.2f} s + {c['cached_parallel_s']:.2f} s "
            "from the cache in a new process.\n"
            f"`ilc-steering run forward_parking`, the whole command: {c['cold_first_run_s']:.1f} s with an empty numba "
            f"cache, {c['cached_first_run_s']:.1f} s with it.\n"
        )
    text += f"A {extra['sweep_grid']} x {extra['sweep_grid']} robustness map (`ilc-steering sweep forward_parking`): "
    text += f"{extra['sweep_s']:.1f} s.\n"
    speedups = [r for r in rows if r["speedup_over_angles"] == r["speedup_over_angles"]]  # not NaN
    if speedups:
        text += "\nBatched car kernel over the angle kernel, same trials, timed in alternation: "
        text += ", ".join(f"{r['task']} N = {r['N']} {r['speedup_over_angles']:.1f}x" for r in speedups) + ".\n"
    return text


def main(args: Args) -> list[dict[str, Any]]:
    if args.quick:
        args = Args(**{**asdict(args), **QUICK, "quick": True})
    rows = [r for name in args.tasks for r in measure_task(name, args)]
    extra: dict[str, Any] = {"args": asdict(args), "machine": machine(), "targets": TARGETS}
    if args.compile_time:
        extra["compile"] = compile_times()
    extra["sweep_s"] = sweep_seconds(args.sweep_grid)
    extra["sweep_grid"] = args.sweep_grid
    extra["peak_rss_mb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    text = report(rows, extra)
    write_results(rows, args.out, "throughput", text, extra)
    print(text)
    return rows


def parse(argv: list[str] | None = None) -> Args:
    parser = Parser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="small batches, few trials and repeats (CI)")
    parser.add_argument("--repeats", type=int, default=Args.repeats, help="timing repeats; medians are reported")
    parser.add_argument("--sizes", type=int, nargs="+", default=list(Args.sizes), help="batch sizes N")
    parser.add_argument("--no-compile-time", action="store_true", help="skip timing numba's compilation")
    parser.add_argument("--out", type=Path, default=Args.out, help="folder for the results")
    ns = parser.parse_args(argv)
    return Args(
        quick=ns.quick, repeats=ns.repeats, sizes=tuple(ns.sizes), compile_time=not ns.no_compile_time, out=ns.out
    )


if __name__ == "__main__":
    arguments = parse()
    main(arguments)
    record_made(arguments.out, __file__, sys.argv[1:])
