"""TensorBoard for every learner (issue 68, item 1): ``run``, a compare cell and the trial loop write one
point per trial of the same tags, trials on the x axis, read back here with TensorBoard's own reader."""

import sys
from dataclasses import replace

import gymnasium as gym
import numpy as np
import pytest

import ilc_steering  # noqa: F401  (registers the envs)
from ilc_steering.cli import main
from ilc_steering.compare.args import Args
from ilc_steering.compare.cells import run_cell
from ilc_steering.errors import BadInput
from ilc_steering.loop import run_trials
from ilc_steering.runner import run_cyclic_ilc, run_ilc
from ilc_steering.trial_board import TAGS, run_folder

POSE_TAGS = set(TAGS)
"""A robot with a pose reports every error, and its config a tolerance: every tag."""


def points(folder):
    """tag -> [(step, value)] of the event files in ``folder``, every point (TensorBoard's reader keeps
    10 tensors per tag unless told otherwise)."""
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator
    from tensorboard.util import tensor_util

    accumulator = EventAccumulator(str(folder), size_guidance={"tensors": 0})
    accumulator.Reload()
    return {
        tag: [(event.step, float(tensor_util.make_ndarray(event.tensor_proto))) for event in accumulator.Tensors(tag)]
        for tag in accumulator.Tags()["tensors"]
    }


def steps(read):
    """The one list of steps every tag shares (asserted)."""
    lists = {tuple(step for step, _ in series) for series in read.values()}
    assert len(lists) == 1, lists
    return list(lists.pop())


@pytest.mark.extra("tensorboard")
def test_run_writes_one_point_per_trial_with_its_errors(tmp_path, capsys):
    assert main(["run", "forward_parking", "--trials", "6", "--tensorboard", str(tmp_path)]) == 0
    folder = tmp_path / "forward_parking" / "ilc_paper_seed1"
    assert [p.name[:20] for p in folder.iterdir()] == ["events.out.tfevents."]
    read = points(folder)
    assert set(read) == POSE_TAGS and steps(read) == [1, 2, 3, 4, 5, 6]
    records = run_ilc("forward_parking", trials=6).trials  # the same run, without the board
    errors = [value for _, value in read["trial/true_cartesian_error"]]
    np.testing.assert_allclose(errors, [r.cartesian_error for r in records], rtol=1e-6)  # float32 events
    assert errors[0] == pytest.approx(0.1, rel=1e-6) and errors[-1] < 1e-5  # eq. 33's tenfold cut a trial
    costs = [value for _, value in read["trial/cost"]]
    np.testing.assert_allclose([-value for _, value in read["trial/reward"]], costs, rtol=1e-6)  # measured exactly
    within = [value for _, value in read["trial/within_tolerance"]]
    assert within == [0.0, 0.0, 0.0, 1.0, 1.0, 1.0]  # 1 cm reached at trial 4
    assert [value for _, value in read["trial/converged"]] == [0.0] * 5 + [1.0]  # held for 3 trials at trial 6
    assert "converged at trial 4 (held for the last 3 trials)" in capsys.readouterr().out


@pytest.mark.extra("tensorboard")
def test_a_rerun_replaces_its_points(tmp_path):
    for trials in ("5", "3"):
        assert main(["run", "forward_parking", "--trials", trials, "--tensorboard", str(tmp_path)]) == 1
    folder = tmp_path / "forward_parking" / "ilc_paper_seed1"
    assert len(list(folder.glob("events.out.tfevents.*"))) == 1
    assert steps(points(folder)) == [1, 2, 3]


