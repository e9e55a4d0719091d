"""The baselines of issue 28: CrossQ and TQC, SBX beside SB3, bayes_opt and noisy_least_squares.

SBX, sb3-contrib and BoTorch are installed by ``.ci/run`` (the ``rl-jax`` and ``bo`` extras): a test
marked with the extra it needs is skipped where that extra is missing, and fails in CI
(``tests/conftest.py``).
"""

from __future__ import annotations

import math
import sys
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

from ilc_steering.agents import bayes_opt as bo
from ilc_steering.agents import registry, rl, rl_settings
from ilc_steering.agents.base import LearnerContext
from ilc_steering.compare.args import Args
from ilc_steering.compare.cells import ENV_ID, measure, run_cell
from ilc_steering.compare.command import BLACKBOX, RL
from ilc_steering.envs.steering_env import ChainedSteeringEnv
from ilc_steering.errors import ConfigError


def context_of(scenario: str, seed: int = 0) -> tuple[gym.Env[Any, Any], LearnerContext]:
    env = gym.make(ENV_ID, config=scenario)
    u: Any = env.unwrapped
    return env, LearnerContext(u.nominal_model, u.action_space, u.observation_space, seed)


@pytest.fixture
def step_counter(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    """Counts every ``ChainedSteeringEnv.step``: every trial the env runs."""
    calls = [0]
    step = ChainedSteeringEnv.step

    def counted(self: ChainedSteeringEnv, action: Any) -> Any:
        calls[0] += 1
        return step(self, action)

    monkeypatch.setattr(ChainedSteeringEnv, "step", counted)
    return calls


@pytest.mark.parametrize(
    "method",
    [
        pytest.param("crossq", marks=pytest.mark.extra("rl", "rl-jax")),
        pytest.param("tqc", marks=pytest.mark.extra("rl", "rl-jax")),
        pytest.param("bayes_opt", marks=pytest.mark.extra("bo")),
        "noisy_least_squares",
    ],
)
@pytest.mark.slow  # RL and BoTorch trainings
def test_new_method_runs_in_compare_and_counts_every_env_step(method: str, step_counter: list[int]) -> None:
    assert method in RL + BLACKBOX
    args = Args(rl_trials=25, blackbox_trials=25)
    cell = run_cell(args, "nominal", method, "forward_parking", 0)
    assert cell["trials"] == cell["budget"] == 25
    assert step_counter[0] == 25  # probes, initial designs, deterministic trials: all counted
    assert cell["trials_to"]["10cm"] == 1  # the first trial is the nominal solution
    package = registry.lookup(method).package or "sbx-rl"  # SBX is installed: it runs the RL methods
    assert cell["implementation"].split()[0] == package


@pytest.mark.parametrize("backend", rl_settings.RL_BACKENDS)
@pytest.mark.slow  # RL trainings
@pytest.mark.extra("rl", "rl-jax")
def test_rl_cell_says_which_implementation_made_it(backend: str, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(rl_settings.BACKEND_VARIABLE, backend)
    cell = run_cell(Args(rl_trials=3), "nominal", "td3", "forward_parking", 0)
    expected = "sbx-rl" if backend == "sbx" else "stable-baselines3"
    assert cell["implementation"].split()[0] == expected


@pytest.mark.slow  # imports JAX and SBX: about 10 s
@pytest.mark.extra("rl", "rl-jax")
def test_sbx_is_the_default_backend_where_installed(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv(rl_settings.BACKEND_VARIABLE, raising=False)
    assert rl_settings.rl_backend() == "sbx"
    assert rl_settings.implementation("crossq", "sb3").startswith("sb3-contrib ")


@pytest.mark.parametrize(
    ("backend", "package", "extra"), [("sb3", "stable_baselines3", "rl"), ("sbx", "sbx", "rl-jax")]
)
def test_an_rl_method_without_its_package_names_the_extra_to_install(
    backend: str, package: str, extra: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setitem(sys.modules, package, None)  # as if it were not installed: importing it fails
    with pytest.raises(ValueError, match=rf'^ppo needs {package}: pip install "ilc-steering\[{extra}\]"$'):
        rl.algorithm_class("ppo", backend)


def test_bad_backend_is_a_one_line_error(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(rl_settings.BACKEND_VARIABLE, "jax")
    with pytest.raises(ValueError, match=r"ILC_STEERING_RL_BACKEND='jax': choose one of") as caught:
        rl_settings.rl_backend()
    assert "\n" not in str(caught.value)


@pytest.mark.extra("rl")
@pytest.mark.slow  # over 2.5 s: the README's test command stays under 5 min
def test_a_key_only_one_backend_knows_is_refused() -> None:
    params = {**rl_settings.hyperparameters("sac", "forward_parking"), "qf_learning_rate": 1e-3}  # SBX only
    with pytest.raises(ConfigError, match=r"here\.qf_learning_rate: unknown key for SAC \(stable-baselines3 "):
        rl_settings.check_hyperparameters("sac", params, "here")
    kwargs = {**rl_settings.hyperparameters("crossq", "forward_parking"), "policy_kwargs": {"renorm_warmup": 5}}
    with pytest.raises(ConfigError, match=r"here\.policy_kwargs\.renorm_warmup: unknown key"):
        rl_settings.check_hyperparameters("crossq", kwargs, "here")


@pytest.mark.parametrize("algorithm", [spec.id for spec in registry.REGISTRY.values() if spec.family == "RL"])
@pytest.mark.slow  # JAX and torch compile a network each
@pytest.mark.extra("rl", "rl-jax")
def test_sbx_and_sb3_act_in_the_same_units(algorithm: str) -> None:
    """Same hyperparameters: the same [-1, 1] action box, and the same first deterministic trial,
    the box's centre (start_at_centre), so the same physical coefficients c = c0."""
    firsts = {}
    for backend in rl_settings.RL_BACKENDS:
        env, context = context_of("forward_parking")
        params = rl_settings.hyperparameters(algorithm, "forward_parking")
        from ilc_steering.boxes import SearchBox

        box = SearchBox(env, *context.search_box())
        model = rl.build(algorithm, box, params, 0, 100, backend=backend)
        assert model.action_space == box.action_space == gym.spaces.Box(-1, 1, (4,), np.float32)
        action, _ = model.predict(np.zeros(box.observation_space.shape, np.float32), deterministic=True)
        firsts[backend] = box.action(action)
    np.testing.assert_allclose(
        firsts["sbx"], context.first_action(), rtol=0, atol=1e-6 * np.abs(context.first_action()).max()
    )
    np.testing.assert_allclose(firsts["sb3"], firsts["sbx"], rtol=1e-6)


@pytest.mark.extra("rl")
def test_sb3_path_gives_the_callers_torch_threads_back() -> None:
    import torch

    before = torch.get_num_threads()
    torch.set_num_threads(2)
    try:
        env, context = context_of("forward_parking")
        rl.train(
            "td3",
            gym.wrappers.RescaleAction(env, -1.0, 1.0),
            rl_settings.hyperparameters("td3", "forward_parking"),
            0,
            2,
            backend="sb3",
        )
        assert torch.get_num_threads() == 2
    finally:
        torch.set_num_threads(before)


class Quadratic(gym.Env[Any, Any]):
    """A smooth one-trial task in search units: cost ``||x - x*||^2`` + 1e-6."""

    def __init__(self, optimum: np.ndarray) -> None:
        self.optimum = optimum
        self.action_space = gym.spaces.Box(-1, 1, optimum.shape, np.float32)
        self.observation_space = gym.spaces.Box(0, 1, (1,), np.float32)
        self.costs: list[float] = []

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> Any:
        return np.zeros(1, np.float32), {}

    def step(self, action: Any) -> Any:
        cost = float(np.sum((np.asarray(action) - self.optimum) ** 2)) + 1e-6
        self.costs.append(cost)
        if len(self.costs) == 40:
            raise StopIteration
        return np.zeros(1, np.float32), -cost, True, False, {}


@pytest.mark.slow  # a GP per trial
@pytest.mark.extra("bo")
def test_bayes_opt_improves_on_its_first_trials_on_a_smooth_task() -> None:
    _, context = context_of("forward_parking")
    task = Quadratic(np.array([0.4, -0.3, 0.2, 0.5]))
    with pytest.raises(StopIteration):
        bo.bayes_opt(task, context)
    design = 1 + 2 * 4  # the start and 2 d Sobol points
    first = min(task.costs[:design])
    assert min(task.costs) < first / 10, (first, min(task.costs))


def test_noisy_least_squares_reaches_the_noisy_tolerance_where_least_squares_does_not() -> None:
    from ilc_steering.agents import blackbox

    reached = {}
    for method in ("least_squares", "noisy_least_squares"):
        env, context = context_of("forward_parking_noisy", seed=0)
        result = measure(env, blackbox.make_learner(getattr(blackbox, method), context), 300, 0)
        reached[method] = result["trials_to"]["0.5mm"]
    assert reached["least_squares"] is None
    assert reached["noisy_least_squares"] is not None and reached["noisy_least_squares"] <= 300


def test_noisy_least_squares_bad_settings_are_one_line_errors() -> None:
    from ilc_steering.agents import blackbox

    env, context = context_of("forward_parking")
    with pytest.raises(ValueError, match=r"probe > 0, repeats >= 1"):
        blackbox.noisy_least_squares(env, context, probe=-1.0)


def test_bayes_opt_budget_is_its_own() -> None:
    from ilc_steering.compare.cells import budget

    assert (
        budget(Args(), "nominal", "bayes_opt", "forward_parking")
        == registry.lookup("bayes_opt").max_trials
        < Args().blackbox_trials
    )
    assert budget(Args(blackbox_trials=40), "nominal", "bayes_opt", "forward_parking") == 40
    assert math.isfinite(bo.COST_FLOOR)
