"""Manoeuvres of several segments in one trial (issue 50, item 1): the config, the env, the learners.

Each segment is the one-trial task from its waypoint to the next, run from where the last segment
really ended; the tests hold it to the one-trial task it is, and to the closed form of the nominal
solution (section 2.2: exact on the nominal plant, whatever the waypoints).
"""

import copy
import doctest
from importlib import resources

import gymnasium as gym
import numpy as np
import pytest
import yaml

import ilc_steering  # noqa: F401  (registers the envs)
from ilc_steering.agents.base import LearnerContext
from ilc_steering.agents.registry import lookup
from ilc_steering.cli import main
from ilc_steering.config import load_config
from ilc_steering.config.loading import packaged_configs
from ilc_steering.envs import manoeuvre, segmented_env
from ilc_steering.errors import ConfigError
from ilc_steering.loop import run_trials
from ilc_steering.runner import run_ilc
from ilc_steering.segmented import segmented_learner

ENV_ID = "ilc_steering/SegmentedSteering-v0"


def packaged():
    assert "segmented_parking" in packaged_configs()
    return yaml.safe_load((resources.files("ilc_steering.configs") / "segmented_parking.yaml").read_text())


def test_doctest():
    assert doctest.testmod(segmented_env, raise_on_error=True).attempted > 0


def test_config_refusals_name_the_key():
    data = packaged()
    data["task"]["segments"][1]["direction"] = "forward"
    with pytest.raises(ConfigError, match=r"task\.segments\[1\]\.direction: forward disagrees"):
        load_config(data)
    data = packaged()
    data["task"]["segments"] = data["task"]["segments"][:1]
    with pytest.raises(ConfigError, match=r"task\.segments: needs one entry per segment, len\(via\) \+ 1 = 2, got 1"):
        load_config(data)
    data = packaged()
    data["task"]["segments"][0]["v2_terms"] = 2  # a one-trial rule, checked for the segment
    with pytest.raises(ConfigError, match=r"task\.segments\[0\]\.v2_terms: needs q >= n - 1 = 3"):
        load_config(data)
    data = packaged()
    data["task"]["segments"][0]["wheel"] = 1
    with pytest.raises(ConfigError, match="wheel"):
        load_config(data)


def test_a_via_points_fault_names_its_own_key():
    """Finding 8 of the review: a bad via point is named ``task.via[0]`` (it was named
    ``task.segments[0].goal``, a key the file does not have), in the frame of the segment that met it."""
    data = packaged()
    data["task"]["via"][0][3] = 1.6
    with pytest.raises(ConfigError, match=r"task\.via\[0\] \(in task\.segments\[0\]'s frame\): phi = 1\.6 rad"):
        load_config(data)
    data = packaged()
    data["task"]["segments"][1]["frame"] = 2.0  # the file's frame is named beside the point it puts off the chart
    match = r"task\.segments\[1\]\.frame: 2\.0 rad puts task\.via\[0\] \(in task\.segments\[1\]'s frame\) at a heading"
    with pytest.raises(ConfigError, match=match + r" of -1\.7"):
        load_config(data)


def test_a_segments_direction_is_kept():
    """Finding 7 of the review: ``direction`` is the learned piece's, and the env keeps ``c11`` to
    its sign (segment 0 forward: ``[0, b]``; segment 1 reverse: ``[-b, 0]``; it was a label only); a
    learner that asks for the other sign is clipped to 0, ``clipped``."""
    env = gym.make(ENV_ID, config="segmented_parking")
    env.reset(seed=0)
    views = env.unwrapped.segment_views()
    n0 = views[0].action_space.shape[0]
    box = env.action_space
    assert box.low[0] == 0 < box.high[0] and box.low[n0] < 0 == box.high[n0]
    c = [view.nominal_model.solve() for view in views]
    c[1][0] = -c[1][0]
    _, _, _, _, info = env.step(np.concatenate(c))
    assert info["segments"][1]["action"][0] == 0 and info["segments"][1]["clipped"]
    assert info["segments"][0]["action"][0] > 0 and not info["segments"][0]["clipped"]


