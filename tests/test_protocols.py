"""Contract tests of the three protocols: Plant, InputProfile and Learner.

A new plant, profile or learner passes these or is not one. Each check is a number that could be
wrong: shapes, a closed form, determinism under a seed.
"""

import dataclasses

import gymnasium as gym
import numpy as np
import pytest

import ilc_steering  # noqa: F401  (registers the envs)
from ilc_steering.agents import CyclicILCAgent, Learner, LearnerContext
from ilc_steering.agents.registry import REGISTRY
from ilc_steering.config import load_config, packaged_configs
from ilc_steering.core import robots
from ilc_steering.core.external import is_external
from ilc_steering.core.integrate import OK
from ilc_steering.core.plants import Kernel, Plant, PlantKind
from ilc_steering.core.profiles import InputProfile, PiecewiseProfile
from ilc_steering.core.robots.car import rotate
from ilc_steering.core.robots.chained import ChainedPlant
from ilc_steering.core.simulate import simulate
from ilc_steering.core.trapezoid import TrapezoidProfile
from ilc_steering.loop import run_trials

CONFIGS = {name: load_config(name) for name in packaged_configs()}


def plants_of_every_kind():
    out = {}
    for config in CONFIGS.values():
        out.setdefault(config.plant.model, (config.plant.plant(), config))
    assert set(out) == set(robots.names()), "every registered robot needs a packaged config"
    return out


def servo_car():
    """The car with every unmodeled servo perturbation on: the lab kernel, its play and encoders off."""
    config = CONFIGS["forward_parking_saturated"]
    plant = dataclasses.replace(config.plant.plant(), steering_offset=0.02, steering_lag=0.05, speed_lag=0.1)
    return plant, config


def lab_car():
    """Section 5's lab robot: dead reckoning, play and the servos, the twelve-state kernel."""
    config = CONFIGS["experiment_forward"]
    return config.plant.plant(), config


@pytest.mark.parametrize("model", [*robots.names(), "car with servos", "car of the lab"])
def test_plant_contract(model):
    special = {"car with servos": servo_car, "car of the lab": lab_car}
    plant, config = special[model]() if model in special else plants_of_every_kind()[model]
    model = model.split()[0]
    assert isinstance(plant, Plant) and isinstance(plant, robots.config_class(model).plant_class)
    assert isinstance(plant.kind, PlantKind) and plant.kind.name == model
    start = np.array(config.points()[0][1])
    q0 = rotate(start, config.frame()) if plant.kind.has_pose else start
    plant.check_configuration(q0)
    with pytest.raises(ValueError):
        plant.check_configuration(np.full_like(q0, np.nan))
    x0 = plant.initial_state(q0)
    assert x0.shape == (plant.state_dim,)
    np.testing.assert_array_equal(plant.configuration(x0), q0)
    assert plant.configuration(np.stack([x0, x0])).shape == (2, q0.size)
    if is_external(plant):  # someone else's code runs its trials (tests/test_highway.py): no kernel
        with pytest.raises(ValueError, match="someone else's code"):
            plant.kernel()
        return
    field, params = plant.kernel()
    assert isinstance(field, Kernel) and params.dtype == np.float64 and params.shape == (len(field.layout.params),)
    profile = config.legs()[0][1].profile()
    c = np.zeros((1, profile.num_coefficients))
    c[0, 0] = 0.1
    trials = simulate(plant, profile, x0[None], c)
    assert trials.status[0] == OK and trials.final.shape == (1, plant.state_dim) and np.all(np.isfinite(trials.final))
    assert len(plant.kind.coordinate_labels(q0.size)) == q0.size


def profiles():
    rng = np.random.default_rng(3)
    yield from {config.legs()[0][1].profile() for config in CONFIGS.values()}
    yield PiecewiseProfile((1.0, 2.0, 1.5), (0.7, -0.4), 4)
    yield PiecewiseProfile(tuple(rng.uniform(0.5, 2.0, size=2)), (rng.normal(),), 6)
    yield TrapezoidProfile((2.0, 1.5, 3.0), (0.7, -0.4), 4, 0.3)


