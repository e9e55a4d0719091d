"""Rendering and trajectory recording: frames from both envs, Gymnasium's render checks, and
recorded trajectories checked against the trial's final state and a solve_ivp reference."""

import dataclasses
import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import ilc_steering  # noqa: F401  (registers the envs)
from ilc_steering.agents import CyclicILCAgent
from ilc_steering.config import load_config
from ilc_steering.core.reference import reference_trial
from ilc_steering.core.robots.car import car_outline, chained_inputs
from ilc_steering.envs import rendering
from ilc_steering.envs.frames import GOAL, PATH, PLOT, START, Scene, draw_scene, view
from ilc_steering.envs.glyphs import ADVANCE, GLYPH_HEIGHT, text_mask
from ilc_steering.envs.raster import Layer, Pen, Raster, WorldToPixels

STEERING, CYCLIC = "ilc_steering/ChainedSteering-v0", "ilc_steering/CyclicSteering-v0"
DOCUMENTED = ("symmetric and normalized space", "observation space minimum", "observation space maximum")


def ink(frame):
    """The fraction of pixels that are not (near) white."""
    return float(np.mean(np.any(frame < 240, axis=-1)))


@pytest.mark.parametrize(
    ("env_id", "config"),
    [
        (STEERING, "forward_parking"),
        (STEERING, "forward_parking_saturated"),
        (STEERING, "chained_perturbed"),
        (CYCLIC, "cyclic_home_goal"),
    ],
)
def test_a_frame_shows_the_task_and_then_the_trial(env_id, config):
    env = gym.make(env_id, config=config, render_mode="rgb_array")
    env.reset(seed=0)
    before = env.render()
    models = getattr(env.unwrapped, "nominal_models", None) or [env.unwrapped.nominal_model]
    env.step(models[0].solve())
    after = env.render()
    for frame in (before, after):
        assert frame.shape == (480, 480, 3) and frame.dtype == np.uint8
        assert 0.01 < ink(frame) < 0.6  # axes, cars and text, on a white page
    assert len(np.unique(after.reshape(-1, 3), axis=0)) > 20
    assert np.any(before != after)  # the trial's path and cars appeared
    env.close()


@pytest.mark.parametrize(("env_id", "config"), [(STEERING, "forward_parking"), (CYCLIC, "cyclic_home_goal")])
def test_gymnasium_render_checks_pass(env_id, config):
    assert gym.spec(env_id) is not None
    for render_mode in (None, "rgb_array"):
        env = gym.make(env_id, config=config, render_mode=render_mode)
        assert env.unwrapped.metadata["render_modes"] == ["rgb_array"] and env.unwrapped.metadata["render_fps"] > 0
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            check_env(env.unwrapped)  # with render_mode None it makes one env per declared mode
        unexpected = [str(w.message) for w in caught if not any(d in str(w.message) for d in DOCUMENTED)]
        assert unexpected == []


def test_render_without_a_render_mode_warns_and_returns_none():
    env = gym.make(STEERING, config="forward_parking")
    env.reset(seed=0)
    with pytest.warns(UserWarning, match="render_mode"):
        assert env.unwrapped.render() is None


def test_car_outline_puts_the_front_wheel_one_wheelbase_ahead_turned_by_phi():
    q = np.array([1.0, 2.0, 0.3, -0.4])
    body, rear, front = car_outline(q, 0.2)
    assert np.allclose(rear.mean(axis=0), q[:2])
    assert np.allclose(front.mean(axis=0), q[:2] + 0.2 * np.array([np.cos(0.3), np.sin(0.3)]))
    direction = front[1] - front[0]
    assert np.isclose(np.arctan2(direction[1], direction[0]), 0.3 - 0.4)
    assert np.allclose(body[0], body[-1])  # a closed polygon


def test_trajectories_are_off_by_default_and_do_not_change_the_trial():
    plain = gym.make(STEERING, config="forward_parking_saturated")
    recording = gym.make(STEERING, config="forward_parking_saturated", record_trajectory=True)
    c = plain.unwrapped.nominal_model.solve() * 1.05
    for env in (plain, recording):
        env.reset(seed=0)
    *_, info = plain.step(c)
    *_, recorded = recording.step(c)
    assert "trajectory" not in info
    assert np.array_equal(info["q_final"], recorded["q_final"])  # bit for bit
    trajectory = recorded["trajectory"]
    assert np.array_equal(trajectory.q[-1], recorded["q_final"])
    assert np.array_equal(trajectory.q[0], plain.unwrapped._scenario.start)
    assert trajectory.t[0] == 0.0 and np.isclose(trajectory.t[-1], 5.0) and np.all(np.diff(trajectory.t) > 0)
    assert np.max(np.abs(trajectory.q[:, 3])) <= np.pi / 4 + 1e-15  # the wheel stays at the stop
    assert np.sum(np.isclose(np.abs(trajectory.q[:, 3]), np.pi / 4)) > 10  # and rests there a while