def test_each_segment_is_its_one_trial_task(monkeypatch):
    """Segment 0 of the manoeuvre, learned by the paper's law, is trial for trial bit for bit the
    one-trial task from the start to the via point: nothing of the later segments leaks into it.
    Each trial drives each segment once: the plant runs as often as the segments run."""
    config = load_config("segmented_parking")
    spec = lookup("ilc_paper")
    env = gym.make(ENV_ID, config=config)
    runs = []
    for k, scenario in enumerate(env.unwrapped._segments):
        run = scenario.run
        monkeypatch.setattr(scenario, "run", lambda *a, k=k, run=run, **kw: runs.append(k) or run(*a, **kw))
    learner = segmented_learner(lambda context: spec.make(context, 6), env.unwrapped.segment_views(), seed=1)
    rollout = run_trials(env, learner, 6, seed=1)
    alone = gym.make("ilc_steering/ChainedSteering-v0", config=config.segment_configs()[0])
    one = run_trials(alone, spec.make(LearnerContext.from_env(alone, seed=1), 6), 6, seed=1)
    for mine, its in zip(rollout.infos, one.infos):
        np.testing.assert_array_equal(mine["segments"][0]["action"], its["action"])
        np.testing.assert_array_equal(mine["segments"][0]["q_final"], its["q_final"])
    assert runs == [k for info in rollout.infos for k, segment in enumerate(info["segments"]) if segment["ran"]]
    assert runs.count(0) == 6


def test_nominal_plant_reaches_every_waypoint_in_one_trial():
    """Closed form (section 2.2): on a car whose true geometry is the nominal one, the nominal solution
    of each segment from its waypoint reaches the next one exactly, through a forward and a reverse
    segment in different charts; and a trial's errors are the worst over its waypoints."""
    data = packaged()
    data["plant"].update(true_wheelbase=0.2, true_wheel_radius=0.02)
    data["task"]["via"] = [[0.5, 0.3, 0.9, 0.0]]
    data["task"]["segments"][1]["frame"] = 0.7
    config = load_config(data)
    env = gym.make(ENV_ID, config=config)
    env.reset(seed=0)
    views = env.unwrapped.segment_views()
    assert config.segment_configs()[0].frame() != config.segment_configs()[1].frame()
    _, _, _, _, info = env.step(np.concatenate([view.nominal_model.solve() for view in views]))
    assert info["cartesian_error"] < 1e-9 and info["orientation_error"] < 1e-9
    for segment in info["segments"]:
        assert segment["cartesian_error"] < 1e-9 and not segment["left_chart"]
    assert info["cartesian_error"] == max(s["cartesian_error"] for s in info["segments"])


def test_second_segment_starts_where_the_first_ended():
    """On the perturbed car, segment 1's error is that of the one-trial task from the state segment 0
    really ended in (not from the via point)."""
    config = load_config("segmented_parking")
    env = gym.make(ENV_ID, config=config)
    env.reset(seed=0)
    views = env.unwrapped.segment_views()
    c = [view.nominal_model.solve() for view in views]
    _, _, _, _, info = env.step(np.concatenate(c))
    first_end = info["segments"][0]["q_final"]
    assert 0.05 < info["segments"][0]["cartesian_error"]  # the perturbed car misses the via point
    moved = copy.deepcopy(packaged())
    moved["task"]["start"] = first_end.tolist()
    moved["task"]["via"] = []
    moved["task"]["segments"] = moved["task"]["segments"][1:]
    single = load_config(moved).segment_configs()[0]
    alone = gym.make("ilc_steering/ChainedSteering-v0", config=single)
    alone.reset(seed=0)
    _, _, _, _, its = alone.step(c[1])
    np.testing.assert_allclose(info["segments"][1]["q_final"], its["q_final"], atol=1e-12)


def test_run_converges_at_every_waypoint(tmp_path):
    result = run_ilc("segmented_parking", learner="ilc_paper")
    assert result.converged_at is not None and result.converged_at <= 8
    last = result.trials[-1]
    assert last.cartesian_error < 5e-4 and last.orientation_error < 5e-4
    assert main(["run", "segmented_parking", "--trials", "10"]) == 0


