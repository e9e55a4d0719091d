"""The Ray backend writes the same cells as the local one (wall times aside), on a local Ray."""

import json
import math
import os

import pytest

from ilc_steering.compare import command as compare
from ilc_steering.engine.backends import run_calls
from ilc_steering.sweep import command as sweep

pytestmark = [pytest.mark.slow, pytest.mark.extra("ray")]  # a local Ray, and the quick comparison on it


@pytest.fixture(scope="module")
def local_ray():
    import ray

    ray.init(num_cpus=2, include_dashboard=False, logging_level="ERROR", log_to_driver=False)
    yield
    ray.shutdown()


def cells(folder):
    found = {}
    for path in sorted((folder / "cells").glob("*.json")):
        cell = json.loads(path.read_text())
        cell.pop("wall_s")
        cell.pop("update_s", None)  # a learner's own update time, like wall_s a timing
        found[path.name] = cell
    return found


ON_RAY = ("ilc", "robust_ilc", "least_squares", "sac")
"""One method of each kind (the paper's law, a model-based learner, a black-box optimizer, an RL
agent): the quick comparison's cells of these, on Ray. tests/test_purity.py checks ray against local
cell by cell for cma_es and ppo; bayes_opt, the dearest, is left to the local run."""


@pytest.mark.extra("rl")
def test_the_quick_comparison_on_ray_writes_the_local_cells(tmp_path, local_ray, quick_comparison):
    # the local run: `compare --quick` (seeds QUICK_SEEDS), computed once per session (conftest.py)
    local = {name: cell for name, cell in cells(quick_comparison).items() if name.split("__")[1] in ON_RAY}
    args = compare.Args(quick=True, seeds=compare.QUICK_SEEDS, methods=ON_RAY, out=tmp_path / "ray", backend="ray")
    on_ray = compare.main(args)
    assert len(on_ray) == len(local) > 0 and {name.split("__")[1] for name in local} == set(ON_RAY)
    assert cells(tmp_path / "ray") == local
    # and it resumes the same way: a second run computes nothing
    stamps = {p.name: p.stat().st_mtime_ns for p in (tmp_path / "ray" / "cells").iterdir()}
    compare.main(args)
    assert {p.name: p.stat().st_mtime_ns for p in (tmp_path / "ray" / "cells").iterdir()} == stamps


def test_a_sweep_on_ray_gives_the_local_map(tmp_path, local_ray):
    args = sweep.SweepArgs(grid=4, trials=8, methods=("ilc_paper", "newton"))
    local = sweep.run_rows(sweep.SweepArgs(**{**args.__dict__, "out": tmp_path / "local"}))
    on_ray = sweep.run_rows(sweep.SweepArgs(**{**args.__dict__, "out": tmp_path / "ray", "backend": "ray"}))
    strip = {key: [{k: v for k, v in row.items() if k != "wall_s"} for row in rows] for key, rows in local.items()}
    assert {
        key: [{k: v for k, v in row.items() if k != "wall_s"} for row in rows] for key, rows in on_ray.items()
    } == strip


def test_an_error_in_a_ray_task_is_raised(local_ray):
    with pytest.raises(Exception, match="math domain error"):
        run_calls(math.sqrt, {0: (-1.0,)}, lambda key, value: None, "ray")


def test_a_ray_task_whose_worker_dies_is_its_calls_failure_and_the_run_goes_on(local_ray):
    outcomes = {}

    def finish(key, value):
        outcomes[key] = ("done", value)

    def failed(key, message):
        outcomes[key] = ("failed", message.split(":")[0])

    run_calls(os._exit, {0: (3,)}, finish, "ray", failed=failed, timeout=60.0)
    run_calls(math.sqrt, {1: (4.0,), 2: (-1.0,)}, finish, "ray", failed=failed, timeout=60.0)
    assert outcomes == {0: ("failed", "WorkerDied"), 1: ("done", 2.0), 2: ("failed", "ValueError")}