@pytest.mark.extra("tensorboard")
def test_compare_cells_of_ilc_and_a_black_box_learner_write_the_same_tags(tmp_path):
    """Each cell writes its own folder; the tags are the same whatever the learner, the result the same
    as without TensorBoard (it is no part of a cell's result)."""
    args = Args(model_trials=6, blackbox_trials=25)
    series = {}
    for method, budget in (("ilc", 6), ("least_squares", 25)):
        plain = run_cell(args, "nominal", method, "forward_parking", 0)
        cell = run_cell(replace(args, tensorboard=tmp_path), "nominal", method, "forward_parking", 0)
        assert {k: v for k, v in cell.items() if k != "wall_s"} == {k: v for k, v in plain.items() if k != "wall_s"}
        read = points(run_folder(tmp_path, "forward_parking", method, 0))
        assert steps(read) == list(range(1, budget + 1)) and cell["trials"] == budget
        best = min(value for _, value in read["trial/cost"])
        assert best == pytest.approx(cell["best_error"], rel=1e-6)  # the cost compare scores
        series[method] = read
    assert set(series["ilc"]) == set(series["least_squares"]) == POSE_TAGS
    assert sorted(p.name for p in (tmp_path / "forward_parking").iterdir()) == ["ilc_seed0", "least_squares_seed0"]
    none = run_cell(replace(args, tensorboard=tmp_path), "none", "ilc", "forward_parking", 0)
    assert (tmp_path / "forward_parking" / "ilc_seed0_prior-none").is_dir() and none["prior"] == "none"


@pytest.mark.extra("tensorboard")
def test_the_trial_loop_writes_for_any_learner_and_a_cyclic_run_per_segment(tmp_path):
    from ilc_steering.agents.base import LearnerContext
    from ilc_steering.agents.registry import lookup

    env = gym.make("ilc_steering/ChainedSteering-v0", config="parallel_parking")
    learner = lookup("nelder_mead").make(LearnerContext.from_env(env, seed=0), 12)
    rollout = run_trials(env, learner, 12, seed=0, tensorboard=tmp_path / "loop")
    read = points(tmp_path / "loop")
    assert steps(read) == list(range(1, 13)) and set(read) == POSE_TAGS
    np.testing.assert_allclose([v for _, v in read["trial/reward"]], rollout.rewards, rtol=1e-6)
    result = run_cyclic_ilc("cyclic_home_goal", cycles=3, tensorboard=tmp_path, hold=2)
    read = points(tmp_path / "cyclic_home_goal" / "ilc_paper_seed0")
    segments = len(result.cycles[0].waypoints)
    assert steps(read) == list(range(1, 3 * segments + 1))
    held = [value for _, value in read["trial/converged"]][segments - 1 :: segments]  # at each cycle's end
    met = [all(w.cartesian_error <= 0.01 and w.orientation_error <= 0.01 for w in c.waypoints) for c in result.cycles]
    assert held == [float(all(met[max(0, k - 1) : k + 1]) and k >= 1) for k in range(3)]


def test_without_the_extra_the_run_is_refused_before_any_trial(tmp_path, monkeypatch, capsys):
    """One line naming the extra, exit 2, before a trial (no header, no cell folder); in Python a BadInput
    before the loop resets the env."""
    for name in [m for m in sys.modules if m == "tensorboard" or m.startswith("tensorboard.")]:
        monkeypatch.delitem(sys.modules, name)
    monkeypatch.setitem(sys.modules, "tensorboard", None)  # import tensorboard raises ImportError
    assert main(["run", "forward_parking", "--tensorboard", str(tmp_path / "tb")]) == 2
    out, err = capsys.readouterr()
    assert out == "" and err.count("\n") == 1
    assert "--tensorboard needs the tensorboard extra" in err and 'pip install "ilc-steering[tensorboard]"' in err
    argv = ["compare", "--quick", "--methods", "ilc", "--scenarios", "forward_parking", "--seeds", "0"]
    assert main([*argv, "--out", str(tmp_path / "run"), "--tensorboard", str(tmp_path / "tb")]) == 2
    assert "--tensorboard needs the tensorboard extra" in capsys.readouterr().err
    assert not (tmp_path / "run").exists() and not (tmp_path / "tb").exists()

    class Counted:
        def __init__(self, env):
            self.env = env

        def reset(self, **kwargs):
            raise AssertionError("the env was reset: a trial was about to run")

        unwrapped = property(lambda self: self.env.unwrapped)

    with pytest.raises(BadInput, match=r"tensorboard needs the tensorboard extra"):
        run_trials(Counted(gym.make("ilc_steering/ChainedSteering-v0")), None, 3, tensorboard=tmp_path / "x")


