"""The learner registry: one table of method ids, one way to build a learner, one context."""

import dataclasses
import os
from pathlib import Path

import gymnasium as gym
import pytest

import ilc_steering
from ilc_steering import cli, reproduce, runner
from ilc_steering.agents import registry
from ilc_steering.agents.base import BaseLearner, Closable, LearnerContext, TimedUpdates, close_learner, update_times
from ilc_steering.agents.costs import NullSpaceCost
from ilc_steering.agents.ilc import ILCAgent
from ilc_steering.compare import cells as compare_cells
from ilc_steering.compare import command as compare
from ilc_steering.compare import settings as compare_settings
from ilc_steering.config import load_config
from ilc_steering.envs.steering_vector_env import ChainedSteeringVectorEnv
from ilc_steering.sweep import command as sweep
from ilc_steering.sweep import rows as sweep_rows


def with_cost(name="forward_parking", cost="path_length"):
    base = load_config(name)
    task = dataclasses.replace(base.task, v2_terms=5)
    return dataclasses.replace(base, task=task, learning=dataclasses.replace(base.learning, cost=cost))


def test_every_method_id_is_in_one_table_and_the_commands_tables_are_views_of_it():
    assert len(registry.METHODS) == len(set(registry.METHODS)) == len(registry.REGISTRY)
    assert compare.METHODS == registry.METHODS
    assert set(compare.MODEL_METHODS) | set(compare.BLACKBOX) | set(compare.RL) == set(registry.METHODS)
    assert compare.DEFAULT_METHODS == tuple(m for m in registry.METHODS if m != "crossq")
    assert (
        set(reproduce.SEEDED_LEARNERS) <= set(registry.METHODS) and runner.DEFAULT_LEARNER in reproduce.SEEDED_LEARNERS
    )
    for spec in registry.REGISTRY.values():
        assert spec.family in registry.FAMILIES[:-1]
        assert spec.budget_key in {f.name for f in dataclasses.fields(registry.Budgets)}


def test_an_id_means_one_learner_in_run_and_in_compare():
    env = gym.make("ilc_steering/ChainedSteering-v0", config="forward_parking")
    context = LearnerContext.from_env(env)
    for method in ("ilc", "ilc_paper"):
        a = runner.learner_spec(method).make(context, 5)
        b = compare_cells.make_learner(compare.Args(), method, "forward_parking", context)
        assert type(a) is type(b) and (a.act() == b.act()).all()
    assert runner.learner_spec("ilc").entry_point.endswith(":make_ilc")  # as in compare, not make_ilc_paper
    assert runner.learner_spec(runner.DEFAULT_LEARNER).entry_point.endswith(":make_ilc_paper")


def test_the_budgets_follow_the_registry_rule():
    budgets = registry.Budgets(model_trials=7, blackbox_trials=500, rl_trials=9, custom_trials=11)
    assert registry.lookup("newton_ilc").budget(budgets) == 7
    assert registry.lookup("cma_es").budget(budgets) == 500
    assert registry.lookup("bayes_opt").budget(budgets) == 300  # its own cap
    assert registry.lookup("ppo").budget(budgets) == 9


def test_an_unknown_id_is_refused_naming_the_option():
    with pytest.raises(ValueError, match="--learner: unknown learner 'nope'"):
        registry.lookup("nope", "--learner")
    with pytest.raises(ValueError, match="--methods: unknown method 'nope'"):
        registry.lookup("nope")
    with pytest.raises(ValueError, match="cannot import it"):
        registry.lookup("no_such_module_here:make")


def test_the_context_carries_the_cost_in_run_compare_and_sweep():
    config = with_cost()
    env = gym.make("ilc_steering/ChainedSteering-v0", config=config)
    vector = ChainedSteeringVectorEnv(2, config)
    for context in (LearnerContext.from_env(env), LearnerContext.from_env(vector, nu_b=0.5)):
        assert context.cost == "path_length" and context.task == "forward_parking"
        learner = registry.lookup("ilc").make(context, 5)
        assert isinstance(learner, ILCAgent) and isinstance(learner.cost, NullSpaceCost)
    assert LearnerContext.from_env(vector, nu_b=0.5).nu_b == 0.5


