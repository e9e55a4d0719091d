"""A robot defined outside the package (``tests/toy_robot.py``, a module in a temporary folder,
with its own field, map, chart and config keys) runs through everything after one registry line:
``register`` in this process, an entry point in the CLI's."""

import os
import shutil
import subprocess
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import ilc_steering  # noqa: F401  (registers the envs)
from ilc_steering.agents import ILCAgent
from ilc_steering.config import load_config
from ilc_steering.core import robots
from ilc_steering.core.reference import trial
from ilc_steering.envs.scenario import Scenario
from ilc_steering.envs.steering_vector_env import ChainedSteeringVectorEnv
from ilc_steering.errors import ConfigError
from ilc_steering.loop import run_trials

HERE = Path(__file__).parent


@pytest.fixture
def skate(tmp_path, monkeypatch):
    """The toy robot's module in a folder of its own, importable, installed as a distribution with
    an entry point (for other processes), and registered here with one line; the YAML path."""
    shutil.copy(HERE / "toy_robot.py", tmp_path / "toy_robot.py")
    info = tmp_path / "toy_robot-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: toy-robot\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text("[ilc_steering.robots]\nskate = toy_robot:SkatePlantConfig\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setattr(robots, "ROBOTS", dict(robots.ROBOTS))
    monkeypatch.setattr(robots, "_LOADED", dict(robots._LOADED))
    robots.register("skate", "toy_robot:SkatePlantConfig")  # the one line
    import toy_robot

    path = tmp_path / "skate_parking.yaml"
    path.write_text(toy_robot.CONFIG)
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join([str(tmp_path), os.environ.get("PYTHONPATH", "")]))
    return path


def test_an_unregistered_robot_is_refused_by_name(tmp_path):
    path = tmp_path / "skate_parking.yaml"
    path.write_text((HERE / "toy_robot.py").read_text().split('CONFIG = """\\\n')[1].split('"""')[0])
    with pytest.raises(ConfigError, match=r"plant\.model: must be one of \['car', 'chained'.*got 'skate'"):
        load_config(path)


@pytest.mark.slow  # compiles the robot's kernel
def test_the_robot_runs_through_the_env_and_the_vector_env_and_learns(skate):
    env = gym.make("ilc_steering/ChainedSteering-v0", config=str(skate))
    rollout = run_trials(env, ILCAgent(env.unwrapped.nominal_model), 6)
    errors = [info["cartesian_error"] for info in rollout.infos]
    assert errors[-1] < 1e-3 * errors[0]  # eqs. 33-34 contract by the gains' mismatch
    vector = ChainedSteeringVectorEnv(5, config=str(skate), true_factors=np.linspace(0.8, 1.2, 10).reshape(5, 2))
    vector.reset(seed=0)
    obs, reward, *_ = vector.step(np.tile(rollout.infos[0]["action"], (5, 1)).astype(np.float32))
    assert obs.shape[0] == 5 and np.all(np.isfinite(reward)) and len(set(reward.tolist())) == 5


@pytest.mark.slow  # compiles the robot's kernel, tight solve_ivp
def test_the_robot_s_kernel_matches_its_own_solve_ivp_reference_within_1e_9(skate):
    scenario = Scenario.from_config(load_config(skate))
    c = scenario.nominals[0].solve() * np.array([1.05, 0.9, 1.1])
    final = scenario.run(c[None]).final[0]
    np.testing.assert_allclose(final, trial(scenario.plant, scenario.profile, scenario.x_start, c), rtol=0, atol=1e-9)


@pytest.mark.slow  # run, sweep and compare
def test_the_robot_runs_through_run_sweep_and_compare(skate, tmp_path):
    def cli(*args):
        done = subprocess.run(
            [sys.executable, "-m", "ilc_steering", *args], capture_output=True, text=True, timeout=600, cwd=tmp_path
        )
        assert done.returncode == 0, (args, done.stdout[-2000:], done.stderr[-2000:])
        return done.stdout

    assert "converged at trial" in cli("run", str(skate))  # and exit 0: learning converged
    cli("sweep", str(skate), "--grid", "3", "--trials", "8", "--out", str(tmp_path / "sweep"), "--workers", "1")
    assert (tmp_path / "sweep" / "sweep.json").is_file()
    out = tmp_path / "compare"
    cli("compare", "--quick", "--scenarios", str(skate), "--methods", "ilc", "newton_ilc", "--priors", "nominal",
        "--seeds", "0", "--out", str(out), "--workers", "1")  # fmt: skip
    assert (out / "compare.json").is_file()


