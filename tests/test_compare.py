"""The comparison benchmark: trial counting, the baselines, resumable run folders, and its output."""

import csv
import json

import gymnasium as gym
import numpy as np
import pytest

from ilc_steering import compare
from ilc_steering.agents.adapters import PullLearner
from ilc_steering.agents.rl import RL_ALGORITHMS, check_hyperparameters, hyperparameters
from ilc_steering.compare import Args, TrialLog, run_cell, run_cells
from ilc_steering.config import ConfigError
from ilc_steering.loop import run_trials

TINY = dict(seeds=(0, 1), ilc_trials=5, blackbox_trials=30, rl_trials=24, progress_bar=False)


def test_trial_log_counts_every_trial_and_refuses_one_past_the_budget():
    env = gym.make("ilc_steering/ChainedSteering-v0", config="forward_parking")
    c = env.unwrapped.nominal_model.solve()
    asked = []

    def forever(port):  # an optimizer that never stops asking for trials
        while True:
            port.reset()
            asked.append(port.step(c))

    learner = PullLearner(forever, env.action_space, env.observation_space)
    log = TrialLog()
    rollout = run_trials(env, learner, 3, callbacks=[log])
    assert len(rollout) == 3 and len(asked) == 3  # the fourth step was stopped inside the optimizer
    assert len(log.cartesian) == 3
    np.testing.assert_allclose(log.cartesian, 0.1, rtol=1e-6)  # the 10% perturbation
    assert compare.first_within(log, (0.2, 0.2)) == 1 and compare.first_within(log, (0.01, 0.01)) is None


def test_ilc_cell_counts_the_papers_trials():
    cell = run_cell(Args(**TINY), "ilc", "forward_parking", 0)
    assert cell["trials"] == 5 and cell["trials_to_loose"] == 2 and cell["trials_to_tight"] == 4
    assert [p[0] for p in cell["curve"]] == [1, 2, 3, 4, 5]  # the error falls every trial


def test_gauss_newton_reaches_the_tight_tolerance_and_every_probe_counts():
    cell = run_cell(Args(**{**TINY, "blackbox_trials": 400}), "gauss_newton", "forward_parking", 0)
    assert cell["trials"] == 400  # the budget wrapper stopped it, not the method
    assert cell["trials_to_tight"] is not None and cell["best_error"] < 1e-4


@pytest.mark.parametrize("method", ["nelder_mead", "cma_es", *RL_ALGORITHMS])
def test_every_baseline_spends_exactly_its_budget(method):
    cell = run_cell(Args(**TINY), method, "parallel_parking", 1)
    assert cell["trials"] == cell["budget"] == (24 if method in RL_ALGORITHMS else 30)
    assert np.isfinite(cell["best_error"])


def test_rl_hyperparameter_files_load_and_unknown_keys_are_named():
    for algorithm in RL_ALGORITHMS:
        for scenario in compare.SCENARIOS:
            assert hyperparameters(algorithm, scenario)["n_timesteps"] >= 1000
    with pytest.raises(ConfigError, match=r"ppo.yaml: forward_parking.n_step: unknown key for PPO"):
        check_hyperparameters("ppo", {"n_timesteps": 10, "n_step": 64}, "configs/rl/ppo.yaml: forward_parking")
    with pytest.raises(ConfigError, match="no hyperparameters for scenario 'chained_perturbed'"):
        hyperparameters("sac", "chained_perturbed")


def test_interrupted_run_resumes_without_recomputing_finished_cells(tmp_path):
    args = Args(out=tmp_path, methods=("ilc", "gauss_newton"), scenarios=("forward_parking",), **TINY)
    calls = []

    def interrupted(a, method, scenario, seed):
        if len(calls) == 2:
            raise KeyboardInterrupt  # the user pressed Ctrl-C during the third cell
        calls.append((method, seed))
        return run_cell(a, method, scenario, seed)

    with pytest.raises(KeyboardInterrupt):
        run_cells(args, interrupted)
    finished = {p.name: p.read_text() for p in (tmp_path / "cells").glob("*.json")}
    assert sorted(finished) == ["ilc__forward_parking__0.json", "ilc__forward_parking__1.json"]
    assert not list((tmp_path / "cells").glob("*.tmp"))

    resumed = []
    cells = run_cells(args, lambda a, m, s, seed: resumed.append((m, seed)) or run_cell(a, m, s, seed))
    assert resumed == [("gauss_newton", 0), ("gauss_newton", 1)]  # only the missing cells
    assert len(cells) == 4
    for name, text in finished.items():
        assert (tmp_path / "cells" / name).read_text() == text  # finished cells untouched

    with pytest.raises(ValueError, match="use another --out folder"):
        run_cells(Args(**{**args.__dict__, "blackbox_trials": 31}))


def test_main_writes_well_formed_results(tmp_path):
    args = Args(
        out=tmp_path, methods=("ilc", "nelder_mead", "ppo"), scenarios=("forward_parking", "parallel_parking"), **TINY
    )
    compare.main(args)
    with open(tmp_path / "compare.csv") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 3 * 2 * 2 and {"method", "scenario", "seed", "trials_to_tight", "best_error", "wall_s"} <= set(
        rows[0]
    )
    data = json.loads((tmp_path / "compare.json").read_text())
    assert len(data["summary"]) == 6 and len(data["cells"]) == 12
    table = (tmp_path / "compare.md").read_text()
    assert "| forward_parking | ilc | 5 | 2 [2, 2] (2/2) | 4 [4, 4] (2/2) |" in table
    assert "> 24 (0/2)" in table  # PPO does not get there in 24 trials, and says so
    assert (tmp_path / "compare.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
