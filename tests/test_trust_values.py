"""Issue 34, classes 5, 6, 9, 10 and 12: values checked where they enter, each refusal naming
the key (or variable, or file) and showing the value the user gave.

Each property test draws inputs of its class: physical values out of their documented ranges
(``docs/trust.md``), hyperparameters of every type, edited run files, seeds and scales.
"""

from __future__ import annotations

import copy
import math
import re
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

import ilc_steering  # noqa: F401  (registers the envs)
from ilc_steering.agents.rl_settings import BACKEND_VARIABLE, check_hyperparameters, hyperparameters, rl_backend
from ilc_steering.config import load_config
from ilc_steering.core.checks import DURATION_RANGE, FACTOR_RANGE, LENGTH_RANGE, MAX_START_ERROR
from ilc_steering.envs.steering_env import ChainedSteeringEnv
from ilc_steering.envs.steering_vector_env import ChainedSteeringVectorEnv
from ilc_steering.envs.vector_base import MAX_ENVS
from ilc_steering.envs.wrappers import MAX_SCALE, ResidualAction
from ilc_steering.errors import ConfigError

CONFIGS = Path(__file__).resolve().parents[1] / "configs"
FAST = settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])

# class 5: the environment and committed files


@pytest.mark.parametrize("value", ["jax", "", "SB3", "1", " sb3"])
def test_the_rl_backend_variable_is_checked_naming_it_and_the_choices(monkeypatch, value):
    monkeypatch.setenv(BACKEND_VARIABLE, value)
    with pytest.raises(ValueError, match=rf"{BACKEND_VARIABLE}=.*choose one of \['sbx', 'sb3', 'auto'\]"):
        rl_backend()


@pytest.fixture(scope="session")
def run_json() -> dict[str, Any]:
    from ilc_steering.runner import run_ilc

    return run_ilc("forward_parking", 2, trajectories=True).to_json()


_KEYS = st.sampled_from(["t", "q", "u"])


@FAST
@given(
    key=_KEYS, edit=st.sampled_from(["nan", "inf", "drop_column", "reverse", "drop_row", "text"]), at=st.integers(0, 50)
)
def test_plot_refuses_an_edited_trajectory_naming_the_record_and_key(run_json, key, edit, at):
    from ilc_steering.plots import load_run

    data = copy.deepcopy(run_json)
    record = data["trials"][-1]["trajectory"]
    values = record[key]
    i = at % len(values)
    if edit in ("nan", "inf"):
        if key == "t":
            values[i] = float(edit)
        else:
            values[i][0] = float(edit)
    elif edit == "drop_column":
        assume(key != "t")
        record[key] = [row[:-1] for row in values]
    elif edit == "reverse":
        assume(key == "t")
        record[key] = values[::-1]
    elif edit == "drop_row":
        record[key] = values[:-1]
    else:
        values[i] = "x"
    with pytest.raises(ValueError, match=r"<run>: trials record 1: 'trajectory") as caught:
        load_run(data)
    assert "\n" not in str(caught.value)


@FAST
@given(
    key=st.sampled_from(["error_norm", "cartesian_error", "orientation_error"]),
    value=st.sampled_from([-1.0, math.nan, math.inf]),
)
def test_plot_refuses_a_non_finite_or_negative_error(run_json, key, value):
    from ilc_steering.plots import load_run

    data = copy.deepcopy(run_json)
    data["trials"][0][key] = value
    with pytest.raises(ValueError, match=rf"trials record 0: '{key}' must be a finite number >= 0"):
        load_run(data)


def test_plot_accepts_the_run_it_wrote(run_json):
    from ilc_steering.plots import load_run

    assert len(load_run(run_json).records) == 2


# class 6: physical ranges

FORWARD = (CONFIGS / "forward_parking.yaml").read_text()
_OUTSIDE = st.one_of(
    st.floats(min_value=1e-300, max_value=0.999e-3), st.floats(min_value=1.001e3, max_value=1e300), st.just(0.0)
)


def _edited(tmp_path: Path, old: str, new: str) -> Path:
    assert old in FORWARD, old
    path = tmp_path / "c.yaml"
    path.write_text(FORWARD.replace(old, new, 1))
    return path


