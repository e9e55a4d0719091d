"""RL Zoo as a client (issue 68): the packaged hyperparameter files in RL Zoo's own format carry
configs/rl/'s values, key by key; the wrappers and the callback they name do what the library's
RL training does; and, in the slow tier, ``python -m rl_zoo3.train`` trains with them on every
registered env and ``rl_zoo3.enjoy`` replays the model, while on ChainedSteering-v0 RL Zoo's
first trials are the library's own, trial by trial."""

import csv
import json
import os
import subprocess
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import yaml

import ilc_steering  # noqa: F401  (registers the envs)
from ilc_steering.agents.rl_settings import OWN_KEYS, RL_ALGORITHMS, hyperparameters, zoo_file
from ilc_steering.errors import BadInput

ROOT = Path(__file__).resolve().parents[1]
ENVS = ("ilc_steering/ChainedSteering-v0", "ilc_steering/CyclicSteering-v0", "ilc_steering/SegmentedSteering-v0")
RESIDUAL = {
    "ilc_steering/ChainedSteering-v0": "ilc_steering.envs.ResidualAction",
    "ilc_steering/CyclicSteering-v0": "ilc_steering.envs.ResidualAction",
    "ilc_steering/SegmentedSteering-v0": "ilc_steering.agents.rl_zoo.SegmentedResidualAction",
}
ZOO = "ilc_steering.agents.rl_zoo"


def translated(algorithm, env_id):
    """RL Zoo's entry for ``env_id`` that carries configs/rl/<algorithm>.yaml's nominal default:
    the algorithm's keys as they are, ``noise_std`` as RL Zoo's normal noise, the nominal prior as
    the wrappers, ``start_at_centre`` as the callback (``eval_every`` is RL Zoo's command line)."""
    params = hyperparameters(algorithm, "forward_parking", "nominal")
    entry = {key: value for key, value in params.items() if key not in OWN_KEYS}
    entry["n_timesteps"] = params["n_timesteps"]
    if "noise_std" in params:
        entry.update(noise_type="normal", noise_std=params["noise_std"])
    entry["env_wrapper"] = [RESIDUAL[env_id], f"{ZOO}.LogReward"]
    assert params["start_at_centre"] is True
    std = params.get("initial_std")
    entry["callback"] = [f"{ZOO}.StartAtCentre" if std is None else {f"{ZOO}.StartAtCentre": {"initial_std": std}}]
    return entry


@pytest.mark.extra("rl")  # configs/rl/ is read as the comparison reads it, checked against SB3's classes
@pytest.mark.parametrize("algorithm", RL_ALGORITHMS)
def test_the_zoo_file_carries_the_comparisons_settings_key_by_key(algorithm):
    table = yaml.safe_load(Path(zoo_file(algorithm)).read_text())  # as RL Zoo reads it
    assert sorted(table) == sorted(ENVS)
    for env_id in ENVS:
        assert table[env_id] == translated(algorithm, env_id), env_id
    eval_every = hyperparameters(algorithm, "forward_parking")["eval_every"]
    assert f"--eval-freq {eval_every} --eval-episodes 1" in (ROOT / "docs" / "usage.md").read_text()


def test_zoo_file_names_a_packaged_file_and_refuses_another_algorithm():
    for algorithm in RL_ALGORITHMS:
        path = Path(zoo_file(algorithm))
        assert path.is_file() and path.parent.name == "rl_zoo" and path.name == f"{algorithm}.yml"
    with pytest.raises(BadInput, match="algorithm must be one of"):
        zoo_file("a2c")


@pytest.mark.extra("rl")  # the module's callback is an SB3 callback
def test_log_reward_and_the_segmented_box_start_at_the_nominal_solution():
    """a = 0 is every segment's nominal solution, bit for bit, and the reward is -log10(cost)."""
    from ilc_steering.agents.rl_zoo import LogReward, SegmentedResidualAction

    env = LogReward(SegmentedResidualAction(gym.make("ilc_steering/SegmentedSteering-v0")))
    env.reset(seed=0)
    _, reward, _, _, info = env.step(np.zeros(env.action_space.shape, dtype=np.float32))
    nominal = np.concatenate([view.nominal_model.solve() for view in env.unwrapped.segment_views()])
    assert np.array_equal(info["action"], nominal)
    raw = gym.make("ilc_steering/SegmentedSteering-v0")
    raw.reset(seed=0)
    cost = -raw.step(nominal)[1]
    assert reward == -np.log10(cost) and 0.1 < cost < 10  # [m + rad]: the nominal solution misses
    with pytest.raises(BadInput, match="ResidualAction"):
        SegmentedResidualAction(gym.make("ilc_steering/ChainedSteering-v0"))


@pytest.mark.extra("rl")
def test_start_at_centre_zeroes_a_fresh_policy_and_leaves_a_trained_one(tmp_path):
    from stable_baselines3 import PPO, SAC

    from ilc_steering.agents.rl_zoo import StartAtCentre
    from ilc_steering.envs import ResidualAction

    env = ResidualAction(gym.make("ilc_steering/ChainedSteering-v0"))
    observation, _ = env.reset(seed=0)
    model = SAC("MlpPolicy", env, learning_starts=0, seed=0, device="cpu")
    assert np.abs(model.predict(observation, deterministic=True)[0]).max() > 1e-3
    StartAtCentre(initial_std=0.01).init_callback(model)
    assert np.array_equal(model.predict(observation, deterministic=True)[0], np.zeros(4))
    model.learn(4)  # four trials, updates after each: the policy moves off the centre
    model.save(tmp_path / "sac")
    trained = SAC.load(tmp_path / "sac", device="cpu")
    before = trained.predict(observation, deterministic=True)[0]
    assert np.abs(before).max() > 0
    StartAtCentre(initial_std=0.01).init_callback(trained)
    assert np.array_equal(trained.predict(observation, deterministic=True)[0], before)
    with pytest.raises(BadInput, match="initial_std is for a squashed-Gaussian policy"):
        StartAtCentre(initial_std=0.01).init_callback(PPO("MlpPolicy", env, device="cpu"))
    with pytest.raises(BadInput, match="initial_std"):
        StartAtCentre(initial_std=2.0)


