"""The MuJoCo car as an external plant: it repeats itself, stays near the kinematic car, scatters
within its band when told to, and is driven once per counted trial."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest

pytest.importorskip("mujoco", reason='the [mujoco] extra: pip install "ilc-steering[mujoco]"')

from ilc_steering.config import load_config
from ilc_steering.core.external import is_external
from ilc_steering.core.robots import config_class
from ilc_steering.core.robots.car import CarModel, CarPlant
from ilc_steering.core.simulate import simulate
from ilc_steering.envs import mujoco_car
from ilc_steering.envs.scenario import Scenario
from ilc_steering.runner import run_ilc

CONFIGS = Path(__file__).resolve().parents[1] / "configs"
FORWARD = CONFIGS / "mujoco_forward_parking.yaml"
SCATTER = CONFIGS / "mujoco_forward_parking_scatter.yaml"


def nominal_trial(config: Path, repeats: int = 1, **keys: Any) -> tuple[Scenario, np.ndarray, np.ndarray]:
    """The scenario of ``config`` (its plant's keys replaced by ``keys``), the nominal solution and
    the final configurations of ``repeats`` trials of it on a fresh plant."""
    loaded = load_config(config)
    if keys:
        loaded = replace(loaded, plant=replace(loaded.plant, **keys))
    scenario = Scenario.from_config(loaded)
    c = scenario.nominal.solve()
    final = np.concatenate([scenario.run(c[None]).final for _ in range(repeats)])
    return scenario, c, final


def test_it_is_a_robot_of_the_entry_point_group() -> None:
    """Registered through the package's entry point, not the core's table; an external plant."""
    assert config_class("mujoco_car") is mujoco_car.MujocoCarConfig
    plant = load_config(FORWARD).plant.plant()
    assert is_external(plant) and plant.steering_limit == 1.2
    with pytest.raises(ValueError, match="model family"):
        plant.family_names()


@pytest.mark.parametrize("config", ["mujoco_forward_parking", "mujoco_forward_parking_scatter"])
def test_gymnasiums_check_env_passes(config: str) -> None:
    """Gymnasium's checks, rendering and step determinism included: with scatter too, the same env
    seed gives the same draws (the env hands the plant its seed)."""
    import gymnasium as gym
    from gymnasium.utils.env_checker import check_env

    import ilc_steering  # noqa: F401  (registers the envs)

    env = gym.make("ilc_steering/ChainedSteering-v0", config=config, render_mode="rgb_array")
    check_env(env.unwrapped, skip_render_check=False)


def test_the_scatter_follows_the_env_s_seed() -> None:
    """The friction draws of ``reset(seed=s)``: the same for the same ``s`` (on a fresh env, and on
    the same env reset again), others for another seed, and in each trial's log."""
    import gymnasium as gym

    import ilc_steering  # noqa: F401  (registers the envs)

    def draws(env: Any, seed: int) -> list[Any]:
        env.reset(seed=seed)
        c = env.unwrapped.nominal_model.solve()
        return [env.step(c)[4]["plant"] for _ in range(2)]

    env = gym.make("ilc_steering/ChainedSteering-v0", config="mujoco_forward_parking_scatter")
    first = draws(env, 3)
    assert first[0]["env_seed"] == 3 and first[0]["friction"] != first[1]["friction"]
    assert draws(env, 3) == first
    assert draws(gym.make("ilc_steering/ChainedSteering-v0", config="mujoco_forward_parking_scatter"), 3) == first
    other = draws(env, 4)
    assert all(a["friction"][i] != b["friction"][i] for a, b in zip(first, other) for i in range(4))


def test_bad_keys_are_refused_by_name() -> None:
    keys = {"model": "mujoco_car", "wheelbase": 0.2, "wheel_radius": 0.02}
    with pytest.raises(ValueError, match="control_period"):
        mujoco_car.MujocoCarConfig(**keys, control_period=0.0105)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="contact_time"):
        mujoco_car.MujocoCarConfig(**keys, contact_time=0.001)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="friction_spread"):
        mujoco_car.MujocoCarConfig(**keys, friction_spread=-0.1)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match=r"steering_limit: .* inner front wheel inside its hinge's 1.5 rad stop"):
        mujoco_car.MujocoCarConfig(**keys, steering_limit=1.3)  # type: ignore[arg-type]  # inner wheel past 90°


def test_ackermann_round_trip() -> None:
    for phi in (-1.2, -0.4, 0.0, 0.3, 1.2):
        left, right = mujoco_car.ackermann(phi, 0.2, 0.12)
        inner, outer = (left, right) if phi >= 0 else (right, left)  # the wheel nearer the turn's centre
        assert abs(inner) >= abs(phi) >= abs(outer)
        assert mujoco_car.bicycle_angle(left, right, 0.2, 0.12) == pytest.approx(phi, abs=1e-12)


