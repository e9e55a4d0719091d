"""The comparison benchmark: trial counting, the priors, the baselines, resumable run folders, users'
learners, parallel workers, and its output."""

import csv
import json
import math
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import ilc_steering  # noqa: F401  (registers the envs)
from ilc_steering.agents import rl
from ilc_steering.agents.adapters import PullLearner
from ilc_steering.agents.base import LearnerContext
from ilc_steering.agents.rl_settings import RL_ALGORITHMS, check_hyperparameters, hyperparameters
from ilc_steering.boxes import RESIDUAL_SCALE
from ilc_steering.compare import cells as compare_cells
from ilc_steering.compare import command as compare
from ilc_steering.compare import stats as compare_report
from ilc_steering.compare.args import Args
from ilc_steering.compare.cells import TrialLog, run_cell
from ilc_steering.compare.command import run_cells
from ilc_steering.core.score import OFF_CHART_PENALTY
from ilc_steering.errors import ConfigError
from ilc_steering.loop import run_trials

CONFIGS = Path(__file__).resolve().parents[1] / "configs"
TINY = dict(seeds=(0, 1), model_trials=5, blackbox_trials=30, rl_trials=24, workers=1)


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
    assert compare_cells.first_within(log, 0.2) == 1 and compare_cells.first_within(log, 0.01) is None


def test_ilc_cells_count_the_papers_trials_and_the_nominal_start():
    paper = run_cell(Args(**TINY), "nominal", "ilc_paper", "forward_parking", 0)
    # the law cuts the error exactly tenfold a trial from 10 cm, so trials 2 and 3 land *on* 1 cm and 1 mm:
    # a level is met when the error is at most it, so the integrator's last digits decide there, and the
    # cell says so (compare.FRAGILE); the paper's count (1 cm at trial 2, 1 mm at 3) is one of the two readings
    assert paper["trials"] == 5 and paper["trials_to"] == {"10cm": 1, "1cm": 3, "1mm": 4, "0.5mm": 4}
    assert paper["fragile"] == ["10cm", "1cm", "1mm"]
    assert [p[0] for p in paper["curve"]] == [1, 2, 3, 4, 5]  # the error falls every trial
    args = Args(**{**TINY, "model_trials": 8})
    assert run_cell(args, "nominal", "ilc_paper", "parallel_parking", 0)["trials_to"]["0.5mm"] == 5
    # from solve(), the error falls tenfold a trial from 5 cm: the third lands on 0.5 mm (to 1e-12), so its
    # count is 3 or 4 by the integrator's last digits, and the cell flags it as fragile
    ilc = run_cell(args, "nominal", "ilc", "parallel_parking", 0)
    assert ilc["trials_to"]["0.5mm"] in (3, 4) and ilc["fragile"] == ["0.5mm"]


def test_a_level_is_met_at_most_at_the_level_and_a_count_on_the_level_is_flagged():
    log = TrialLog()
    for error in (0.01 * (1 + 1e-12), 0.01 * (1 + 1e-6), 0.01 * (1 - 1e-12)):
        log.cartesian.append(error)
        log.orientation.append(0.0)
        log.left_chart.append(False)
    assert compare_cells.first_within(log, 0.01) == 3  # no slack: 1e-12 above the level is not within it
    assert "1cm" in compare_cells.fragile_levels(log)  # and a change of 1e-6 would move the count to trial 1
    log.cartesian[:] = [0.01 * (1 + 1e-5), 0.01 * (1 - 1e-5), 0.0]
    assert compare_cells.first_within(log, 0.01) == 2 and compare_cells.fragile_levels(log) == []


def test_least_squares_counts_every_jacobian_probe():
    # LM with a 2-point Jacobian from the nominal solution: 1 + 4 probes + the step, per iteration
    cell = run_cell(Args(**{**TINY, "blackbox_trials": 60}), "nominal", "least_squares", "forward_parking", 0)
    assert cell["trials"] == 60  # the budget stopped it, not the method
    assert cell["trials_to"]["1cm"] == 6 and cell["trials_to"]["0.5mm"] == 11 and cell["best_error"] < 1e-9