def test_a_segment_learner_sees_no_true_error_and_one_trial_envs_refuse_a_manoeuvre():
    from ilc_steering.core.score import TRUE_KEYS

    env = gym.make(ENV_ID, config="segmented_parking")
    env.reset(seed=0)
    c = np.concatenate([view.nominal_model.solve() for view in env.unwrapped.segment_views()])
    _, _, _, _, info = env.step(c)
    assert all(key in info for key in TRUE_KEYS)  # the worst over the waypoints, for scoring
    assert not any(key in segment for segment in info["segments"] for key in TRUE_KEYS)
    with pytest.raises(ValueError, match="a manoeuvre of several segments"):
        gym.make("ilc_steering/ChainedSteering-v0", config="segmented_parking")
    assert main(["compare", "--scenarios", "segmented_parking", "--methods", "ilc_paper"]) == 2


def first_within(rollout, tolerance=5e-4):
    """The first trial (1-based) whose every waypoint is within ``tolerance`` (m and rad)."""
    return next(
        t + 1
        for t, info in enumerate(rollout.infos)
        if info["cartesian_error"] < tolerance and info["orientation_error"] < tolerance
    )


def test_a_segment_learns_as_if_it_began_at_its_via_point():
    """Finding 1 of the review: segment 1's learner is told where its segment really began, and its
    error is re-based on the nominal model to the via point (eq. 23: ``z(T) = V z0 + W c``), so it
    does not take segment 0's miss for its own. ``newton_ilc`` learns each segment alone in 2 trials;
    in the manoeuvre every waypoint is within 5e-4 by trial 3 (it took 6 when segment 1 learned from
    the raw error), and the error at the goal never grows from trial 1 to trial 2."""
    env = gym.make(ENV_ID, config="segmented_parking")
    views = env.unwrapped.segment_views()
    rollout = run_trials(env, segmented_learner(lambda c: lookup("newton_ilc").make(c, 8), views, seed=1), 8, seed=1)
    first = rollout.infos[0]["segments"]
    np.testing.assert_array_equal(first[0]["z_start"], views[0].nominal_model.z_start)
    assert np.linalg.norm(first[1]["z_start"] - views[1].nominal_model.z_start) > 0.05  # segment 0 missed the via
    assert first_within(rollout) <= 3
    goal = [info["segments"][1]["cartesian_error"] for info in rollout.infos]
    assert goal[1] < goal[0]


@pytest.mark.parametrize("name", ["ilc_paper", "newton_ilc", "robust_ilc"])
def test_a_segment_that_never_ran_is_not_learned_from(name):
    """Finding 2 of the review: when segment 0 leaves its chart, segment 1 is not run; it is marked
    ``ran=False`` and its learner keeps its state (its next action is its last), while segment 0's
    learner learns from its own chart exit; the trial counts once, failed."""
    env = gym.make(ENV_ID, config="segmented_parking")
    obs, _ = env.reset(seed=0)
    views = env.unwrapped.segment_views()
    n0 = views[0].action_space.shape[0]
    learner = segmented_learner(lambda c: lookup(name).make(c, 4), views, seed=1)
    action = learner.act(obs)
    action[:n0] = views[0].action_space.high * np.array([1, 1, 0, 0])  # off segment 0's chart
    _, _, _, _, info = env.step(action)
    assert [s["ran"] for s in info["segments"]] == [True, False]
    assert info["segments"][0]["left_chart"] and info["left_chart"]
    learner.learn(info)
    after = learner.act(obs)
    np.testing.assert_array_equal(after[n0:], action[n0:])
    assert not np.array_equal(after[:n0], action[:n0])


def test_a_segment_not_run_is_measured_at_its_charts_edge():
    """Segment 0 halts at its chart's edge, a heading past segment 1's chart (its frame turned 0.7 rad
    the other way): segment 1 is not run, and is measured at its own chart's edge, ``left_chart``,
    not a ``ValueError`` from the chained map (the trial counts, failed)."""
    data = packaged()
    data["task"]["segments"][1]["frame"] = 0.7
    env = gym.make(ENV_ID, config=load_config(data))
    obs, _ = env.reset(seed=0)
    views = env.unwrapped.segment_views()
    n0 = views[0].action_space.shape[0]
    action = np.concatenate([view.nominal_model.solve() for view in views])
    action[:n0] = views[0].action_space.high * np.array([1, -1, 0, 0])
    _, _, _, _, info = env.step(action)
    assert [s["ran"] for s in info["segments"]] == [True, False]
    assert all(s["left_chart"] for s in info["segments"]) and np.all(np.isfinite(info["error"]))


