"""The single runs the pages quote: ``ilc-steering run`` on a task, its output kept as an artifact.

    python benchmarks/runs.py [--only NAME ...] [--folder FOLDER ...] [--list] [--out results]

Each run of :data:`RUNS` is a packaged config, or one with a few keys changed (written beside the
output, ``<folder>/configs/<name>.yaml``, so the run can be repeated as it was), and the options
of ``ilc-steering run``; or a ``python`` block of a page. Its output goes to
``<out>/<folder>/<name>.txt``: the command on the first line, what the run is on the next, then
what it printed (stdout and stderr as they came) and its exit code. Each folder it writes gets
its entry in ``made.json`` (the command and the code: the closure of the CLI, the runs' learners
and robots), so ``ilc-steering current`` tells when a run must be made again.
"""

from __future__ import annotations

import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from ilc_steering.agents.registry import lookup
from ilc_steering.arguments import Parser
from ilc_steering.config import load_config
from ilc_steering.engine.provenance import record_made
from ilc_steering.output import write_atomic


@dataclass(frozen=True)
class Run:
    """One run: ``config`` (a packaged config's name) with ``changes`` (``section: {key: value}``,
    None for the packaged config as it is), run with ``options``; or, with ``page``, the first
    ``python`` block after ``heading`` of that page."""

    note: str
    config: str = ""
    changes: dict[str, dict[str, Any]] | None = None
    options: tuple[str, ...] = ()
    page: str = ""
    heading: str = ""
    learners: tuple[str, ...] = ("ilc_paper",)
    """The learners the run uses (``run``'s default: the paper's law), roots of its code."""
    task_of: str = ""
    """Take the ``task`` section of this packaged config (a task on another robot)."""
    generate: tuple[str, ...] = ()
    """``python -m`` arguments whose output is the config (a generated task), instead of ``config``."""
    cli: tuple[str, ...] = ()
    """An ``ilc-steering`` command of its own (``reproduce``), instead of ``run``."""
    title: str = ""
    """The changed config's ``name`` (empty: the one it has)."""