@FAST
@given(key=st.sampled_from(["wheelbase", "wheel_radius", "true_wheelbase", "true_wheel_radius"]), value=_OUTSIDE)
def test_a_length_outside_its_range_is_refused_with_the_value_given(tmp_path, key, value):
    text = FORWARD
    line = next(l for l in text.splitlines() if l.strip().startswith(f"{key}:"))
    path = _edited(tmp_path, line, f"  {key}: {value!r}")
    with pytest.raises(
        ConfigError, match=rf"plant\.{key}: must be a length in \[0.001, 1000\] m, got {re.escape(repr(value))}"
    ):
        load_config(path)


@FAST
@given(value=st.one_of(st.floats(min_value=1e-300, max_value=0.99e-3), st.floats(min_value=1.01e4, max_value=1e300)))
def test_a_piece_outside_its_range_is_refused(tmp_path, value):
    line = next(l for l in FORWARD.splitlines() if l.strip().startswith("pieces:"))
    path = _edited(tmp_path, line, f"  pieces: [{value!r}]")
    with pytest.raises(ConfigError, match=r"task\.pieces: durations must be in \[0\.001, 10000\] s"):
        load_config(path)
    assert DURATION_RANGE == (1e-3, 1e4)


@FAST
@given(sigma=st.floats(min_value=MAX_START_ERROR * 1.001, max_value=1e300))
def test_a_start_error_larger_than_a_homing_error_is_refused(tmp_path, sigma):
    path = tmp_path / "c.yaml"
    path.write_text(FORWARD + f"simulation:\n  start_error: [{sigma!r}, 0.0, 0.0, 0.0]\n")
    with pytest.raises(ConfigError, match=r"start_error: each sigma must be finite and in \[0, 1\]"):
        load_config(path)


@FAST
@given(
    factor=_OUTSIDE,
    column=st.integers(0, 1),
    model=st.sampled_from(["forward_parking", "unicycle_parking", "chained_perturbed", "trailer_bay"]),
)
def test_a_true_factor_outside_its_range_is_refused_naming_it_with_the_value_given(factor, column, model):
    plant = load_config(model).plant.plant()
    factors = np.ones(2)
    factors[column] = factor
    with pytest.raises(
        ValueError,
        match=rf"{plant.factor_names[column]}: must be a ratio in \[0.001, 1000\], got {re.escape(repr(factor))}",
    ):
        plant.with_true_factors(factors)
    assert FACTOR_RANGE[0] <= 1.0 <= FACTOR_RANGE[1] and LENGTH_RANGE[0] < LENGTH_RANGE[1]


def test_vector_env_true_factors_name_the_row():
    factors = np.ones((2, 2))
    factors[1, 0] = 1e-300
    with pytest.raises(ValueError, match=r"true_factors\[1\]: wheelbase_ratio: .*got 1e-300"):
        ChainedSteeringVectorEnv(2, config="forward_parking", true_factors=factors)


# class 9: wrappers and vector envs


@FAST
@given(
    scale=st.one_of(
        st.floats(min_value=MAX_SCALE * 1.0001, max_value=1e308), st.floats(max_value=0.0), st.just(math.nan)
    )
)
def test_residual_action_refuses_a_scale_outside_its_range(scale):
    with pytest.raises(ValueError, match=r"scale must be a number in \(0, 100\]"):
        ResidualAction(gym.make("ilc_steering/ChainedSteering-v0"), scale=scale)


def test_residual_action_passes_gymnasiums_check_env():
    from gymnasium.utils.env_checker import check_env

    env = ResidualAction(gym.make("ilc_steering/ChainedSteering-v0", config="forward_parking"), scale=0.5)
    check_env(env, skip_render_check=True)
    assert env.spec is not None and env.spec.additional_wrappers[-1].kwargs == {"scale": 0.5}


@FAST
@given(count=st.one_of(st.integers(MAX_ENVS + 1, 10**18), st.integers(max_value=0)))
def test_a_vector_env_refuses_a_count_beyond_its_bound_before_allocating(count):
    from ilc_steering.envs.cyclic_vector_env import CyclicSteeringVectorEnv

    for make in (ChainedSteeringVectorEnv, CyclicSteeringVectorEnv):
        with pytest.raises(ValueError, match=rf"num_envs must be an integer in \[1, {MAX_ENVS}\]"):
            make(count)


