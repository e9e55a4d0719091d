"""The learner registry: one table of method ids, one way to build a learner, one context."""

import dataclasses

import gymnasium as gym
import pytest

import ilc_steering  # noqa: F401  (registers the envs)
from ilc_steering import cli, compare, runner, sweep, sweep_rows
from ilc_steering.agents import registry
from ilc_steering.agents.base import BaseLearner, Closable, LearnerContext, TimedUpdates, close_learner, update_times
from ilc_steering.agents.costs import NullSpaceCost
from ilc_steering.agents.ilc import ILCAgent
from ilc_steering.config import load_config
from ilc_steering.envs.steering_vector_env import ChainedSteeringVectorEnv


def with_cost(name="forward_parking", cost="path_length"):
    base = load_config(name)
    task = dataclasses.replace(base.task, v2_terms=5)
    return dataclasses.replace(base, task=task, learning=dataclasses.replace(base.learning, cost=cost))


def test_every_method_id_is_in_one_table_and_the_commands_tables_are_views_of_it():
    assert len(registry.METHODS) == len(set(registry.METHODS)) == len(registry.REGISTRY)
    assert compare.METHODS == registry.METHODS
    assert set(compare.MODEL_METHODS) | set(compare.BLACKBOX) | set(compare.RL) == set(registry.METHODS)
    assert compare.DEFAULT_METHODS == tuple(m for m in registry.METHODS if m != "crossq")
    assert set(cli.SEEDED_LEARNERS) <= set(registry.METHODS) and runner.DEFAULT_LEARNER in cli.SEEDED_LEARNERS
    for spec in registry.REGISTRY.values():
        assert spec.family in registry.FAMILIES[:-1]
        assert spec.budget_key in {f.name for f in dataclasses.fields(registry.Budgets)}


def test_an_id_means_one_learner_in_run_and_in_compare():
    env = gym.make("ilc_steering/ChainedSteering-v0", config="forward_parking")
    context = LearnerContext.from_env(env)
    for method in ("ilc", "ilc_paper"):
        a = runner.learner_spec(method).make(context, 5)
        b = compare.make_learner(compare.Args(), method, "forward_parking", context)
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