@pytest.fixture(scope="module")
def seed_12():
    """parking-v0 seed 12 (a car facing away from its spot: two segments), as the generator writes it."""
    from ilc_steering.envs import highway

    return load_config(highway.highway_config(12))


@pytest.mark.extra("highway")
def test_a_manoeuvre_into_the_walls_is_never_sent(seed_12):
    """Review finding 5 on a manoeuvre: the paper's law from its fictitious zero iteration asks seed
    12's car to drive into the lot's walls in segment 1 (it did, in 7 of 8 trials): segment 1 is
    refused after segment 0 drove, before anything of it is sent (only segment 0's actions are
    logged); every trial counts, failed, every error finite."""
    env = gym.make(ENV_ID, config=seed_12)
    views = env.unwrapped.segment_views()
    rollout = run_trials(env, segmented_learner(lambda c: lookup("ilc_paper").make(c, 3), views, seed=1), 3, seed=1)
    steps = round(sum(seed_12.segment_configs()[0].task.pieces) / 0.2)
    assert len(rollout) == 3
    for info in rollout.infos:
        first, second = info["segments"]
        assert info["left_chart"] and np.all(np.isfinite(info["error"])) and info["plant"]["refused"]
        assert not info["plant"]["left_lot"] and not info["plant"]["crashed"]
        assert not first["plant"]["refused"] and second["plant"]["refused"] and second["plant"]["actions"] == []
        assert len(info["plant"]["actions"]) == steps


@pytest.mark.extra("highway")
def test_the_second_segment_of_seed_12_learns_as_fast_as_the_first(seed_12):
    """Finding 1 on the issue's own target: with its error re-based to the via point, segment 1 of
    seed 12 is inside 1 cm at trial 2 with ``newton_ilc``, as segment 0 is (from the raw error it took
    until trial 5: 0.24, 0.26, 0.27, 0.17, 5.6e-3 m)."""
    env = gym.make(ENV_ID, config=seed_12)
    views = env.unwrapped.segment_views()
    rollout = run_trials(env, segmented_learner(lambda c: lookup("newton_ilc").make(c, 2), views, seed=1), 2, seed=1)
    last = rollout.infos[-1]
    assert last["cartesian_error"] < 1e-2 and last["orientation_error"] < 1e-2
    assert not last["plant"]["crashed"] and not last["plant"]["left_lot"]


def test_run_json_keeps_the_manoeuvres_trajectory_for_plot(tmp_path):
    """Finding 4 of the review: ``run --json`` on a manoeuvre keeps each trial's trajectory (the
    segments joined, time running on, starting at ``task.start`` and ending at the goal's measured
    configuration), so ``plot`` draws it."""
    path = tmp_path / "run.json"
    assert main(["run", "segmented_parking", "--trials", "8", "--json", str(path)]) == 0
    result = run_ilc("segmented_parking", learner="ilc_paper", trials=3, trajectories=True)
    trajectory = result.trials[-1].trajectory
    assert trajectory is not None and np.all(np.diff(trajectory.t) > 0)
    config = load_config("segmented_parking")
    np.testing.assert_allclose(trajectory.q[0], config.task.start, atol=1e-12)
    assert trajectory.t[-1] == pytest.approx(sum(sum(c.task.pieces) for c in config.segment_configs()))
    assert main(["plot", str(path), "--out", str(tmp_path / "plots")]) == 0