@settings(max_examples=10, deadline=None)
@given(seeds=st.lists(st.integers(0, 2**32 - 1), min_size=2, max_size=4))
def test_a_list_of_seeds_gives_each_env_what_a_single_env_of_that_seed_measures(seeds):
    n = len(seeds)
    vector = ChainedSteeringVectorEnv(n, config="forward_parking_noisy")
    vector.reset(seed=seeds)
    action = vector.nominal_model.solve().astype(np.float32)
    _, rewards, *_ = vector.step(np.tile(action, (n, 1)))
    for i, seed in enumerate(seeds):
        single = ChainedSteeringEnv(config="forward_parking_noisy")
        single.reset(seed=seed)
        _, reward, *_ = single.step(action)
        assert rewards[i] == pytest.approx(reward, rel=1e-12, abs=1e-15)
    with pytest.raises(ValueError, match="one seed per env"):
        vector.reset(seed=[*seeds, 1])


# class 10: the RL hyperparameter files

_BAD = {
    "learning_rate": st.one_of(
        st.floats(max_value=0.0), st.just("fast"), st.booleans(), st.floats(min_value=1.01, max_value=1e300)
    ),
    "batch_size": st.one_of(
        st.floats(min_value=0.5, max_value=1e6).filter(lambda v: v != int(v)), st.booleans(), st.integers(max_value=0)
    ),
    "n_timesteps": st.one_of(st.booleans(), st.integers(max_value=0), st.text(max_size=5)),
    "gamma": st.one_of(st.floats(min_value=1.0001, max_value=1e9), st.floats(max_value=-1e-9)),
    "eval_every": st.one_of(st.integers(max_value=0), st.floats(allow_nan=True)),
}


@FAST
@given(data=st.data(), key=st.sampled_from(sorted(_BAD)))
def test_an_rl_hyperparameter_of_the_wrong_type_or_range_is_refused_naming_file_and_key(data, key):
    from ilc_steering.agents.rl_settings import check_value

    value = data.draw(_BAD[key])
    where = f"configs/rl/ppo.yaml: nominal.default.{key}"
    with pytest.raises(ConfigError, match=rf"^{re.escape(where)}: must be"):
        check_value(key, value, where)


@pytest.mark.slow
@pytest.mark.extra("rl")
def test_the_packaged_hyperparameters_pass_and_a_bad_one_is_named_with_its_file():
    for algorithm in ("ppo", "sac", "td3", "crossq", "tqc"):
        for prior in ("nominal", "none"):
            assert hyperparameters(algorithm, "forward_parking", prior)["n_timesteps"] >= 1
    params = {**hyperparameters("ppo", "forward_parking"), "batch_size": 256.5}
    with pytest.raises(ConfigError, match=r"^configs/rl/ppo\.yaml: nominal\.default\.batch_size: must be an integer"):
        check_hyperparameters("ppo", params, "configs/rl/ppo.yaml: nominal.default")
    params = {**hyperparameters("ppo", "forward_parking"), "learning_rate": "3e-4"}
    assert check_hyperparameters("ppo", params, "x")["learning_rate"] == 3e-4  # YAML 1.1's text, the number


# class 12: small ones


@pytest.mark.parametrize("text", ["0.0_2", "1_0", "0_1.5"])
def test_a_yaml_number_with_an_underscore_is_refused_like_a_leading_zero(tmp_path, text):
    path = tmp_path / "c.yaml"
    path.write_text(FORWARD + f"simulation:\n  max_step: {text}\n")
    with pytest.raises(ConfigError, match=rf"max_step: '{text}' is ambiguous"):
        load_config(path)


def test_a_step_coarser_than_a_piece_is_refused(tmp_path):
    path = tmp_path / "c.yaml"
    path.write_text(
        FORWARD.replace("pieces: [5.0]", "pieces: [1.0, 0.5]").replace("v1_fixed: []", "v1_fixed: [0.1]")
        + "simulation:\n  max_step: 0.75\n"
    )
    with pytest.raises(ConfigError, match=r"simulation\.max_step: 0\.75 s is longer than the shortest piece"):
        load_config(path)


