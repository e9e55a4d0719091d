"""``SegmentedSteering-v0``'s vector entry point against Gymnasium's SyncVectorEnv of scalar envs (issue 68,
item 2): bit for bit, step after step, the trials that halt, are refused or are measured with noise included."""

import doctest
from importlib import resources

import gymnasium as gym
import numpy as np
import pytest
import yaml
from gymnasium.utils.env_checker import data_equivalence
from gymnasium.vector import AutoresetMode

import ilc_steering  # noqa: F401  (registers the envs)
from ilc_steering.config import load_config
from ilc_steering.envs import segmented_vector_env
from ilc_steering.envs.segmented_vector_env import SegmentedSteeringVectorEnv

ENV_ID = "ilc_steering/SegmentedSteering-v0"
NAMES = ["obs", "rewards", "terminations", "truncations", "info"]


def overshooting():
    """segmented_parking with segment 1's frame 1.45 rad off the via point's axis, on a car unlike the
    nominal one: an overshoot of segment 0 ends past segment 1's chart (test_segmented's finding 3)."""
    data = yaml.safe_load((resources.files("ilc_steering.configs") / "segmented_parking.yaml").read_text())
    data["plant"].update(true_wheelbase=0.2, true_wheel_radius=0.02)
    data["task"]["segments"][1]["frame"] = 0.3 - 1.45
    return load_config(data)


def pair(num_envs, config, **kwargs):
    native = gym.make_vec(ENV_ID, num_envs=num_envs, vectorization_mode="vector_entry_point", config=config, **kwargs)
    sync = gym.make_vec(
        ENV_ID,
        num_envs=num_envs,
        vectorization_mode="sync",
        config=config,
        vector_kwargs={"autoreset_mode": AutoresetMode.SAME_STEP},
        **kwargs,
    )
    return native, sync


def mixed_actions(envs, rng):
    """One row per kind of trial: the nominal solution (both segments run), segment 0 overshooting
    (segment 1 would start off its chart: refused), segment 0 off its chart (segment 1 not run), the
    nominal perturbed, and actions across and past the box (clipped)."""
    views = envs.unwrapped.segment_views()
    n0 = views[0].action_space.shape[0]
    nominal = np.concatenate([view.nominal_model.solve() for view in views])
    overshoot, off_chart = nominal.copy(), nominal.copy()
    overshoot[1:n0] *= 1.6
    off_chart[:n0] = views[0].action_space.high * np.array([1, 1, 0, 0])
    high = envs.single_action_space.high.astype(np.float64)
    rows = [nominal, overshoot, off_chart, nominal * (1 + 0.2 * rng.standard_normal(nominal.size))]
    rows += list(rng.uniform(-1.5, 1.5, size=(envs.num_envs - len(rows), high.size)) * high)
    return np.array(rows)[rng.permutation(envs.num_envs)]


def run_both(native, sync, seed, steps=3):
    """Reset both with ``seed`` and step both ``steps`` times with the same actions; every output must
    be equal, bit for bit. Returns the native env's ``final_info`` of every step."""
    assert native.metadata["autoreset_mode"] == AutoresetMode.SAME_STEP
    assert native.action_space == sync.action_space and native.observation_space == sync.observation_space
    assert data_equivalence(native.reset(seed=seed), sync.reset(seed=seed), exact=True)
    rng = np.random.default_rng(0)
    finals = []
    for _ in range(steps):
        c = mixed_actions(native, rng)
        out, expected = native.step(c), sync.step(c)
        for name, x, y in zip(NAMES, out, expected):
            assert data_equivalence(x, y, exact=True), name
        assert out[2].all() and not out[3].any()  # every step is a whole trial, reset in the same step
        np.testing.assert_array_equal(out[0], native.reset(seed=None)[0])  # the next episode's task
        finals.append(out[4]["final_info"])
    return finals