def test_a_segment_that_would_start_off_its_chart_is_not_run():
    """Finding 3 of the review: segment 1's frame puts the via point 1.45 rad from its axis, and
    segment 0 overshoots to a heading past segment 1's chart. Segment 1 is not run (it ran before,
    and ended 13 m away with a folded heading, ``left_chart=False``): ``ran=False``, ``left_chart``,
    its ``refused`` says why, every error finite, the trial counted once, failed."""
    data = packaged()
    data["plant"].update(true_wheelbase=0.2, true_wheel_radius=0.02)
    data["task"]["segments"][1]["frame"] = 0.3 - 1.45
    env = gym.make(ENV_ID, config=load_config(data))
    env.reset(seed=0)
    c = [view.nominal_model.solve() for view in env.unwrapped.segment_views()]
    _, _, _, _, info = env.step(np.concatenate(c))
    assert info["cartesian_error"] < 1e-9 and not info["left_chart"]  # the nominal car: both segments run
    c[0][1:] *= 1.6  # segment 0 ends with a heading past segment 1's chart
    _, _, _, _, info = env.step(np.concatenate(c))
    first, second = info["segments"]
    assert first["ran"] and not first["left_chart"]
    assert not second["ran"] and second["left_chart"] and "would start off its chart" in second["refused"]
    assert info["left_chart"] and np.all(np.isfinite(info["error"]))


def test_a_segment_the_plant_refuses_after_the_car_drove_counts_the_trial(monkeypatch):
    """Finding 3: once segment 0 has driven the plant, a ``ValueError`` from segment 1's run (an
    external plant's refusal) fails the trial, counted, never a ``LearnerError``; segment 1's
    learner does not learn from it."""
    env = gym.make(ENV_ID, config="segmented_parking")
    scenario = env.unwrapped._segments[1]
    ran = []

    def refuse(*args, **kwargs):
        ran.append(1)
        raise ValueError("task.start is not where the last segment left the car")

    monkeypatch.setattr(scenario, "run", refuse)
    views = env.unwrapped.segment_views()
    rollout = run_trials(env, segmented_learner(lambda c: lookup("newton_ilc").make(c, 3), views, seed=1), 3, seed=1)
    assert len(ran) == 3 and len(rollout) == 3
    for info in rollout.infos:
        assert info["left_chart"] and not info["segments"][1]["ran"]
        assert "segment 1 refused: ValueError: task.start is not" in info["segments"][1]["refused"]
    actions = [info["segments"][1]["action"] for info in rollout.infos]
    np.testing.assert_array_equal(actions[0], actions[-1])


def test_a_segments_learner_sees_no_plant_and_reset_reseeds_it(monkeypatch):
    """Finding 10 of the review: a segment's view holds its name and ``learning`` only (it held the
    whole config, the true wheelbase included), and ``reset(seed=...)`` reseeds the one plant's
    scatter in every segment (an external plant's own draws follow ``run --seed``)."""
    from ilc_steering.envs.scenario import Scenario

    env = gym.make(ENV_ID, config="segmented_parking")
    views = env.unwrapped.segment_views()
    assert all(not hasattr(view.config, "plant") and not hasattr(view.config, "task") for view in views)
    context = LearnerContext.from_env(views[1], seed=3)
    assert context.task == "segmented_parking.1" and context.nu_a == load_config("segmented_parking").learning.nu_a
    seeds = []
    monkeypatch.setattr(Scenario, "reseed", lambda self, seed: seeds.append((id(self), seed)))
    env.reset(seed=7)
    env.reset()
    assert sorted(seeds) == sorted((id(scenario), 7) for scenario in env.unwrapped._segments)


def test_measurement_noise_reaches_every_segment():
    """``measurement_noise`` in the segmented env: each segment's end is measured with noise (its
    measured error differs from its true one, which is the noiseless env's), drawn from the env's
    seed (the same seed, the same trial)."""
    c = None
    infos = []
    for noise, seed in ((None, 0), (0.01, 0), (0.01, 0), (0.01, 1)):
        env = gym.make(ENV_ID, config="segmented_parking", measurement_noise=noise)
        env.reset(seed=seed)
        if c is None:
            c = np.concatenate([view.nominal_model.solve() for view in env.unwrapped.segment_views()])
        infos.append(env.step(c)[4])
    exact, noisy, again, other = infos
    for k in range(2):
        assert noisy["segments"][k]["cartesian_error"] != exact["segments"][k]["cartesian_error"]
        np.testing.assert_array_equal(noisy["segments"][k]["q_final"], again["segments"][k]["q_final"])
        assert not np.array_equal(noisy["segments"][k]["q_final"], other["segments"][k]["q_final"])
    assert noisy["true_cartesian_error"] == exact["true_cartesian_error"] == exact["cartesian_error"]