def test_gauss_newton_reaches_the_tight_tolerance_without_a_prior():
    cell = run_cell(Args(**{**TINY, "blackbox_trials": 400}), "none", "gauss_newton", "forward_parking", 0)
    assert cell["trials"] == 400 and cell["trials_to"]["0.5mm"] is not None and cell["best_error"] < 1e-4


@pytest.mark.parametrize("prior", ["nominal", "none"])
@pytest.mark.parametrize(
    "method",
    ["newton", "nelder_mead", *(pytest.param(m, marks=pytest.mark.extra("rl")) for m in ("cma_es", *RL_ALGORITHMS))],
)
@pytest.mark.slow  # RL trainings
def test_every_baseline_spends_exactly_its_budget(method, prior):
    cell = run_cell(Args(**TINY), prior, method, "parallel_parking", 1)
    budget = 5 if method == "newton" else 24 if method in RL_ALGORITHMS else 30
    assert cell["trials"] == cell["budget"] == budget
    assert np.isfinite(cell["best_error"])


@pytest.mark.parametrize("method", [m for m in compare.METHODS if m != "ilc_paper"])
@pytest.mark.slow  # every method, RL included
def test_every_methods_first_trial_is_the_conditions_start(method):
    env = gym.make("ilc_steering/ChainedSteering-v0", config="forward_parking")
    u = env.unwrapped
    for prior in ("nominal", "none"):
        context = LearnerContext(u.nominal_model, u.action_space, u.observation_space, 3, prior=prior)
        learner = compare_cells.make_learner(Args(**TINY), method, "forward_parking", context)
        first = run_trials(env, learner, 2, seed=3).infos[0]["action"]
        expected = u.nominal_model.solve() if prior == "nominal" else context.first_action()
        np.testing.assert_allclose(first, expected, rtol=1e-12, atol=1e-12)
    centre, half = context.search_box()  # prior none: the whole action box
    np.testing.assert_array_equal(half, u.action_space.high)


@pytest.mark.slow
def test_the_residual_box_holds_every_packaged_solution():
    for name in ("forward_parking", "forward_parking_saturated", "parallel_parking", "chained_perturbed"):
        env = gym.make("ilc_steering/ChainedSteering-v0", config=name)
        u = env.unwrapped
        context = LearnerContext(u.nominal_model, u.action_space, u.observation_space)
        rollout = run_trials(env, compare_cells.make_learner(Args(), "ilc", name, context), 12)
        centre, half = context.search_box()
        np.testing.assert_array_equal(half, RESIDUAL_SCALE * u.nominal_model.action_scale())
        inside = np.abs(rollout.infos[-1]["action"] - centre) / half
        assert inside.max() < 0.75, (name, inside)  # the solution, with margin


@pytest.mark.extra("rl")
def test_rl_deterministic_trials_start_at_the_nominal_solution_and_are_counted():
    env = gym.make("ilc_steering/ChainedSteering-v0", config="forward_parking")
    u = env.unwrapped
    context = LearnerContext(u.nominal_model, u.action_space, u.observation_space, 0)
    params = {**hyperparameters("td3", "forward_parking"), "learning_starts": 100, "eval_every": 4}
    rollout = run_trials(env, rl.make_learner("td3", params, 12, False, context), 12, seed=0)
    c0 = u.nominal_model.solve()
    at_start = [bool(np.allclose(info["action"], c0, rtol=0, atol=1e-12)) for info in rollout.infos]
    # trial 1: the start; then 4 random training trials and a deterministic trial of the untrained
    # policy, whose zeroed output layer acts at the nominal solution
    assert at_start == [True, False, False, False, False, True, False, False, False, False, True, False]