def kinds(finals):
    """How many trials of the steps ran both segments, were refused, halted, clipped."""
    segments = [trial for final in finals for trial in final["segments"]]
    return {
        "both": sum(all(s["ran"] for s in trial) for trial in segments),
        "refused": sum("refused" in trial[1] for trial in segments),
        "halted": sum(not trial[1]["ran"] and "refused" not in trial[1] for trial in segments),
        "clipped": sum(int(final["clipped"].sum()) for final in finals),
    }


def test_the_vector_env_matches_the_sync_vector_env_bit_for_bit():
    finals = run_both(*pair(7, overshooting()), seed=3)
    found = kinds(finals)
    assert found["both"] >= 3 and found["refused"] >= 3 and found["halted"] >= 3 and found["clipped"] >= 3, found
    assert all(final["left_chart"].dtype == np.bool_ for final in finals)
    assert all(final["cartesian_error"].dtype == np.float64 for final in finals)


def test_with_noise_each_env_measures_what_its_own_scalar_env_would():
    """``reset(seed=[s_0, ...])``: env ``i`` draws its noise, segment by segment, from a stream seeded
    as the scalar env's ``reset(seed=s_i)`` (the sync env's ``reset(seed=list)``)."""
    native, sync = pair(6, "segmented_parking", measurement_noise=0.01)
    finals = run_both(native, sync, seed=list(range(20, 26)))
    final = finals[-1]
    assert not np.array_equal(final["cartesian_error"], final["true_cartesian_error"])  # the noise was drawn


def test_when_the_plant_refuses_a_batch_each_trial_is_run_alone(monkeypatch):
    """A ``ValueError`` from segment 1's batched run (a plant refusing one trial's segment) refuses that
    trial's segment only, as each scalar env refuses its own: the batch runs again trial by trial."""
    native, sync = pair(5, "segmented_parking")
    scenarios = [native.unwrapped._manoeuvre.segments[1], *(env.unwrapped._segments[1] for env in sync.envs)]
    views = native.unwrapped.segment_views()
    nominal = np.concatenate([view.nominal_model.solve() for view in views])
    n0 = views[0].action_space.shape[0]
    limit = 1.2 * abs(nominal[n0])  # segment 1's c11 [m]: a trial asking more is refused
    for scenario in scenarios:
        run = scenario.run

        def refusing(c, *args, run=run, **kwargs):
            if np.any(np.abs(c[:, 0]) > limit):
                raise ValueError("segment too fast for this plant")
            return run(c, *args, **kwargs)

        monkeypatch.setattr(scenario, "run", refusing)
    c = np.tile(nominal, (5, 1))
    c[[1, 3], n0] *= 1.3
    assert data_equivalence(native.reset(seed=0), sync.reset(seed=0), exact=True)
    out, expected = native.step(c), sync.step(c)
    for name, x, y in zip(NAMES, out, expected):
        assert data_equivalence(x, y, exact=True), name
    final = out[4]["final_info"]
    assert [trial[1]["ran"] for trial in final["segments"]] == [True, False, True, False, True]
    assert "segment 1 refused: ValueError: segment too fast" in final["segments"][3][1]["refused"]
    assert final["left_chart"].tolist() == [False, True, False, True, False]


def test_bad_input_is_named():
    envs = SegmentedSteeringVectorEnv(3, "segmented_parking")
    envs.reset(seed=0)
    size = envs.single_action_space.shape[0]
    with pytest.raises(ValueError, match=rf"must have shape \(3, {size}\)"):
        envs.step(np.zeros(size))
    with pytest.raises(ValueError, match="takes none"):
        envs.reset(options={"start": [0, 0, 0, 0]})
    with pytest.raises(ValueError, match="needs task.segments"):
        SegmentedSteeringVectorEnv(2, "forward_parking")
    with pytest.raises(ValueError, match="num_envs"):
        SegmentedSteeringVectorEnv(0, "segmented_parking")


def test_docstring_example_runs():
    results = doctest.testmod(segmented_vector_env, raise_on_error=False)
    assert results.attempted > 0 and results.failed == 0