def test_a_nan_at_a_later_waypoint_is_not_hidden():
    """Finding 11 of the review: the worst error over the waypoints is NaN when any is (Python's
    ``max(0.005, nan)`` was 0.005: a trial within tolerance), and the trial is ``left_chart``."""
    from ilc_steering.core.score import within_tolerance

    env = gym.make(ENV_ID, config="segmented_parking")
    env.reset(seed=0)
    c = np.concatenate([view.nominal_model.solve() for view in env.unwrapped.segment_views()])
    _, _, _, _, info = env.step(c)
    infos = [dict(segment) for segment in info["segments"]]
    for segment in infos:
        segment.update({key: 1e-6 for key in manoeuvre.WORST if key in info})
    assert not manoeuvre.summary(infos)["left_chart"]
    infos[1]["cartesian_error"] = float("nan")
    summary = manoeuvre.summary(infos)
    assert np.isnan(summary["cartesian_error"]) and summary["left_chart"]
    assert not within_tolerance(load_config("segmented_parking").learning.tolerance, summary)


def test_every_segments_learner_is_closed_when_one_raises():
    """Finding 16 of the review: ``close()`` closes every segment's learner, then raises the first
    error (it stopped at the first learner that raised, the others left open)."""
    from ilc_steering.segmented import SegmentedLearner

    closed = []

    class Learner:
        def __init__(self, k):
            self.k = k

        def act(self, observation):
            return np.zeros(1)

        def learn(self, info):
            pass

        def reset(self):
            pass

        def close(self):
            closed.append(self.k)
            if self.k < 2:
                raise RuntimeError(f"learner {self.k} failed to close")

    views = gym.make(ENV_ID, config="segmented_parking").unwrapped.segment_views()
    learner = SegmentedLearner([Learner(k) for k in range(3)], [views[0]] * 3)
    with pytest.raises(RuntimeError, match="learner 0 failed"):
        learner.close()
    assert closed == [0, 1, 2]


def test_a_segment_may_have_its_own_action_bound():
    """Finding 17 of the review: ``task.segments[k].action_bound`` is a segment's box (it was refused
    as an unknown key), checked as a one-trial task's, its fault named by the segment's key."""
    data = packaged()
    data["task"]["segments"][1]["action_bound"] = [0.5, 9.0, 9.0, 9.0]
    env = gym.make(ENV_ID, config=load_config(data))
    views = env.unwrapped.segment_views()
    np.testing.assert_allclose(views[1].action_space.high, [0.5, 9.0, 9.0, 9.0])
    assert not np.allclose(views[0].action_space.high[0], 0.5)
    data["task"]["segments"][1]["action_bound"] = [0.5, 9.0]
    with pytest.raises(ConfigError, match=r"task\.segments\[1\]\.action_bound"):
        load_config(data)


def test_a_lab_robot_takes_a_manoeuvre_in_one_frame_only():
    """Finding 15 of the review: the env asks whether the plant's state turns with the frame (its
    configuration and the controller's estimate of a turned state are the turned ones), not whether
    the state has more than 6 entries: the lab robot's dead-reckoned estimate does not turn, so its
    segments must share one frame; the car's do turn."""
    lab = yaml.safe_load((resources.files("ilc_steering.configs") / "experiment_forward.yaml").read_text())
    data = packaged()
    data["plant"] = lab["plant"]
    for segment in data["task"]["segments"]:
        segment["frame"] = 0.15
    assert gym.make(ENV_ID, config=load_config(data)).unwrapped._segments[0].plant.state_dim == 12
    data["task"]["segments"][1]["frame"] = 0.7
    with pytest.raises(ValueError, match="segments in different frames need a plant whose state turns with the frame"):
        gym.make(ENV_ID, config=load_config(data))
    car = packaged()
    car["task"]["segments"][1]["frame"] = 0.7
    assert manoeuvre._turns_with_frame(gym.make(ENV_ID, config=load_config(car)).unwrapped._segments[0])
