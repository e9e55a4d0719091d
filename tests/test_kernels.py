"""One factory for every robot's batch runners (``ilc_steering.core.kernels``): each robot's runners
are its own compiled functions, named and cached apart, in one process and across processes."""

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
from numba import njit

from ilc_steering.core.kernels import trial_kernel
from ilc_steering.core.plants import KernelLayout
from ilc_steering.core.robots import car_trailer_fields, chained, unicycle

HERE = Path(__file__).resolve().parent

# Four robots on two templates: a confused cache would hand one robot another's runner, which
# compiles from the same bytecode and runs without complaint, so each process checks the numbers.
RUN = textwrap.dedent(
    """
    import json, sys
    import numpy as np
    sys.path.insert(0, {tests!r})
    import toy_robot
    from ilc_steering.config import load_config
    from ilc_steering.core.simulate import simulate
    from ilc_steering.envs.scenario import Scenario
    out = {{}}
    for name in ("unicycle_parking", "trailer_hitch", "chained_perturbed"):
        scenario = Scenario.from_config(load_config(name))
        c = np.tile(scenario.nominals[0].solve(), (3, 1)) * np.array([[1.0], [1.01], [0.99]])
        x0 = np.tile(scenario.x_start, (3, 1))
        trials = simulate(scenario.plant, scenario.profile, x0, c, scenario.max_step)
        out[name] = trials.final.tolist()
    plant = toy_robot.SkatePlant(1.1, 0.9)
    scenario = Scenario.from_config(load_config({skate!r}))
    c = np.tile(scenario.nominals[0].solve(), (2, 1))
    out["skate"] = simulate(plant, scenario.profile, np.zeros((2, 3)), c, scenario.max_step).final.tolist()
    from ilc_steering.core.robots import chained
    runners = [chained.KERNEL.serial, toy_robot.KERNEL.serial]
    out["misses"] = sum(sum(r.stats.cache_misses.values()) for r in runners)
    out["hits"] = sum(sum(r.stats.cache_hits.values()) for r in runners)
    print(json.dumps(out))
    """
)


def test_each_kernel_is_compiled_under_its_robots_module_and_its_own_name():
    runners = {
        "unicycle": unicycle.KERNEL,
        "trailer": car_trailer_fields.LANES_KERNEL,
        "trailer (stop)": car_trailer_fields.KERNEL,
        "chained": chained.KERNEL,
    }
    names = set()
    for kernel in runners.values():
        for runner in (kernel.serial, kernel.parallel):
            function = getattr(runner, "py_func", None)
            if function is None:  # a lane kernel's Python runner: its blocks are compiled
                continue
            assert function.__code__.co_filename == sys.modules[function.__module__].__file__
            names.add((function.__module__, function.__qualname__))
    assert ("ilc_steering.core.robots.chained", "chained_form__serial") in names
    assert len(names) == 4  # two compiled runners each for the two trial kernels, none shared


def test_two_kernels_of_one_name_in_one_module_are_refused():
    layout = KernelLayout(("x",), ("gain",))

    @njit(inline="always")
    def field(params, x, v1, v2, out):  # type: ignore[no-untyped-def]
        out[0] = params[0] * v1

    kernel = trial_kernel("decay test", layout, __name__, field)
    assert kernel.serial.py_func.__qualname__ == "decay_test__serial"
    with pytest.raises(ValueError, match="two kernels named 'decay test'"):
        trial_kernel("decay test", layout, __name__, field)
    with pytest.raises(ValueError, match="imported module"):
        trial_kernel("other", layout, "no_such_module", field)


def run_fresh(cache: Path) -> dict:
    code = RUN.format(tests=str(HERE), skate=str(HERE.parent / "configs" / "unicycle_parking.yaml"))
    env = {**os.environ, "NUMBA_CACHE_DIR": str(cache), "MALLOC_CHECK_": "3", "MALLOC_PERTURB_": "165"}
    done = subprocess.run(
        [sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=600, cwd=cache.parent
    )
    assert done.returncode == 0, done.stderr[-3000:]
    return json.loads(done.stdout.strip().splitlines()[-1])


@pytest.mark.slow  # two fresh processes, the first compiling four robots into an empty cache
def test_robots_built_by_one_factory_share_no_cache_entry_in_a_fresh_process_with_a_warm_cache(tmp_path):
    cache = tmp_path / "numba-cache"
    first = run_fresh(cache)
    second = run_fresh(cache)
    assert first["misses"] > 0 and first["hits"] == 0  # compiled, each into its own file
    assert second["misses"] == 0 and second["hits"] > 0  # loaded, each from its own file
    for name in ("unicycle_parking", "trailer_hitch", "chained_perturbed", "skate"):
        assert np.array_equal(first[name], second[name]), name
    assert not np.allclose(first["unicycle_parking"][0], first["skate"][0])
    names = {path.name.split("-")[0] for path in cache.rglob("*.nbi")}
    assert {"toy_robot.skate__serial", "chained.chained_form__serial", "unicycle.unicycle__block_one"} <= names