TRAILER = "configs/trailer_bay.yaml"
RUNS: dict[str, Run] = {
    "reproduce/reproduce": Run(
        "the paper's simulations and experiments: every table of docs/paper.md",
        "forward_parking",
        cli=("reproduce",),
        learners=("ilc_paper", "newton_ilc", "robust_ilc", "ilc"),
    ),
    "reproduce/unicycle_parking": Run("the packaged unicycle task", "unicycle_parking"),
    "reproduce/trailer_bay": Run("the packaged trailer task", "trailer_bay"),
    "reproduce/cyclic_pickup_dropoff": Run(
        "the packaged cycle of waypoints", "cyclic_pickup_dropoff", learners=("ilc",)
    ),
    "reproduce/trailer_bay_wheelbase": Run(
        f"{TRAILER} with only the true wheelbase off (10 % longer) and 12 trials",
        "trailer_bay",
        {
            "plant": {"true_wheelbase": 0.22, "true_wheel_radius": 0.02, "true_hitch_length": 0.3},
            "learning": {"trials": 12},
        },
    ),
    "reproduce/trailer_bay_hitch": Run(
        f"{TRAILER} with only the true hitch off (10 % shorter) and 12 trials",
        "trailer_bay",
        {
            "plant": {"true_wheelbase": 0.2, "true_wheel_radius": 0.02, "true_hitch_length": 0.27},
            "learning": {"trials": 12},
        },
    ),
    "reproduce/trailer_bay_forward": Run(
        f"{TRAILER} driven forward to (1.5, 0.6, 0.5), wheelbase 10 % longer and hitch 10 % shorter, 12 trials",
        "trailer_bay",
        {
            "task": {"goal": [1.5, 0.6, 0.5, 0.0, 0.0]},
            "plant": {"true_wheelbase": 0.22, "true_wheel_radius": 0.02, "true_hitch_length": 0.27},
            "learning": {"trials": 12},
        },
    ),
    "learners/parallel_parking_offset_ilc_paper": Run(
        "configs/parallel_parking.yaml with a 0.002 rad steering offset, the paper's law",
        "parallel_parking",
        {"plant": {"steering_offset": 0.002}},
        ("--learner", "ilc_paper", "--trials", "20"),
    ),
    "learners/parallel_parking_offset_newton_ilc": Run(
        "configs/parallel_parking.yaml with a 0.002 rad steering offset, newton_ilc",
        "parallel_parking",
        {"plant": {"steering_offset": 0.002}},
        ("--learner", "newton_ilc", "--trials", "20"),
        learners=("newton_ilc",),
    ),
    "learners/broyden": Run(
        "the python block of docs/learners.md's 'Your own learner' (Broyden on parallel_parking, 6 trials, seed 0): "
        "the Cartesian error [m] of each trial",
        page="docs/learners.md",
        heading="## Your own learner",
    ),
    "mujoco/spread08_robust_ilc": Run(
        "configs/mujoco_forward_parking_scatter.yaml with plant.friction_spread 0.8 (mujoco_spread.md's 0.8 row)",
        "mujoco_forward_parking_scatter",
        {"plant": {"friction_spread": 0.8}},
        ("--learner", "robust_ilc", "--trials", "15"),
        learners=("robust_ilc",),
    ),
    "mujoco/spread08_newton_ilc": Run(
        "configs/mujoco_forward_parking_scatter.yaml with plant.friction_spread 0.8 (mujoco_spread.md's 0.8 row)",
        "mujoco_forward_parking_scatter",
        {"plant": {"friction_spread": 0.8}},
        ("--learner", "newton_ilc", "--trials", "15"),
        learners=("newton_ilc",),
    ),
    "mujoco/simulation3_robust_ilc": Run(
        "simulation 3's task (configs/parallel_parking.yaml's task) on the MuJoCo car of "
        "configs/mujoco_parallel_parking.yaml (its plant and learning)",
        "mujoco_parallel_parking",
        {},
        ("--learner", "robust_ilc"),
        learners=("robust_ilc",),
        task_of="parallel_parking",
        title="mujoco_simulation3",
    ),
    "highway/highway_pictures_seed12": Run(
        "the run benchmarks/highway_pictures.py --seed 12 draws: parking-v0 seed 12, generated by "
        "python -m ilc_steering.envs.highway --seed 12",
        "highway_parking",
        {},
        ("--learner", "robust_ilc", "--trials", "8"),
        learners=("robust_ilc",),
        generate=("ilc_steering.envs.highway", "--seed", "12"),
    ),
    "highway/highway_pictures": Run(
        "the run benchmarks/highway_pictures.py draws: parking-v0 seed 4",
        "highway_parking",
        None,
        ("--learner", "robust_ilc", "--trials", "8"),
        learners=("robust_ilc",),
    ),
    **{
        f"robustness/tasks/{task}_{learner}": Run(
            f"the packaged {task} task, {learner}",
            task,
            None,
            ("--learner", learner, "--trials", "30"),
            learners=(learner,),
        )
        for task in ("parallel_parking_servo", "parallel_parking_lag", "trailer_hitch")
        for learner in ("ilc", "newton_ilc", "robust_ilc")
    },
}
"""Every run, by its output's path under ``--out`` (without ``.txt``)."""


def _packaged_yaml(name: str) -> dict[str, Any]:
    from importlib import resources

    data: dict[str, Any] = yaml.safe_load((resources.files("ilc_steering.configs") / f"{name}.yaml").read_text())
    return data


def _python_block(page: Path, heading: str) -> str:
    """The first ``python`` block after ``heading`` in ``page``."""
    text = page.read_text()
    start = text.index(heading)
    block = text.index("```python\n", start) + len("```python\n")
    return text[block : text.index("```", block)]