def test_an_off_chart_trial_costs_the_penalty_and_never_sets_the_best_error():
    env = gym.make("ilc_steering/ChainedSteering-v0", config="forward_parking")
    c = env.unwrapped.nominal_model.solve() * np.array([1.0, 60.0, 60.0, 60.0])  # steers the wheel off the chart
    env.reset(seed=0)
    _, reward, _, _, info = env.step(c)
    assert info["left_chart"]  # it halted where it left, and is scored from there
    assert info["cartesian_error"] == pytest.approx(np.hypot(*info["q_final"][:2]), rel=1e-12)  # the goal: (0, 0)
    assert reward == pytest.approx(-(info["cartesian_error"] + info["orientation_error"] + OFF_CHART_PENALTY))
    log = TrialLog()
    log(1, info)
    assert compare_cells.first_within(log, 10.0) is None and compare_cells.best_so_far(log)[0][1] > OFF_CHART_PENALTY


@pytest.mark.extra("rl")
def test_rl_hyperparameter_files_load_and_unknown_keys_are_named():
    for algorithm in RL_ALGORITHMS:
        for prior in ("nominal", "none"):
            for scenario in compare.SCENARIOS:
                assert hyperparameters(algorithm, scenario, prior)["n_timesteps"] >= 1000
            assert hyperparameters(algorithm, "chained_perturbed", prior)["eval_every"] >= 1  # the default
    with pytest.raises(ConfigError, match=r"ppo.yaml: nominal.default.n_step: unknown key for PPO"):
        check_hyperparameters("ppo", {"n_timesteps": 10, "n_step": 64}, "configs/rl/ppo.yaml: nominal.default")
    with pytest.raises(ConfigError, match="initial_std: SAC, CrossQ, TQC only"):
        check_hyperparameters("td3", {"n_timesteps": 10, "initial_std": 0.1}, "td3")
    with pytest.raises(ValueError, match="prior must be one of"):
        hyperparameters("sac", "forward_parking", "optimistic")


def test_interrupted_run_resumes_without_recomputing_finished_cells(tmp_path):
    args = Args(
        out=tmp_path, priors=("nominal",), methods=("ilc", "gauss_newton"), scenarios=("forward_parking",), **TINY
    )
    calls = []

    def interrupted(a, prior, method, scenario, seed):
        if len(calls) == 2:
            raise KeyboardInterrupt  # the user pressed Ctrl-C during the third cell
        calls.append((method, seed))
        return run_cell(a, prior, method, scenario, seed)

    with pytest.raises(KeyboardInterrupt):
        run_cells(args, interrupted)
    finished = {p.name: p.read_text() for p in (tmp_path / "cells").glob("*.json")}
    assert sorted(finished) == ["nominal__ilc__forward_parking__0.json", "nominal__ilc__forward_parking__1.json"]
    assert not list((tmp_path / "cells").glob("*.tmp"))

    resumed = []
    cells = run_cells(args, lambda a, p, m, s, seed: resumed.append((m, seed)) or run_cell(a, p, m, s, seed))
    assert resumed == [("gauss_newton", 0), ("gauss_newton", 1)]  # only the missing cells
    assert len(cells) == 4
    for name, text in finished.items():
        assert (tmp_path / "cells" / name).read_text() == text  # finished cells untouched

    with pytest.raises(ValueError, match="use another --out folder"):
        run_cells(Args(**{**args.__dict__, "blackbox_trials": 31}))


def test_a_clone_without_cells_resumes_from_compare_json(tmp_path):
    import shutil

    args = Args(out=tmp_path, priors=("nominal",), methods=("ilc",), scenarios=("forward_parking",), **TINY)
    compare.main(args)
    before = json.loads((tmp_path / "compare.json").read_text())["cells"]
    shutil.rmtree(tmp_path / "cells")  # what a clone of a committed run folder holds: run.json and compare.json

    def never(*call):
        raise AssertionError(f"recomputed {call[1:]}")

    cells = run_cells(args, never)
    assert [c["trials_to"] for c in cells] == [c["trials_to"] for c in before]
    assert len(list((tmp_path / "cells").glob("*.json"))) == len(before)