def test_the_guides_outline_takes_one_configuration_or_a_batch(skate):
    from toy_robot import SkateMap

    one = SkateMap().outline(np.array([0.0, 0.0, 0.3]))[0][0]
    batch = SkateMap().outline(np.array([[0.0, 0.0, 0.3], [1.0, 2.0, -0.2]]))[0][0]
    assert one.shape == (4, 2) and batch.shape == (2, 4, 2)
    np.testing.assert_allclose(batch[0], one)
    np.testing.assert_allclose(one[0], [0.1 * np.cos(0.3), 0.1 * np.sin(0.3)])  # the tip, 0.1 m ahead


@pytest.mark.slow
def test_the_guides_robot_passes_check_env_with_rendering(skate):
    from gymnasium.utils.env_checker import check_env

    env = gym.make("ilc_steering/ChainedSteering-v0", config=str(skate), render_mode="rgb_array")
    check_env(env.unwrapped)  # render check included: outline draws a batch of configurations
    env.reset(seed=0)
    env.step(env.unwrapped.nominal_model.solve().astype(np.float32))
    frame = env.render()
    assert frame.ndim == 3 and frame.shape[2] == 3 and frame.std() > 0


def test_a_robot_from_module_colon_class_loads_without_registering(skate, tmp_path, monkeypatch):
    monkeypatch.setattr(robots, "ROBOTS", {k: v for k, v in robots.ROBOTS.items() if k != "skate"})
    monkeypatch.setattr(robots, "_LOADED", {})
    path = tmp_path / "by_class.yaml"
    path.write_text(skate.read_text().replace("model: skate", "model: toy_robot:SkatePlantConfig"))
    assert load_config(path).plant.model == "skate"


@pytest.mark.slow  # three fresh processes, each compiling the robot's kernel
def test_a_robot_from_module_colon_class_runs_through_run_compare_and_sweep(tmp_path):
    # No entry point and no register(): the YAML names the class, and each process (the workers
    # of compare and sweep included) imports it from PYTHONPATH.
    shutil.copy(HERE / "toy_robot.py", tmp_path / "toy_robot.py")
    config = (HERE / "toy_robot.py").read_text().split('CONFIG = """\\\n')[1].split('"""')[0]
    path = tmp_path / "by_class.yaml"
    path.write_text(config.replace("model: skate", "model: toy_robot:SkatePlantConfig"))
    env = {**os.environ, "PYTHONPATH": str(tmp_path)}
    commands = {
        "run": ["run", str(path), "--trials", "3"],
        "compare": ["compare", "--scenarios", str(path), "--methods", "ilc_paper", "newton", "--seeds", "0",
                    "--priors", "nominal", "--model-trials", "3", "--blackbox-trials", "3",
                    "--workers", "1", "--out", str(tmp_path / "compare")],
        "sweep": ["sweep", str(path), "--grid", "2", "--trials", "3", "--workers", "1",
                  "--out", str(tmp_path / "sweep")],
    }  # fmt: skip
    for name, arguments in commands.items():
        done = subprocess.run(
            [sys.executable, "-m", "ilc_steering", *arguments], env=env, cwd=tmp_path, capture_output=True, text=True
        )
        assert done.returncode in (0, 1), f"{name}: exit {done.returncode}: {done.stderr[-400:]}"
        assert "Traceback" not in done.stderr, f"{name}: {done.stderr[-400:]}"
    assert (tmp_path / "compare" / "compare.json").is_file() and (tmp_path / "sweep" / "sweep.json").is_file()


@pytest.mark.slow  # two fresh processes, the skate's kernel compiled
@pytest.mark.parametrize("where", ["beside", "elsewhere"])
def test_a_robot_module_beside_its_config_runs_through_the_installed_script(tmp_path, where):

    folder = tmp_path / "robot"
    folder.mkdir()
    shutil.copy(HERE / "toy_robot.py", folder / "toy_robot.py")
    text = (HERE / "toy_robot.py").read_text().split('CONFIG = """\\\n')[1].split('"""')[0]
    (folder / "skate.yaml").write_text(text.replace("model: skate", "model: toy_robot:SkatePlantConfig"))
    cwd = folder if where == "beside" else tmp_path
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    script = Path(sys.executable).parent / "ilc-steering"
    command = [str(script)] if script.exists() else [sys.executable, "-m", "ilc_steering"]
    result = subprocess.run(
        [*command, "run", str(folder / "skate.yaml"), "--trials", "2", "--hold", "2"],
        capture_output=True,
        text=True,
        cwd=cwd,
        env=env,
    )
    assert result.returncode in (0, 1), result.stderr[-2000:]  # converged or not: it ran, the module was found
    assert "skate_parking: 2 trials" in result.stdout, result.stdout[-2000:]
    assert [line.split()[0] for line in result.stdout.splitlines() if line[:5].strip().isdigit()] == ["1", "2"]
