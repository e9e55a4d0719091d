"""Memory safety of the compiled simulator: numba's on-disk cache shared by processes, and the
checks at the boundary into compiled code.

The cache sequence is the one that corrupted the heap when two lane counts of the batched car
kernel were closures of one factory (they compiled to one symbol): with an empty cache, one trial
in one process, then batches in new processes, each under glibc's heap checking and compared with
the scalar path bit for bit.
"""

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from ilc_steering.config import load_config
from ilc_steering.core.integrate import integrate
from ilc_steering.envs.scenario import Scenario

FIRST_TRIAL = textwrap.dedent(
    """
    import gymnasium as gym
    import ilc_steering
    env = gym.make("ilc_steering/ChainedSteering-v0", config={config!r})
    env.reset(seed=0)
    env.step(env.unwrapped.nominal_model.solve())
    print("ok")
    """
)

BATCH = textwrap.dedent(
    """
    import numpy as np
    from ilc_steering.config import load_config
    from ilc_steering.core.simulate import simulate
    from ilc_steering.envs.scenario import Scenario
    scenario = Scenario.from_config(load_config({config!r}))
    c0 = scenario.nominals[0].solve()
    rng = np.random.default_rng({count})
    c = c0 * (1 + 0.05 * rng.standard_normal(({count}, c0.size)))
    x0 = np.tile(scenario.x_start, ({count}, 1))
    args = (scenario.profile, x0, c, scenario.max_step)
    for parallel in (False, True):
        batch = simulate(scenario.plant, *args, parallel=parallel)
        for i in range({count}):
            one = simulate(scenario.plant, scenario.profile, x0[i : i + 1], c[i : i + 1], scenario.max_step)
            assert np.array_equal(one.final[0], batch.final[i]) and one.status[0] == batch.status[i], (i, parallel)
    print("ok")
    """
)


def run_fresh(code: str, cache: str) -> None:
    """``code`` in a new interpreter under glibc's heap checks, outside the source tree (whose bare
    ``ilc_steering/`` folder would shadow the installed package)."""
    env = {**os.environ, "NUMBA_CACHE_DIR": cache, "MALLOC_CHECK_": "3", "MALLOC_PERTURB_": "165"}
    command = [sys.executable, "-c", code]
    done = subprocess.run(command, env=env, capture_output=True, text=True, timeout=300, cwd=Path(cache).parent)
    assert done.returncode == 0 and done.stdout.strip() == "ok", (done.returncode, done.stdout, done.stderr[-2000:])


@pytest.mark.slow  # fresh processes compiling into a fresh cache
@pytest.mark.parametrize("config", ["forward_parking_saturated", "unicycle_parking"])
def test_a_fresh_cache_shared_by_processes_keeps_every_batch_size_bit_for_bit(tmp_path, config):
    cache = str(tmp_path / "numba-cache")
    run_fresh(FIRST_TRIAL.format(config=config), cache)
    for count in (1, 7, 15, 64, 65):
        run_fresh(BATCH.format(config=config, count=count), cache)


def kernel_args(name, batch=3):
    scenario = Scenario.from_config(load_config(name))
    field, params = scenario.plant.kernel()
    c = np.tile(scenario.nominals[0].solve(), (batch, 1))
    v1, v2 = scenario.profile.polynomials(c)
    spans = np.asarray(scenario.profile.spans, dtype=np.float64)
    steps = np.full(spans.shape, 40, dtype=np.int64)
    x0 = np.tile(scenario.x_start, (batch, 1))
    return dict(kernel=field, params=params, x0=x0, durations=spans, steps=steps, v1=v1, v2=v2)


@pytest.mark.parametrize("name", ["forward_parking", "unicycle_parking", "trailer_bay", "chained_perturbed"])
@pytest.mark.parametrize(
    ("change", "message"),
    [
        (lambda a: a.update(x0=np.zeros((3, a["x0"].shape[1] + 2))), "state"),
        (lambda a: a.update(x0=np.zeros((3, 1))), "state"),
        (lambda a: a.update(params=a["params"][:-1]), "parameter"),
        (lambda a: a.update(params=np.tile(a["params"], (2, 1))), "rows of plant parameters"),
        (lambda a: a.update(v1=a["v1"][:, :-1]), "pieces"),
        (lambda a: a.update(v2=a["v2"][:2]), "trials"),
        (lambda a: a.update(steps=a["steps"][:-1]), "steps"),
        (lambda a: a.update(steps=np.zeros_like(a["steps"])), "steps"),
        (lambda a: a.update(durations=-a["durations"]), "durations"),
        (lambda a: a.update(durations=a["durations"][None]), "durations"),
        (lambda a: a.update(steps=-a["steps"]), "steps"),
        (lambda a: a.update(v1=a["v1"][..., :0]), "v1"),
        (lambda a: a.update(params=np.full_like(a["params"], np.nan)), "NaN"),
        (lambda a: a.update(x0=np.full_like(a["x0"], np.nan)), "finite"),
    ],
)
def test_the_kernel_refuses_arrays_that_do_not_fit_its_layout(name, change, message):
    args = kernel_args(name)
    change(args)
    with pytest.raises(ValueError, match=message):
        integrate(**args)