def test_the_docs_broyden_learner_survives_a_repeated_action_and_still_learns(monkeypatch):
    """The old example divided by ``|dc|^2 = 0`` once an action repeated (clipped to the box): NaN in
    ``J``, then ``LinAlgError`` (27 of 60 runs of 40 trials on three tasks, measured)."""
    from ilc_steering.agents import LearnerContext
    from ilc_steering.loop import run_trials

    monkeypatch.syspath_prepend(str(Path(__file__).resolve().parents[1] / "examples"))
    import my_learners

    for config, prior, seed in (("unicycle_parking", "none", 5), ("unicycle_parking", "none", 6)):
        env = gym.make("ilc_steering/ChainedSteering-v0", config=config)
        u = env.unwrapped
        context = LearnerContext(u.nominal_model, u.action_space, u.observation_space, seed=seed, prior=prior)
        run_trials(env, my_learners.make(context), trials=30, seed=seed)  # no LinAlgError
    env = gym.make("ilc_steering/ChainedSteering-v0", config="parallel_parking")
    u = env.unwrapped
    context = LearnerContext(u.nominal_model, u.action_space, u.observation_space, seed=0)
    rollout = run_trials(env, my_learners.make(context), trials=4, seed=0)
    assert rollout.infos[-1]["cartesian_error"] < 5e-4 < rollout.infos[0]["cartesian_error"]


def test_the_ranges_table_of_docs_trust_is_the_codes():
    from ilc_steering.core import checks
    from ilc_steering.core.grid import MAX_STEPS_PER_TRIAL

    text = (Path(__file__).resolve().parents[1] / "docs" / "trust.md").read_text()
    rows = {
        line.split("|")[-2].strip(" `"): line.split("|")[3].strip()
        for line in text.splitlines()
        if line.startswith("| ")
    }

    def shown(low: float, high: float) -> str:
        return f"[{low:g}, {high:g}]"

    assert rows["LENGTH_RANGE"] == shown(*checks.LENGTH_RANGE)
    assert rows["DURATION_RANGE"] == shown(*checks.DURATION_RANGE)
    assert rows["FACTOR_RANGE"] == shown(*checks.FACTOR_RANGE)
    assert rows["MAX_START_ERROR"] == shown(0, checks.MAX_START_ERROR)
    assert rows["MAX_NOISE"] == shown(0, checks.MAX_NOISE)
    assert rows["MAX_JITTER"] == shown(0, checks.MAX_JITTER)
    assert f"at most {MAX_STEPS_PER_TRIAL} steps" in rows["grid.MAX_STEPS_PER_TRIAL"]


@pytest.mark.slow
def test_a_valid_config_with_a_cost_runs_without_a_warning_from_scipys_files():
    """Section 7's null-space search meets ``inf`` outside its box; scipy's Nelder-Mead subtracted
    two of them and numpy warned from scipy's file (parallel_parking_servo with a cost, measured)."""
    import dataclasses
    import warnings

    from ilc_steering.runner import run_ilc

    data = dataclasses.asdict(load_config("parallel_parking_servo"))
    data["task"]["v2_terms"], data["task"]["action_bound"] = 5, None
    data["learning"]["cost"] = "path_length"
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        run_ilc(load_config(data), 4)


def test_the_backend_setting_pins_rl_runs_only_and_checks_the_variable(monkeypatch):
    from ilc_steering.agents.rl_settings import backend_setting

    monkeypatch.setenv(BACKEND_VARIABLE, "sb3")
    assert backend_setting(["ilc", "ppo"]) == {"rl_backend": "sb3"}
    assert backend_setting(["ilc", "least_squares"]) == {}
    monkeypatch.setenv(BACKEND_VARIABLE, "jax")
    with pytest.raises(ValueError, match=BACKEND_VARIABLE):
        backend_setting(["sac"])


def test_every_test_the_trust_page_names_for_a_case_exists():
    """docs/trust.md's table of issue 64's cases names a test per case: each is a test of its file."""
    import ast

    root = Path(__file__).resolve().parents[1]
    text = (root / "docs" / "trust.md").read_text()
    table = text[text.index("## Issue 64's cases") :]
    named = re.findall(r"`tests/(test_\w+\.py)::(test_\w+)`", table)
    assert len(named) >= 30
    for file, name in named:
        tree = ast.parse((root / "tests" / file).read_text())
        tests = {node.name for node in ast.walk(tree) if isinstance(node, ast.FunctionDef)}
        assert name in tests, f"docs/trust.md names tests/{file}::{name}, which is no test of that file"