def command(name: str, run: Run, out: Path) -> tuple[list[str], str]:
    """The command of ``run`` (its changed config written now) and how its first line shows it."""
    if run.page:
        root = Path(__file__).resolve().parent.parent
        code = _python_block(root / run.page, run.heading)
        return [sys.executable, "-c", code], f"python <the python block of {run.page}, {run.heading!r}>"
    if run.cli:
        return [sys.executable, "-m", "ilc_steering", *run.cli], " ".join(["ilc-steering", *run.cli])
    config = run.config
    if run.changes is not None:
        if run.generate:
            made = subprocess.run([sys.executable, "-m", *run.generate], capture_output=True, text=True, check=True)
            data = yaml.safe_load(made.stdout)
        else:
            data = _packaged_yaml(run.config)
        if run.task_of:
            data["task"] = _packaged_yaml(run.task_of)["task"]
        for section, keys in run.changes.items():
            data.setdefault(section, {}).update(keys)
        data["name"] = run.title or data["name"]
        path = out / Path(name).parent / "configs" / f"{Path(name).name}.yaml"
        path.parent.mkdir(parents=True, exist_ok=True)
        write_atomic(path, yaml.safe_dump(data, sort_keys=False))
        config = str(path)
    argv = ["run", config, *run.options]
    return [sys.executable, "-m", "ilc_steering", *argv], " ".join(["ilc-steering", *argv])


def run_roots(run: Run) -> tuple[str, ...]:
    """Where a run's computation starts: the CLI, its learner and its robot."""
    robot = () if run.page else (type(load_config(run.config).plant).__module__,)
    learners = [root for learner in run.learners for root in lookup(learner).sources()]
    return ("ilc_steering.cli", "ilc_steering.runner", *learners, *robot, "ilc_steering.configs")


def make(name: str, run: Run, out: Path) -> int:
    """Run ``run``, write its output to ``out/<name>.txt``; its exit code."""
    argv, shown = command(name, run, out)
    done = subprocess.run(argv, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, timeout=3600)
    text = f"# {shown}\n# {run.note}\n{done.stdout}"
    target = out / f"{name}.txt"
    target.parent.mkdir(parents=True, exist_ok=True)
    write_atomic(target, text + f"# exit {done.returncode}\n")
    print(f"{target}: exit {done.returncode}", flush=True)
    return done.returncode


def main(argv: list[str] | None = None) -> int:
    parser = Parser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--only", nargs="+", default=None, metavar="NAME", help="these runs only (see --list)")
    parser.add_argument(
        "--folder", nargs="+", default=None, metavar="FOLDER", help="the runs of these folders (reproduce, ...)"
    )
    parser.add_argument("--list", action="store_true", help="print the runs' names and what each is")
    parser.add_argument("--out", type=Path, default=Path("results"), help="the folder of the results")
    args = parser.parse_args(argv)
    if args.list:
        for name, run in RUNS.items():
            print(f"{name}: {run.note}")
        return 0
    unknown = sorted(set(args.only or ()) - set(RUNS))
    if unknown:
        parser.error(f"--only: no run named {unknown[0]!r}; --list names them")
    folders_of = {str(Path(name).parent) for name in RUNS}
    unknown = sorted(set(args.folder or ()) - folders_of)
    if unknown:
        parser.error(f"--folder: no run is in {unknown[0]!r} (the folders: {', '.join(sorted(folders_of))})")
    named = [*(args.only or ()), *(n for n in RUNS if str(Path(n).parent) in (args.folder or ()))]
    chosen = {name: RUNS[name] for name in named or RUNS}
    folders = dict.fromkeys(args.out / Path(name).parent for name in chosen)
    for name, run in chosen.items():
        make(name, run, args.out)
    for folder in folders:
        every = {n: r for n, r in RUNS.items() if args.out / Path(n).parent == folder}
        if set(every) <= set(chosen):  # only a folder whose every run was made now is of this code
            roots = sorted(set().union(*(run_roots(r) for r in every.values())))
            record_made(folder, __file__, ["--only", *sorted(every)], roots)
        else:
            print(f"{folder}: its made.json is left as it was: make all its runs to record them", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