@pytest.mark.slow  # worker processes
@pytest.mark.extra("rl")  # td3
def test_workers_give_the_cells_of_one_process(tmp_path):
    settings = dict(
        priors=("nominal", "none"), methods=("ilc", "least_squares", "td3"), scenarios=("forward_parking_noisy",)
    )
    serial = run_cells(Args(out=tmp_path / "serial", **settings, **TINY))
    parallel = run_cells(Args(out=tmp_path / "parallel", **settings, **{**TINY, "workers": 2}))
    assert len(serial) == len(parallel) == 12
    for a, b in zip(serial, parallel):
        timings = ("wall_s", "update_s")
        assert {k: v for k, v in a.items() if k not in timings} == {k: v for k, v in b.items() if k not in timings}


USER_LEARNER = '''
import numpy as np

from ilc_steering.agents.newton import nominal_jacobian


class Broyden:
    """Secant steps: the nominal Jacobian at the start, corrected after each trial by what the trial
    measured (Broyden's rank-one update), so the model error is learned along the way."""

    def __init__(self, context):
        self.context = context
        self.reset()

    def reset(self):
        self.c = self.context.first_action()  # the nominal solution, under prior=nominal
        self.J = nominal_jacobian(self.context.model, self.c)
        self.last = None

    def act(self, observation):
        return self.c.copy()

    def learn(self, info):
        c, error = np.asarray(info["action"]), np.asarray(info["error"])
        if self.last is not None:
            dc, dz = c - self.last[0], self.last[1] - error  # how far the final state moved
            self.J += np.outer(dz - self.J @ dc, dc) / (dc @ dc)
        self.last = (c, error)
        self.c = c + np.linalg.lstsq(self.J, error, rcond=None)[0]


def make(context):
    return Broyden(context)


not_a_factory = 3
'''


@pytest.mark.slow  # a comparison on two workers
def test_a_users_learner_and_a_yaml_scenario_from_outside_the_package(tmp_path, monkeypatch, capsys):
    from ilc_steering.cli import main

    (tmp_path / "user_learners.py").write_text(USER_LEARNER)
    monkeypatch.syspath_prepend(str(tmp_path))
    source = (CONFIGS / "parallel_parking.yaml").read_text()
    scenario = tmp_path / "my_bay.yaml"
    scenario.write_text(source.replace("name: parallel_parking", "name: my_bay"))
    out = tmp_path / "run"
    argv = ["compare", "--quick", "--out", str(out), "--priors", "nominal", "--seeds", "0"]
    argv += ["--methods", "ilc", "user_learners:make", "--scenarios", str(scenario), "--workers", "2"]
    assert main(argv) == 0
    table = (out / "compare.md").read_text()
    assert "| my_bay | user_learners:make | 20 |" in table and "| my_bay | ilc | 6 |" in table
    cells = json.loads((out / "compare.json").read_text())["cells"]
    user = next(c for c in cells if c["method"] == "user_learners:make")
    assert user["trials"] == 20 and user["trials_to"]["0.5mm"] == 3  # secant steps beat eqs. 33-34 here
    assert (out / "cells" / "nominal__user_learners_make__my_bay__0.json").exists()
    for method, message in (
        ("user_learners:nope", "cannot import it"),
        ("no_such_module:make", "cannot import it"),
        ("user_learners:not_a_factory", "not callable"),
    ):
        assert main(["compare", "--quick", "--out", str(tmp_path / "bad"), "--methods", method]) == 2
        assert message in capsys.readouterr().err