def test_sweep_builds_its_learners_with_the_configs_cost(monkeypatch):
    """sweep used to drop learning.cost: its learners had none where compare's had a NullSpaceCost."""
    made = []
    original = sweep_rows.lockstep

    def capture(envs, learners, trials, tolerance, seed=0, name=None):
        made.extend(learners)
        return original(envs, learners, 1, tolerance, seed, name)

    monkeypatch.setattr(sweep_rows, "lockstep", capture)
    sweep.run_row(sweep.SweepArgs(config=with_cost(), grid=2, trials=1), "ilc", None, 0)  # type: ignore[arg-type]
    assert len(made) == 2 and all(isinstance(learner.cost, NullSpaceCost) for learner in made)


def test_the_optional_parts_of_a_learner_are_declared():
    class Mine(BaseLearner):
        closed = False

        def close(self):
            self.closed = True

    mine = Mine()
    assert isinstance(mine, Closable) and isinstance(mine, TimedUpdates) and update_times(mine) == []
    close_learner(mine)
    assert mine.closed
    env = gym.make("ilc_steering/ChainedSteering-v0", config="forward_parking")
    plain = ILCAgent(env.unwrapped.nominal_model)
    assert not isinstance(plain, Closable) and update_times(plain) == []
    close_learner(plain)  # nothing to close: no error


OUTSIDE = '''
"""A learner from outside the package: eqs. 33-34 at half gain, written against the Learner protocol."""
import numpy as np

from ilc_steering.agents.base import BaseLearner
from ilc_steering.agents.ilc import ILCAgent


class Halving(BaseLearner):
    def __init__(self, context):
        super().__init__()
        self.inner = ILCAgent(context.model, context.nu_a, 0.5 * context.nu_b, start=context.first_action())

    def act(self, observation=None):
        return self.inner.act(observation)

    def learn(self, info):
        self.inner.learn(info)

    def reset(self):
        self.inner.reset()


def make(context):
    return Halving(context)
'''


@pytest.mark.slow  # over 2.5 s: the README's test command stays under 5 min
def test_a_learner_from_outside_runs_through_run_compare_and_sweep(tmp_path, monkeypatch, capsys):
    """module:attr from the working directory, no entry point installed: the same lookup everywhere."""
    (tmp_path / "outside_learners.py").write_text(OUTSIDE)
    monkeypatch.chdir(tmp_path)
    monkeypatch.syspath_prepend(str(tmp_path))
    spec = "outside_learners:make"
    assert cli.main(["run", "forward_parking", "--learner", spec, "--trials", "4"]) in (0, 1)
    assert "forward_parking: 4 trials" in capsys.readouterr().out
    cells = compare.run_cells(
        compare.Args(
            out=tmp_path / "c",
            methods=(spec,),
            priors=("nominal",),
            scenarios=("forward_parking",),
            seeds=(0,),
            custom_trials=4,
            workers=1,
        )
    )
    assert [c["method"] for c in cells] == [spec] and cells[0]["trials"] == 4 and cells[0]["implementation"] == spec
    maps = sweep.run_rows(sweep.SweepArgs(methods=(spec,), grid=2, trials=3, workers=1, out=tmp_path / "s"))
    assert list(maps) == [(spec, 1.0)] and len(maps[spec, 1.0]) == 2