def test_without_scatter_it_repeats_bit_for_bit() -> None:
    _, _, final = nominal_trial(FORWARD, repeats=2)
    assert np.array_equal(final[0], final[1])


def test_with_grip_it_ends_near_the_kinematic_car() -> None:
    """On stiff, grippy contacts (friction 1, no slip in the 0.4 m/s² turns) the nominal solution
    ends where the kinematic car of eqs. 3-5 with the same geometry ends (the goal, to 1e-12),
    within 2.5 cm and 0.02 rad: what remains is the start's spin-up, the tyres' sinking and creep,
    and the steering servo's lag. The forward task measures -6.5 mm, -16.8 mm, -0.012 rad."""
    scenario, c, final = nominal_trial(FORWARD)
    model = CarModel(0.2, 0.02)
    kinematic = simulate(CarPlant(model, model), scenario.nominal.profile, scenario.x_start[None], c[None], 0.01)
    error = final[0] - kinematic.final[0]
    assert np.hypot(error[0], error[1]) < 0.025 and abs(error[2]) < 0.02 and abs(error[3]) < 0.02
    assert np.hypot(error[0], error[1]) > 1e-3  # and it is not the kinematic car


def test_the_scatter_is_a_few_millimetres() -> None:
    """12 repeats of the same commands on the scatter config (friction 0.4, spread 0.2, seed 0):
    the std of the final x, y lies in [0.5, 6] mm, of theta in [0.3, 6] mrad (measured: 1.3, 1.5 mm,
    1.0 mrad; 20 repeats of seed 1: 2.1, 2.5 mm, 2.0 mrad); the same seed replays the same draws."""
    _, _, final = nominal_trial(SCATTER, repeats=12)
    std = final.std(axis=0)
    assert 5e-4 <= std[0] <= 6e-3 and 5e-4 <= std[1] <= 6e-3 and 3e-4 <= std[2] <= 6e-3, std
    _, _, again = nominal_trial(SCATTER, repeats=2)
    assert np.array_equal(again, final[:2])
    _, _, other = nominal_trial(SCATTER, repeats=1, seed=1)
    assert not np.array_equal(other[0], final[0])


def test_driven_once_per_counted_trial(monkeypatch: pytest.MonkeyPatch) -> None:
    """A run of 3 trials runs 3 MuJoCo trials of 500 periods of 10 steps, and no more."""
    import mujoco

    calls: list[int] = []
    step = mujoco.mj_step

    def counted(model: Any, data: Any, nstep: int = 1) -> None:
        calls.append(nstep)
        step(model, data, nstep=nstep)

    monkeypatch.setattr(mujoco, "mj_step", counted)
    trials: list[int] = []
    original = mujoco_car.MujocoCarPlant.trial

    def counted_trial(self: Any, *args: Any) -> Any:
        trials.append(1)
        return original(self, *args)

    monkeypatch.setattr(mujoco_car.MujocoCarPlant, "trial", counted_trial)
    result = run_ilc(FORWARD, trials=3, learner="ilc")
    assert len(result.trials) == 3 and len(trials) == 3
    settle = round(0.5 / 0.001)  # the plant settles on its tyres once, when first used: one call, no trial
    assert calls[0] == settle
    assert sum(calls) - settle == 3 * 5000 and calls.count(10) == 3 * 500


@pytest.mark.slow
def test_robust_ilc_stays_within_a_centimetre_on_the_scatter() -> None:
    """Each trial's friction is new: the learner cannot learn it away, but holds 1 cm / 0.01 rad
    from trial 6 at the latest (issue 48's bound) over the last five of 15 trials (run's seed 1:
    inside at trials 2-4, out once at 12.5 mm at trial 5, inside again from trial 6)."""
    result = run_ilc(SCATTER, trials=15, learner="robust_ilc")
    errors = [(r.cartesian_error, r.orientation_error) for r in result.trials]
    assert result.converged_at is not None and result.converged_at <= 6, errors
    assert all(e[0] <= 0.01 and e[1] <= 0.01 for e in errors[-5:]), errors
    assert max(e[0] for e in errors[-5:]) > 1e-3  # and the scatter is there


@pytest.mark.slow
def test_robust_ilc_reaches_a_centimetre_within_three_trials() -> None:
    result = run_ilc(FORWARD, trials=5, learner="robust_ilc")
    errors = [(r.cartesian_error, r.orientation_error) for r in result.trials]
    assert result.converged_at is not None and result.converged_at <= 3, errors
    assert all(e[0] <= 0.01 and e[1] <= 0.01 for e in errors[2:]), errors
