"""The paper's figures from a run: every figure type written for short runs, the plotted data
equal to the run's, and bad run files named."""

import json

import matplotlib.image
import numpy as np
import pytest

from ilc_steering.cli import main
from ilc_steering.plots import coordinates_figure, errors_figure, load_run, path_figure, trajectory_figure, write_plots
from ilc_steering.runner import run_cyclic_ilc, run_ilc


def assert_png(path, min_ink=0.01):
    image = matplotlib.image.imread(path)
    assert image.ndim == 3 and image.shape[0] >= 300 and image.shape[1] >= 500
    ink = np.mean(np.any(image[..., :3] < 0.94, axis=-1))
    assert min_ink < ink < 0.6, f"{path.name}: {ink:.3f} of the pixels are drawn"


@pytest.fixture(scope="module")
def saturated():
    return json.loads(json.dumps(run_ilc("forward_parking_saturated", trials=3, trajectories=True).to_json()))


@pytest.fixture(scope="module")
def cyclic():
    return run_cyclic_ilc("cyclic_home_goal", cycles=3, trajectories=True).to_json()


def test_every_figure_of_a_one_trial_run_is_written(saturated, tmp_path):
    paths = write_plots(saturated, tmp_path)
    assert [p.name for p in paths] == [
        f"forward_parking_saturated_{kind}.png" for kind in ("trajectory", "coordinates", "inputs", "errors")
    ]
    for path in paths:
        assert_png(path)


def test_every_figure_of_a_cyclic_run_is_written(cyclic, tmp_path):
    paths = write_plots(cyclic, tmp_path)
    assert [p.name for p in paths] == ["cyclic_home_goal_path.png", "cyclic_home_goal_waypoint_errors.png"]
    for path in paths:
        assert_png(path)


def test_chained_plant_figures_are_written(tmp_path):
    run = run_ilc("chained_perturbed", trials=2, trajectories=True).to_json()
    for path in write_plots(run, tmp_path):
        assert_png(path, min_ink=0.005)


@pytest.mark.slow
def test_plotted_data_are_the_runs(saturated):
    run = load_run(saturated)
    last = run.trajectory(run.records[-1])
    ax = trajectory_figure(run).axes[0]
    path = next(line for line in ax.lines if line.get_label() == "trial 3")
    assert np.array_equal(path.get_xydata(), last.q[:, :2])
    first_end = next(line for line in ax.lines if line.get_label() == "end of trial 1")
    assert first_end.get_linestyle() == ":"
    body = first_end.get_xydata()
    x, y, theta, _ = saturated["trials"][0]["final_state"]
    assert len(body) == 5 and np.array_equal(body[0], body[-1])  # a closed outline
    centre = np.array([x, y]) + 0.5 * 0.2 * np.array([np.cos(theta), np.sin(theta)])  # half a wheelbase ahead
    assert np.allclose(body[:4].mean(axis=0), centre)
    errors = errors_figure(run).axes[0]
    assert errors.get_yscale() == "log"
    assert np.array_equal(errors.lines[0].get_ydata(), [r["cartesian_error"] for r in saturated["trials"]])
    dashed = [line for line in errors.lines if line.get_linestyle() == "--"]
    assert [line.get_ydata()[0] for line in dashed] == [5e-4]  # equal tolerances: one line, named for both
    assert dashed[0].get_label() == "tolerance 0.0005 (Cartesian, orientation)"
    panels = coordinates_figure(run).axes
    assert [ax.get_ylabel() for ax in panels] == ["x [m]", "y [m]", "θ [rad]", "φ [rad]"]
    assert np.array_equal(panels[3].lines[0].get_ydata(), last.q[:, 3])
    assert sorted(line.get_ydata()[0] for line in panels[3].lines[1:]) == pytest.approx([-np.pi / 4, np.pi / 4])


def test_cyclic_arrivals_are_numbered_in_order(cyclic):
    run = load_run(cyclic)
    ax = path_figure(run).axes[0]
    numbers = [t.get_text() for t in ax.texts if t.get_text().isdigit()]
    assert numbers == [str(k) for k in range(1, 3 * 2 + 1)]
    second = next(t for t in ax.texts if t.get_text() == "2")  # home after the first cycle (the paper's "2")
    assert np.allclose(second.xy, cyclic["cycles"][0]["waypoints"][1]["final_state"][:2])


@pytest.mark.slow  # figures, twice
def test_cli_run_and_plot_write_the_same_figures(tmp_path, capsys):
    run_json = tmp_path / "run.json"
    assert (
        main(
            [
                "run",
                "parallel_parking",
                "--trials",
                "2",
                "--hold",
                "2",
                "--json",
                str(run_json),
                "--plots",
                str(tmp_path / "a"),
            ]
        )
        == 1
    )
    assert main(["plot", str(run_json), "--out", str(tmp_path / "b")]) == 0
    written = sorted(p.name for p in (tmp_path / "a").iterdir())
    assert written == sorted(p.name for p in (tmp_path / "b").iterdir()) and len(written) == 4
    assert "wrote" in capsys.readouterr().out


def test_bad_run_files_are_named(tmp_path, capsys):
    assert main(["plot", str(tmp_path / "missing.json"), "--out", str(tmp_path)]) == 2
    assert "cannot read" in capsys.readouterr().err
    not_a_run = tmp_path / "other.json"
    not_a_run.write_text('{"name": "x"}')
    assert main(["plot", str(not_a_run), "--out", str(tmp_path)]) == 2
    assert "not a run's JSON" in capsys.readouterr().err
    bare = run_ilc("forward_parking", trials=1).to_json()  # no trajectories recorded
    with pytest.raises(ValueError, match="no trajectories"):
        write_plots(bare, tmp_path)
    with pytest.raises(ValueError, match="malformed cycles"):
        load_run({**bare, "kind": "cycles"})
    bare["config"]["plant"]["wheelbase"] = -1.0
    with pytest.raises(ValueError, match="wheelbase"):
        load_run(bare)