def test_trajectory_matches_solve_ivp_at_every_sample():
    env = gym.make(STEERING, config="forward_parking", record_trajectory=True)
    env.reset(seed=0)
    c = env.unwrapped.nominal_model.solve() * np.array([1.1, 0.9, 1.05, 0.95])
    *_, info = env.step(c)
    trajectory = info["trajectory"]
    scenario = env.unwrapped._scenario
    field = scenario.plant.reference_field(scenario.profile, c)[0]
    for k in (20, 57, 100, 143):
        reference = reference_trial(field, scenario.x_start, np.array([0.0, trajectory.t[k]]))
        assert np.max(np.abs(scenario.to_world(reference) - trajectory.q[k])) < 1e-9


def test_inputs_are_eqs_4_5_with_the_nominal_geometry_at_the_measured_configuration():
    env = gym.make(STEERING, config="parallel_parking", record_trajectory=True)
    env.reset(seed=0)
    model = env.unwrapped.nominal_model
    c = model.solve()
    *_, info = env.step(c)
    trajectory = info["trajectory"]
    v1, v2 = model.profile.evaluate(c, trajectory.t)
    task = env.unwrapped._scenario.to_task(trajectory.q)
    for k in (0, 33, 79, 81, 150, 160):
        u1, u2 = chained_inputs(task[k, 2], task[k, 3], v1[k], v2[k], 0.2, 0.02)
        assert np.allclose(trajectory.u[k], [u1, u2], rtol=1e-12, atol=1e-12)
    assert np.isclose(trajectory.u[0, 0], c[0] / (0.02 * np.cos(task[0, 2])))  # u1 = v1 / (rho cos theta)
    assert trajectory.u[10, 0] > 0 > trajectory.u[-10, 0]  # forward, then backward


def test_a_trial_that_leaves_the_chart_ends_where_the_car_halted():
    env = gym.make(STEERING, config="forward_parking", record_trajectory=True)
    env.reset(seed=0)
    c = env.unwrapped.nominal_model.solve()
    c[1] = env.action_space.high[1]  # steer hard: theta runs to pi/2
    *_, info = env.step(c)
    trajectory = info["trajectory"]
    assert info["left_chart"] and trajectory.left_chart
    assert trajectory.t[-1] < 5.0
    assert np.array_equal(trajectory.q[-1], info["q_final"])
    assert np.any(trajectory.q[-1] != trajectory.q[-2])  # no standstill kept after the halt


def test_cyclic_segments_record_their_own_time_and_chain_up():
    env = gym.make(CYCLIC, config="cyclic_home_goal", cycles=2, record_trajectory=True)
    obs, _ = env.reset(seed=0)
    agent = CyclicILCAgent(env.unwrapped.nominal_models, 1.0, 1.0)
    previous = None
    truncated = False
    while not truncated:
        obs, _, _, truncated, info = env.step(agent.act(obs))
        agent.learn(info)
        trajectory = info["trajectory"]
        assert trajectory.t[0] == 0.0 and np.isclose(trajectory.t[-1], 5.0)
        assert np.array_equal(trajectory.q[-1], info["q_final"])
        if previous is not None:
            assert np.allclose(trajectory.q[0], previous, atol=1e-12)  # never reset
        previous = info["q_final"]


def test_equal_relative_perturbation_of_wheelbase_and_radius_leaves_theta_and_phi_nominal():
    """The yaw rate rho u1 tan(phi) / ell keeps its nominal value when ell and rho grow by the same
    factor: only the speed along the path changes (why simulation 1's orientation error is round-off)."""
    config = load_config("forward_parking")
    nominal = dataclasses.replace(
        config, plant=dataclasses.replace(config.plant, true_wheelbase=0.2, true_wheel_radius=0.02)
    )
    c = np.array([0.2, -0.3, 0.1, 0.02])
    runs = []
    for cfg in (config, nominal):
        env = gym.make(STEERING, config=cfg, record_trajectory=True)
        env.reset(seed=0)
        runs.append(env.step(c)[-1]["trajectory"].q)
    perturbed, exact = runs
    assert np.max(np.abs(perturbed[:, 2:] - exact[:, 2:])) < 1e-12
    assert np.max(np.abs(perturbed[:, :2] - exact[:, :2])) > 0.01  # the path itself differs


# The rasterizer behind the frames: pixels that must and must not be inked, and the scene it draws.

WHITE = np.array([255, 255, 255])