# Every RL Zoo command of the slow tests runs in one fresh interpreter, as ``python -m`` runs it
# (runpy), one after the other: RL Zoo's imports (torch, optuna, its env packages) take about 5 s,
# paid once rather than per command.
DRIVER = """
import json, runpy, sys
for argv in json.loads(sys.argv[1]):
    sys.argv = argv
    runpy.run_module(argv[0], run_name="__main__", alter_sys=True)
"""


def zoo(commands, cwd):
    """Run RL Zoo's ``commands`` (argv lists, a module first) in one fresh interpreter in ``cwd``."""
    env = {**os.environ, "ILC_STEERING_RL_BACKEND": "sb3"}
    result = subprocess.run(
        [sys.executable, "-c", DRIVER, json.dumps(commands)],
        cwd=cwd,
        env=env,
        capture_output=True,
        text=True,
        timeout=900,
    )
    assert result.returncode == 0, f"{result.stdout[-2000:]}\n{result.stderr[-3000:]}"
    return result


def train(algorithm, env_id, budget, seed=0):
    return [
        *("rl_zoo3.train", "--algo", algorithm, "--env", env_id, "--gym-packages", "ilc_steering"),
        *("-conf", zoo_file(algorithm), "-f", "logs", "-n", str(budget), "--seed", str(seed)),
        *("--device", "cpu", "--num-threads", "1", "--verbose", "0"),
    ]


def run_folder(cwd, algorithm, env_id):
    """RL Zoo's folder of the first run of ``algorithm`` on ``env_id`` (``/`` in the id becomes ``-``)."""
    return cwd / "logs" / algorithm / f"{env_id.replace('/', '-')}_1"


@pytest.mark.slow
@pytest.mark.extra("rl", "zoo")
@pytest.mark.timeout(900)
def test_rl_zoo_trains_on_every_registered_env_and_replays(tmp_path):
    """PPO with the packaged file for one rollout (64 trials, its ``n_steps``: ``-n 1`` still
    collects one) on each env, then ``rl_zoo3.enjoy`` for 5 steps of the saved model."""
    commands = []
    for env_id in ENVS:
        commands.append(train("ppo", env_id, 1))
        commands.append(
            [
                *("rl_zoo3.enjoy", "--algo", "ppo", "--env", env_id, "--gym-packages", "ilc_steering"),
                *("-f", "logs", "-n", "5", "--no-render", "--deterministic", "--device", "cpu"),
            ]
        )
    out = zoo(commands, tmp_path).stdout
    for env_id in ENVS:
        folder = run_folder(tmp_path, "ppo", env_id)
        assert (folder / f"{env_id.replace('/', '-')}.zip").is_file()
        lengths = [int(row["l"]) for row in monitor(folder)]  # the episodes the rollout ended
        assert sum(lengths) == (60 if env_id == ENVS[1] else 64)  # the cycle: 3 episodes of 20 trials
    assert out.count("Loading latest experiment, id=1") == len(ENVS)


def monitor(folder):
    """The rows of RL Zoo's Monitor file, one per episode: its reward ``r`` (the env's, below the
    wrappers; 6 digits) and its length ``l``."""
    with open(folder / "0.monitor.csv") as file:
        next(file)  # the Monitor's JSON header
        return list(csv.DictReader(file))


def read_costs(folder):
    """Each trial's cost, ``-r``, on a one-trial env (an episode is a trial)."""
    return [-float(row["r"]) for row in monitor(folder)]


@pytest.mark.slow
@pytest.mark.extra("rl", "zoo")
@pytest.mark.timeout(900)
def test_rl_zoo_trains_as_the_library_does_trial_for_trial(tmp_path, monkeypatch):
    """Each algorithm's file on ChainedSteering-v0, seed 0: RL Zoo's first 16 trials cost what
    :func:`ilc_steering.agents.rl.train`'s do on SB3 with configs/rl/'s settings, to the Monitor's
    6 digits; the same training, not merely a similar one."""
    from ilc_steering.agents.rl import train as library_train
    from ilc_steering.envs import ResidualAction

    budget = 16  # below every eval_every (20): the library runs no deterministic trial in between
    zoo([train(algorithm, ENVS[0], budget) for algorithm in RL_ALGORITHMS], tmp_path)
    monkeypatch.setenv("ILC_STEERING_RL_BACKEND", "sb3")
    for algorithm in RL_ALGORITHMS:
        env = ResidualAction(Costs(gym.make(ENVS[0])))
        library_train(algorithm, env, hyperparameters(algorithm, "forward_parking"), seed=0, trials=budget)
        costs = env.env.costs[:budget]
        ours = read_costs(run_folder(tmp_path, algorithm, ENVS[0]))[:budget]
        np.testing.assert_allclose(ours, costs, rtol=1e-5, err_msg=algorithm)
        assert max(costs) / min(costs) > 1.01, algorithm  # the trials differ: the check can fail


class Costs(gym.Wrapper):
    """Records each trial's cost, ``-reward``."""

    def __init__(self, env):
        super().__init__(env)
        self.costs = []

    def step(self, action):
        result = self.env.step(action)
        self.costs.append(-float(result[1]))
        return result
