"""Property-based tests: whatever a user passes, the library answers with a result or a clear
``ValueError`` (exit 2 on the command line): never a traceback of another kind, a hang or a NaN."""

import copy
import json
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import ilc_steering  # noqa: F401  (registers the envs)
from ilc_steering.cli import main
from ilc_steering.compare.args import Args
from ilc_steering.compare.command import validate
from ilc_steering.config import load_config
from ilc_steering.envs.scenario import Scenario

CONFIGS = Path(__file__).resolve().parents[1] / "configs"
BASE = {
    name: yaml.safe_load((CONFIGS / f"{name}.yaml").read_text()) for name in ("forward_parking", "chained_perturbed")
}
FAST = settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])

numbers = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.integers(min_value=-(10**400), max_value=10**400),
    st.sampled_from([0, 1, -1, 0.5, 1e-12, 1e300, -1e300, 3.0e38]),
)
scalars = st.one_of(st.none(), st.booleans(), numbers, st.text(max_size=8))
values = st.recursive(
    scalars,
    lambda inner: st.lists(inner, max_size=6) | st.dictionaries(st.text(max_size=6), inner, max_size=3),
    max_leaves=12,
)


def paths(data, prefix=()):
    """Every (path to a value) in a config mapping."""
    for key, value in data.items():
        yield (*prefix, key)
        if isinstance(value, dict):
            yield from paths(value, (*prefix, key))


@FAST
@given(base=st.sampled_from(sorted(BASE)), data=st.data(), value=values)
@pytest.mark.slow  # many hypothesis examples
def test_any_config_value_loads_or_is_a_config_error(base, data, value):
    config = copy.deepcopy(BASE[base])
    path = data.draw(st.sampled_from(sorted(paths(config))))
    node = config
    for key in path[:-1]:
        node = node[key]
    if data.draw(st.booleans()):
        node[path[-1]] = value
    else:
        node.pop(path[-1])
    try:
        loaded = load_config(config)
    except ValueError:
        return
    scenario = Scenario.from_config(loaded)  # a config that loads builds and runs
    c = scenario.nominal.solve()
    assert np.all(np.isfinite(c)) and np.all(np.isfinite(scenario.action_high))
    measured = scenario.measure(*(lambda t: (t.final, t.status))(scenario.run(c[None])))
    assert np.isfinite(measured["error_norm"][0])


@FAST
@given(
    dtype=st.sampled_from(["float64", "float32", "int64", "complex128", "bool", "U3", "object"]),
    shape=st.sampled_from([(4,), (3,), (1, 4), (), (4, 1)]),
    fill=st.floats(allow_nan=True, allow_infinity=True) | st.integers(-(10**30), 10**30),
)
@pytest.mark.slow  # many hypothesis examples
def test_any_action_runs_a_trial_or_is_a_value_error(dtype, shape, fill):
    env = gym.make("ilc_steering/ChainedSteering-v0", config="forward_parking")
    env.reset(seed=0)
    try:
        action = np.full(shape, fill, dtype=dtype)
    except (OverflowError, ValueError, TypeError):
        return
    try:
        _, reward, terminated, _, info = env.step(action)
    except ValueError:
        return
    assert terminated and np.isfinite(reward) and np.all(np.isfinite(info["q_final"]))


@FAST
@given(options=st.none() | st.dictionaries(st.sampled_from(["start", "strt", "seed"]), values, max_size=2) | values)
@pytest.mark.slow  # many hypothesis examples
def test_any_cyclic_reset_options_start_or_are_a_value_error(options):
    env = gym.make("ilc_steering/CyclicSteering-v0", config="cyclic_home_goal", cycles=1)
    try:
        observation, _ = env.reset(seed=0, options=options)
    except ValueError:
        return
    assert np.all(np.isfinite(observation))
    model = env.unwrapped.nominal_models[0]
    _, reward, *_ = env.step(np.clip(model.solve(), env.action_space.low, env.action_space.high))
    assert np.isfinite(reward)


@FAST
@given(
    methods=st.lists(st.sampled_from(["ilc", "gauss_newton", "ppo", "nope", ""]), max_size=3),
    scenarios=st.lists(
        st.sampled_from(["forward_parking", "chained_perturbed", "cyclic_home_goal", "x", "../y"]), max_size=3
    ),
    seeds=st.lists(st.integers(-5, 2**33), max_size=3),
)
def test_any_compare_arguments_validate_or_are_a_value_error(methods, scenarios, seeds):
    try:
        names = validate(Args(methods=tuple(methods), scenarios=tuple(scenarios), seeds=tuple(seeds)))
    except ValueError:
        return
    assert len(set(names.values())) == len(scenarios) and all(0 <= s < 2**32 for s in seeds)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    trials=st.one_of(st.integers(-3, 3).map(str), st.text(max_size=4)),
    config=st.sampled_from(["forward_parking", "chained_perturbed", "nope", "/nonexistent.yaml", "", "../x.yaml"]),
)
def test_any_run_arguments_exit_0_1_or_2(trials, config, capsys):
    try:
        code = main(["run", config, "--trials", trials])
    except SystemExit as exit_:  # argparse: an argument of the wrong type
        code = exit_.code
    assert code in (0, 1, 2)
    err = capsys.readouterr().err
    assert "Traceback" not in err and "internal error" not in err


def test_a_config_json_round_trip_is_stable():
    for name in ("forward_parking", "cyclic_home_goal", "chained_perturbed"):
        import dataclasses

        config = load_config(name)
        assert load_config(json.loads(json.dumps(dataclasses.asdict(config)))) == config


@pytest.mark.parametrize("base", sorted(BASE))
def test_the_property_tests_start_from_valid_configs(base):
    assert load_config(copy.deepcopy(BASE[base])).name == base