@pytest.mark.parametrize(
    "profile", list(profiles()), ids=lambda p: f"{type(p).__name__}-p{len(p.durations)}q{p.v2_terms}"
)
def test_input_profile_contract(profile):
    assert isinstance(profile, InputProfile)
    rng = np.random.default_rng(0)
    c = rng.normal(size=(3, profile.num_coefficients))
    assert profile.num_coefficients == 1 + profile.v2_terms
    np.testing.assert_allclose(sum(profile.spans), sum(profile.durations), rtol=1e-15)
    np.testing.assert_allclose(np.diff(profile.breakpoints), profile.spans, rtol=1e-12)
    # polynomials and evaluate describe the same inputs
    v1, v2 = profile.polynomials(c)
    for s, (t0, span) in enumerate(zip(profile.breakpoints[:-1], profile.spans)):
        tau = np.array([0.1, 0.5, 0.9]) * span
        e1, e2 = profile.evaluate(c[1], t0 + tau)
        np.testing.assert_allclose(np.polyval(v1[1, s, ::-1], tau), e1, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(np.polyval(v2[1, s, ::-1], tau), e2, rtol=1e-10, atol=1e-10)
    # what a profile hands out or keeps cannot be written to change its next trials (a user's plant
    # gets the profile; before, a profile of several pieces kept a writeable matrix of v2)
    held = [a for value in vars(profile).values() for a in (value if isinstance(value, tuple) else (value,))]
    for array in [profile.bases(), profile.breakpoints, *held]:
        if isinstance(array, np.ndarray) and array.flags.writeable:
            array[...] = 0.0
    for again, first in zip(profile.polynomials(c), (v1, v2)):
        np.testing.assert_array_equal(again, first)
    # z1 (eq. 12) and z_b (eqs. 24-25) on the unperturbed chained form, as simulated
    n = 1 + min(profile.v2_terms, 4)
    z0 = rng.normal(size=(3, n))
    final = simulate(ChainedPlant(n), profile, z0, c).final
    for b in range(3):
        z1 = z0[b, 0] + profile.learned_area * c[b, 0] + profile.fixed_displacement
        assert final[b, 0] == pytest.approx(z1, abs=1e-12)
        V, W = profile.transition(c[b, 0], n)
        np.testing.assert_allclose(final[b, 1:], V @ z0[b, 1:] + W @ c[b, 1:], rtol=1e-9, atol=1e-9)


def context(name="forward_parking", seed=0):
    env = gym.make("ilc_steering/ChainedSteering-v0", config=name)
    unwrapped = env.unwrapped
    return env, LearnerContext(unwrapped.nominal_model, unwrapped.action_space, unwrapped.observation_space, seed)


EXTRA_OF = {"stable_baselines3": "rl", "sb3_contrib": "rl", "cma": "rl", "botorch": "bo"}
"""The extra of pyproject.toml that installs a learner's package (tests/conftest.py's EXTRAS, turned round)."""


def extras(spec):
    """The extras that ``spec``'s packages come with (none: scipy's, or the library's own)."""
    packages = [spec.package, spec.rl.sb3_module if spec.rl else None]
    return tuple(dict.fromkeys(EXTRA_OF[p] for p in packages if p in EXTRA_OF))


def learner_params():
    """Every id of the registry, each marked with the extras it needs; in the slow tier the RL ones
    after the first (each trains a network) and those of costly trials (bayes_opt: a GP a trial)."""
    params, first_rl = [], True
    for method, spec in REGISTRY.items():
        marks = [pytest.mark.extra(*extras(spec))] if extras(spec) else []
        if (spec.family == "RL" and not first_rl) or spec.trial_seconds >= 0.1:
            marks.append(pytest.mark.slow)
        first_rl = first_rl and spec.family != "RL"
        params.append(pytest.param(method, marks=marks))
    return params


@pytest.mark.parametrize("method", learner_params())
def test_learner_contract(method):
    env, _ = context()
    learner = REGISTRY[method].make(LearnerContext.from_env(env, seed=0), 12)
    assert isinstance(learner, Learner)
    first = run_trials(env, learner, 6)
    assert len(first) == 6
    for info in first.infos:
        assert info["action"].shape == env.action_space.shape and np.all(np.isfinite(info["action"]))
    learner.reset()  # forget: the same seed gives the same trials again
    again = run_trials(env, learner, 6)
    for a, b in zip(first.infos, again.infos):
        np.testing.assert_array_equal(a["action"], b["action"])


def test_the_cyclic_learner_meets_the_protocol():
    env = gym.make("ilc_steering/CyclicSteering-v0", config="cyclic_home_goal", cycles=2)
    learner = CyclicILCAgent(env.unwrapped.nominal_models)
    assert isinstance(learner, Learner)
    rollout = run_trials(env, learner, 4)
    assert [info["waypoint"] for info in rollout.infos] == [1, 2, 1, 2]
    assert rollout.infos[-1]["cartesian_error"] < rollout.infos[1]["cartesian_error"]