def test_an_installed_packages_learner_is_found_by_its_name(tmp_path, monkeypatch, capsys):
    """A learner named in the entry-point group ilc_steering.learners of an installed distribution:
    found by its name in run and compare (whose workers read the same metadata); an entry point
    that would replace a library id, or is malformed, is skipped with one warning line each."""
    (tmp_path / "outside_learners.py").write_text(OUTSIDE)
    info = tmp_path / "outside_learners-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: outside-learners\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text(
        "[ilc_steering.learners]\noutside = outside_learners:make\nilc = outside_learners:make\n"
        "Bad-Name = outside_learners:make\nbroken = not an entry\n"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setenv("PYTHONPATH", str(tmp_path))
    monkeypatch.setattr(registry, "_INSTALLED", {})
    monkeypatch.setattr(registry, "_READ", [])
    assert registry.installed() == {"outside": "outside_learners:make"}
    err = capsys.readouterr().err
    assert len(err.splitlines()) == 3 and "'ilc' is a learner of the library" in err and "broken = not an entry" in err
    assert registry.lookup("ilc") is registry.REGISTRY["ilc"]
    spec = registry.lookup("outside", "--learner")
    assert (spec.family, spec.entry_point) == ("yours", "outside_learners:make")
    assert spec.implementation() == "package outside-learners's learner outside_learners:make"
    assert cli.main(["run", "forward_parking", "--learner", "outside", "--trials", "3"]) in (0, 1)
    assert "forward_parking: 3 trials" in capsys.readouterr().out
    args = compare.Args(
        out=tmp_path / "c", methods=("outside",), priors=("nominal",), scenarios=("forward_parking",), seeds=(0,)
    )
    cells = compare.run_cells(dataclasses.replace(args, custom_trials=3, workers=1))
    assert [c["method"] for c in cells] == ["outside"] and cells[0]["trials"] == 3
    with pytest.raises(ValueError, match=r"an installed learner \['outside'\] or give module:attr"):
        registry.lookup("outsider")


def test_sweep_and_compare_run_the_same_trials_for_the_same_learner_cost_and_plant():
    """The vector form of the trial loop (sweep's rows) and the one-env form (compare's cells) give
    every trial the same action and the same true error, bit for bit, on a config with a cost."""
    from ilc_steering.loop import run_trials, run_vector_trials

    config = with_cost()
    for method in ("ilc", "newton_ilc", "least_squares"):
        env = gym.make("ilc_steering/ChainedSteering-v0", config=config)
        spec = registry.lookup(method)
        single = run_trials(env, spec.make(LearnerContext.from_env(env, seed=3), 6), 6, seed=3).infos
        vector = ChainedSteeringVectorEnv(2, config)
        learners = [spec.make(LearnerContext.from_env(vector, seed=3), 6) for _ in range(2)]
        seen = []
        run_vector_trials(vector, learners, 6, seed=3, callbacks=[lambda k, rows, seen=seen: seen.append(rows)])
        assert len(seen) == len(single) == 6
        for one, rows in zip(single, seen):
            for row in rows:
                assert (row["action"] == one["action"]).all(), method
                assert row["true_error_norm"] == one["true_error_norm"], method


def test_quick_is_resolved_in_one_place():
    """compare.main(Args(quick=True)) used to run 10 seeds: the plan resolves quick once."""
    resolved = compare_settings.resolve(compare.Args(quick=True))
    assert resolved.seeds == compare.QUICK_SEEDS and resolved.model_trials == compare.QUICK["model_trials"]
    assert compare_settings.resolve(compare.Args(quick=True, seeds=(5,), model_trials=9)).seeds == (5,)
    assert compare_settings.resolve(compare.Args(quick=True, model_trials=9)).model_trials == 9
    assert compare_settings.resolve(compare.Args()).seeds == compare_settings.SEEDS
    the_plan = compare.plan(compare.Args(quick=True, methods=("ilc", "ppo"), scenarios=("forward_parking",)))
    assert {cell[3] for cell in the_plan.grid} == set(compare.QUICK_SEEDS)
    assert the_plan.budgets["nominal", "ppo", "forward_parking"] == compare.QUICK["rl_trials"]


def test_one_plugin_reader_reads_every_entry_point_group():
    """Robots and learners come from installed packages through one reader (issue 65): no other
    module of the library reads entry points."""
    package = Path(ilc_steering.__file__).parent
    files = [Path(top, name) for top, _, names in os.walk(package, followlinks=True) for name in names]
    modules = [path for path in files if path.suffix == ".py"]
    assert any(path.name == "registry.py" for path in modules)  # agents/ is walked (a link in a checkout)
    readers = [path.relative_to(package).as_posix() for path in modules if "entry_points(" in path.read_text("utf-8")]
    assert readers == ["entries.py"]