def distance_to_segment(points, a, b):
    """Distance [px] of points ``(..., 2)`` from the segment ``a``-``b``."""
    ab = b - a
    t = np.clip(((points - a) @ ab) / (ab @ ab), 0.0, 1.0)
    return np.linalg.norm(points - (a + t[..., None] * ab), axis=-1)


@pytest.mark.parametrize(
    ("a", "b", "width"),
    [
        ((10.0, 40.5), (90.0, 40.5), 2.0),  # horizontal
        ((30.2, 5.0), (30.2, 75.0), 1.1),  # vertical
        ((12.3, 70.1), (85.7, 9.6), 3.3),  # shallow, rising to the right
        ((40.0, 4.0), (55.0, 76.0), 1.7),  # steep
    ],
)
def test_a_segment_inks_the_pixels_near_it_and_no_others(a, b, width):
    raster = Raster(100, 80)
    colour = (200, 30, 10)
    raster.stroke([np.array([a, b])], colour, Pen(width))
    rows, columns = np.mgrid[:80, :100]
    centres = np.stack([columns + 0.5, rows + 0.5], axis=-1)
    distance = distance_to_segment(centres, np.array(a), np.array(b))
    # Away from the ends (butt caps): the colour mixed in by clip(w / 2 + 1 / 2 - d, 0, 1), d from the segment.
    ab = np.array(b) - np.array(a)
    along = ((centres - np.array(a)) @ ab) / (ab @ ab)
    middle = (along > 0.05) & (along < 0.95)
    coverage = np.clip(width / 2 + 0.5 - distance, 0.0, 1.0)[middle][:, None]
    expected = 255 + (np.array(colour) - 255) * coverage
    assert np.max(np.abs(raster.image[middle] - expected)) <= 1.5
    assert np.sum(coverage > 0.5) > 60  # the line is there
    # Beyond the half width plus half a pixel: untouched white (past the ends, where the butt cap
    # is cut square to the major axis, beyond the width plus a pixel).
    far = (distance >= width / 2 + 0.5) & (((along > 0) & (along < 1)) | (distance > width + 1))
    assert np.all(raster.image[far] == WHITE)


def test_a_dashed_line_leaves_its_gaps_white():
    raster = Raster(120, 20)
    raster.stroke([np.array([(0.0, 10.5), (120.0, 10.5)])], (0, 0, 0), Pen(1.0, (6.0, 4.0)))
    inked = raster.image[10, :, 0] < 128
    assert np.array_equal(inked, (np.arange(120) + 0.5) % 10.0 < 6.0)
    assert np.all(raster.image[:8] == 255) and np.all(raster.image[13:] == 255)


def test_dots_and_crossing_lines_take_their_colour_once():
    raster = Raster(60, 60)
    raster.dots(np.array([[20.0, 20.0]]), 8.0, (0, 0, 255), 0.5)
    crossing = [np.array([(0.0, 40.5), (60.0, 40.5)]), np.array([(30.5, 0.0), (30.5, 60.0)])]
    raster.draw([Layer(crossing, Pen(3.0), (0, 0, 255), 0.5), Layer([crossing[0][:, ::-1]], Pen(1.0), (0, 0, 0))])
    rows, columns = np.mgrid[:60, :60]
    disc = np.hypot(columns + 0.5 - 20.0, rows + 0.5 - 20.0)
    assert np.all(raster.image[disc < 3.5] == (128, 128, 255))
    assert np.all(raster.image[(disc >= 4.5) & (disc < 7)] == WHITE)
    assert tuple(raster.image[40, 30]) == (128, 128, 255)  # where the lines cross: alpha once, not twice
    assert tuple(raster.image[30, 40]) == (0, 0, 0)  # the second layer, over the first


def test_a_pen_too_wide_and_pens_that_do_not_match_the_lines_are_refused():
    raster = Raster(50, 50)
    with pytest.raises(ValueError, match="pixels wide"):
        raster.stroke([np.array([(0.0, 0.0), (10.0, 10.0)])], (0, 0, 0), Pen(30.0))
    with pytest.raises(ValueError, match="one pen"):
        raster.stroke([np.array([(0.0, 0.0), (10.0, 10.0)])], (0, 0, 0), [Pen(1.0), Pen(2.0)])


def test_world_to_pixels_has_one_scale_and_centres_the_box():
    to_pixels = WorldToPixels(np.array([-1.0, 0.0]), np.array([1.0, 0.5]), (10, 20, 210, 120))
    assert to_pixels.scale == 100.0  # the wide axis fills the 200 px
    assert np.allclose(to_pixels(np.array([[-1.0, 0.25], [1.0, 0.25], [0.0, 0.0]])), [[10, 70], [210, 70], [110, 95]])
    assert np.allclose(to_pixels.lower, [-1.0, -0.25]) and np.allclose(to_pixels.upper, [1.0, 0.75])