@pytest.mark.extra("tensorboard")
def test_an_unwritable_folder_is_refused_by_name(tmp_path, capsys):
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    assert main(["run", "forward_parking", "--tensorboard", str(blocker)]) == 2
    out, err = capsys.readouterr()
    assert out == "" and f"--tensorboard {blocker}: cannot write there" in err


@pytest.mark.slow
@pytest.mark.extra("tensorboard", "rl")
def test_a_comparison_of_ilc_and_rl_lays_both_on_one_chart(tmp_path, capsys):
    """``compare --quick --methods ilc ppo``: a folder per cell, one point per trial (6 and 48), the same
    tags, PPO's own SB3 logs beside its points; the run folder is the same as without ``--tensorboard``."""
    from ilc_steering.readers import read_json

    argv = ["compare", "--quick", "--methods", "ilc", "ppo", "--scenarios", "forward_parking", "--seeds", "0"]
    argv += ["--priors", "nominal", "--out", str(tmp_path / "run")]
    assert main([*argv, "--tensorboard", str(tmp_path / "tb")]) == 0
    ilc = points(tmp_path / "tb" / "forward_parking" / "ilc_seed0")
    ppo = points(tmp_path / "tb" / "forward_parking" / "ppo_seed0")
    assert set(ilc) == set(ppo) == POSE_TAGS
    assert steps(ilc) == list(range(1, 7)) and steps(ppo) == list(range(1, 49))
    assert list((tmp_path / "tb" / "forward_parking" / "ppo_seed0").glob("PPO_*/events.out.tfevents.*"))
    settings = read_json(tmp_path / "run" / "run.json", 1 << 20)
    assert "tensorboard" not in settings
    cell = read_json(tmp_path / "run" / "cells" / "nominal__ppo__forward_parking__0.json", 1 << 20)
    plain = run_cell(Args(quick=True, rl_trials=48), "nominal", "ppo", "forward_parking", 0)
    assert cell["curve"] == plain["curve"] and cell["trials_to"] == plain["trials_to"]
    best = min(value for _, value in ppo["trial/cost"])
    assert best == pytest.approx(cell["best_error"], rel=1e-6)
    capsys.readouterr()
    assert main(argv) == 0  # resumed without --tensorboard: every cell taken as it is
    assert "all 2 cells finished" in capsys.readouterr().out
    assert read_json(tmp_path / "run" / "cells" / "nominal__ppo__forward_parking__0.json", 1 << 20) == cell


@pytest.mark.extra("tensorboard")
def test_a_session_writes_its_recorded_trials_with_the_same_tags(tmp_path, capsys):
    from ilc_steering import session
    from ilc_steering.config import load_config
    from ilc_steering.lab_robot import LabRobot

    robot, folder = LabRobot(load_config("experiment_forward")), tmp_path / "s"
    state = session.new(folder, "experiment_forward_process", trials=10) and session.status(folder)
    while state.state is session.State.PENDING:  # the module's example: MARIO stands in for the robot
        state = session.record(folder, robot.trial(session.next(folder).request)["final"])
    assert main(["session", "status", str(folder), "--tensorboard", str(tmp_path / "tb")]) == 0
    read = points(tmp_path / "tb" / "experiment_forward_process" / "ilc_paper_seed1")
    assert set(read) == POSE_TAGS and steps(read) == list(range(1, len(state.trials) + 1))
    measured = [value for _, value in read["trial/cartesian_error"]]
    np.testing.assert_allclose(measured, [t.cartesian_error for t in state.trials], rtol=1e-6)  # float32 events
    assert [value for _, value in read["trial/true_cartesian_error"]] == measured  # a session measures, only
    assert [value for _, value in read["trial/converged"]][-1] == 1.0 and state.converged_at == 4
    capsys.readouterr()
    assert main(["session", "status", str(folder), "--tensorboard", str(folder / "tb")]) == 2
    assert "inside the session" in capsys.readouterr().err