@pytest.mark.slow  # a comparison with PPO
@pytest.mark.extra("rl")
def test_main_writes_well_formed_results(tmp_path):
    args = Args(
        out=tmp_path,
        methods=("ilc", "nelder_mead", "ppo"),
        scenarios=("forward_parking", "parallel_parking"),
        **TINY,
    )
    compare.main(args)
    with open(tmp_path / "compare.csv") as f:
        rows = list(csv.DictReader(f))
    fields = {"prior", "method", "scenario", "seed", "trials_to_1cm", "trials_to_0.5mm", "best_error", "wall_s"}
    assert len(rows) == 2 * 3 * 2 * 2 and fields <= set(rows[0])
    data = json.loads((tmp_path / "compare.json").read_text())  # strict JSON: no Infinity
    assert len(data["summary"]) == 12 and len(data["cells"]) == 24 and data["ratios"]
    table = (tmp_path / "compare.md").read_text()
    assert "### prior=nominal" in table and "### prior=none" in table
    # the counts that land on their level (1 cm at trial 2 or 3, 1 mm at 3 or 4) are marked fragile
    row = "| forward_parking | ilc | 5 | 1 [1, 1] (2/2) † | 3 [3, 3] (2/2) † | 4 [4, 4] (2/2) † | 4 [4, 4] (2/2) |"
    assert row in table and "†: in some seed, a relative change of 1e-6" in table
    assert "> 24 (0/2)" in table  # PPO does not get there in 24 trials, and says so
    for scenario in args.scenarios:
        assert (tmp_path / f"compare_{scenario}.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_bootstrap_interval_and_quartiles_keep_not_reached_as_infinite():
    assert compare_report.bootstrap_median([4, 4, 4, 4]) == (4, 4)
    low, high = compare_report.bootstrap_median([3, 4, 5, 6, 7, 8, 9, 10, 11, 12])
    assert 3 <= low <= 7.5 <= high <= 12  # the median lies inside its interval
    assert compare_report.quartiles([1, 2, math.inf, math.inf]) == (1, 2, math.inf)
    assert compare_report.bootstrap_median([math.inf] * 5) == (math.inf, math.inf)


def test_ratios_name_the_best_of_each_family():
    def cell(method, reached):
        trials_to = {level: reached for level in compare_report.LADDER}
        return {"prior": "nominal", "scenario": "s", "method": method, "budget": 100, "trials_to": trials_to,
                "best_error": 1e-3, "off_chart_fraction": 0.0, "wall_s": 1.0}  # fmt: skip

    cells = [cell("ilc", 4), cell("least_squares", 12), cell("cma_es", 80), cell("td3", None), cell("ppo", 400)]
    families = {"black-box": compare.BLACKBOX, "RL": compare.RL}
    entries = compare_report.ratios(compare_report.summarize(cells), families)
    assert len(entries) == len(compare_report.LADDER)
    first = entries[0]
    assert first["black-box"] == {"method": "least_squares", "median": 12.0, "ratio": 3.0}
    assert first["RL"] == {"method": "ppo", "median": 400.0, "ratio": 100.0}


def test_least_squares_uses_trf_where_lm_lacks_residuals(tmp_path):
    source = (CONFIGS / "forward_parking.yaml").read_text()
    path = tmp_path / "five_terms.yaml"
    path.write_text(source.replace("v2_terms: 3 ", "v2_terms: 5 ").replace("name: forward_parking", "name: five"))
    cell = run_cell(Args(**{**TINY, "blackbox_trials": 60}), "nominal", "least_squares", str(path), 0)
    assert cell["trials"] == 60 and cell["trials_to"]["1cm"] is not None  # 6 coefficients, 5 residuals


def test_a_committed_run_that_records_no_seeds_is_refused_as_its_bad_input(tmp_path):
    """A run.json without one of the settings a run records (here its seeds) is the committed run's
    fault, said in one line naming it (exit 2), not a TypeError of the library (exit 3)."""
    from dataclasses import asdict, fields

    from ilc_steering import __version__
    from ilc_steering.compare.against import resolve_settings
    from ilc_steering.compare.args import Args
    from ilc_steering.compare.committed import CommittedRun
    from ilc_steering.compare.settings import resolve, run_settings
    from ilc_steering.errors import BadInput

    settings = run_settings(resolve(Args()))
    del settings["seeds"]
    committed = CommittedRun(tmp_path, settings, {}, label=f"--against {tmp_path}")
    defaults = {f.name: f.default for f in fields(Args)}
    with pytest.raises(BadInput, match=r"--against .*: its run.json records no 'seeds'"):
        resolve_settings(committed, asdict(Args()), defaults, __version__)
    settings["seeds"] = [0]
    assert resolve_settings(committed, asdict(Args()), defaults, __version__)["seeds"] == (0,)