def test_the_font_has_every_character_of_the_titles_and_a_box_for_the_rest():
    title = "forward_parking: trial 12, error 1.30e-01 m [rad] (z5)"
    assert text_mask(title).shape == (GLYPH_HEIGHT, ADVANCE * len(title) - 1)
    assert np.array_equal(text_mask("θ"), text_mask("?"))
    assert not np.array_equal(text_mask("0"), text_mask("O"))
    assert all(text_mask(c).any() for c in "0123456789abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ.,:-_[]()")


def test_the_frame_puts_the_car_where_it_is_and_nothing_far_from_it():
    car = load_config("forward_parking").plant.nominal_map()
    start, goal = np.array([0.0, 0.0, 0.0, 0.0]), np.array([1.0, 0.6, 0.5, 0.3])
    scene = Scene(np.array([start, goal]), car, ["start", "goal"], [], "a title")
    frame = draw_scene(scene)
    to_pixels = view(scene)
    for q, colour in ((start, START), (goal, GOAL)):
        body, rear, front = car_outline(q, car.wheelbase)
        for wheel in (rear, front):  # a wheel's middle: solid, its colour
            column, row = np.floor(to_pixels(wheel.mean(axis=0))).astype(int)
            assert tuple(frame[row, column]) == colour
        inked = [frame[r, c] for c, r in np.floor(to_pixels((body[:-1] + body[1:]) / 2)).astype(int)]
        assert sum(np.any(p < 200) for p in inked) >= 3  # the body's sides (the goal's are dashed)
    # Between the two cars, where nothing is drawn (a grid line at most): white or the grid's grey.
    column, row = np.floor(to_pixels(np.array([0.5, -0.3]))).astype(int)
    assert np.all(frame[row - 3 : row + 4, column - 3 : column + 4] >= 231)
    assert np.any(frame[: PLOT[1] - 5] < 128)  # the title, above the axes


def test_the_frames_colours_are_the_figures():
    from matplotlib.colors import to_rgb

    for name, rgb in ((rendering.START, START), (rendering.GOAL, GOAL), (rendering.PATH, PATH)):
        assert np.allclose(np.array(to_rgb(name)) * 255, rgb, atol=0.5)


@pytest.mark.parametrize(("env_id", "config"), [(STEERING, "trailer_bay"), (CYCLIC, "cyclic_pickup_dropoff")])
def test_frames_are_deterministic_and_show_the_last_path(env_id, config):
    frames = []
    for _ in range(2):
        env = gym.make(env_id, config=config, render_mode="rgb_array")
        env.reset(seed=0)
        models = getattr(env.unwrapped, "nominal_models", None) or [env.unwrapped.nominal_model]
        env.step(models[0].solve() * 1.01)
        frames += [env.render(), env.render()]
    assert all(np.array_equal(frames[0], f) for f in frames[1:])
    scene = env.unwrapped.scene()
    has_pose = scene.robot is not None
    path = view(scene)(rendering.plane(scene.paths[-1], has_pose))
    columns, rows = np.floor(path[5:-5:7]).T.astype(int)
    assert np.mean(np.any(frames[0][rows, columns] < 200, axis=-1)) > 0.9  # the path is drawn where it runs


def test_lines_far_outside_or_not_finite_draw_only_what_is_in_the_image():
    raster = Raster(100, 80)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no overflow or invalid-value warning either
        lines = [
            np.array([(-1e12, 40.5), (1e12, 40.5)]),  # across the whole image
            np.array([(np.nan, 3.0), (5.0, 5.0)]),
            np.array([(np.inf, 10.0), (np.inf, 20.0)]),
            np.array([(1e9, -1e9), (2e9, 1e9)]),  # entirely outside
        ]
        raster.stroke(lines, (0, 0, 0), Pen(2.0))
    inked = np.any(raster.image < 255, axis=-1)
    assert np.all(raster.image[40] == 0) and np.array_equal(np.flatnonzero(inked.any(axis=1)), [39, 40, 41])


@pytest.mark.parametrize("config", ["forward_parking", "unicycle_parking", "trailer_bay"])
def test_the_outline_of_many_configurations_is_each_ones_outline(config):
    robot = load_config(config).plant.nominal_map()
    q = np.random.default_rng(3).normal(size=(6, 5))
    batch = rendering.robot_outline(robot, q)
    for k in range(6):
        single = rendering.robot_outline(robot, q[k])
        assert [w for _, w in single] == [w for _, w in batch]
        assert all(np.array_equal(line[k], one) for (line, _), (one, _) in zip(batch, single))
