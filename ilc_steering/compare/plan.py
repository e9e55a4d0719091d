"""The plan of a comparison, built in one pass and frozen: :class:`Plan` and :func:`plan`.

:func:`plan` turns the :class:`Args` a user gave into a :class:`Plan` that every later stage
reads and none recomputes, in one pass: the committed run of ``--against`` read once
(:mod:`~ilc_steering.compare.committed`) and its settings, scenarios and priors taken
(:mod:`~ilc_steering.compare.against`); ``quick`` applied and every option checked
(:mod:`~ilc_steering.compare.settings`); every scenario's config loaded, hashed and checked as a
task once (an env each); each (prior, method, scenario)'s budget read once (for RL from its
hyperparameter file); the committed cells checked against their keys; and the grid of cells laid
out in the report's order. It prints nothing: its warnings are the plan's, printed when it runs.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Any

import gymnasium as gym

from ilc_steering import __version__
from ilc_steering.agents import registry
from ilc_steering.compare.against import Cell, against_args, committed_cells, joint_cells, stale_warning
from ilc_steering.compare.args import Args, seeds_of
from ilc_steering.compare.cells import ENV_ID, budgets, cell_roots
from ilc_steering.compare.committed import CommittedRun, read_committed
from ilc_steering.compare.settings import check_options, resolve, run_settings
from ilc_steering.config import SteeringConfig
from ilc_steering.errors import BadInput
from ilc_steering.output import content_hash

__all__ = ["Plan", "plan"]


@dataclass(frozen=True)
class Plan:
    """A comparison as it will run: read by every stage, recomputed by none."""

    args: Args
    """The arguments resolved (:func:`~ilc_steering.compare.settings.resolve`): budgets and seeds concrete."""
    names: dict[str, str]
    """Each scenario as given -> its config's name."""
    configs: dict[str, str]
    """Each config name (the committed run's too) -> the content hash of its config."""
    grid: tuple[Cell, ...]
    """Every cell, in the report's order."""
    budgets: dict[tuple[str, str, str], int]
    """(prior, method, config name) -> budget [trials]."""
    warnings: tuple[str, ...] = ()
    """Warnings, printed once before the first cell: the committed run's stale cells, a config's coarse step."""
    committed: CommittedRun | None = None
    """The committed run of ``--against``."""
    held: dict[Cell, dict[str, Any]] = field(default_factory=dict)
    """The committed run's cells, each checked."""
    robots: dict[str, str] = field(default_factory=dict)
    """Each config name of this run -> the module of its robot (a root of its cells' code)."""

    @property
    def settings(self) -> dict[str, Any]:
        """What the run folder's ``run.json`` records (:func:`~ilc_steering.compare.settings.run_settings`)."""
        return run_settings(self.args)

    def key(self, cell: Cell) -> dict[str, Any]:
        """What a finished cell must hold: its identity, budget, config hash and the version."""
        prior, method, name, seed = cell
        return {
            "prior": prior,
            "method": method,
            "scenario": name,
            "seed": seed,
            "budget": self.budgets[prior, method, name],
            "config_sha": self.configs[name],
            "version": __version__,
        }

    def identity(self, cell: Cell) -> dict[str, Any]:
        """What a finished cell must hold to be this cell at all (:meth:`key` without its stamp)."""
        return {k: v for k, v in self.key(cell).items() if k not in ("config_sha", "version")}

    def stamp(self, cell: Cell) -> dict[str, Any]:
        """What a cell computed by this run records besides its result: its config's content hash,
        the version and, for RL, the backend that trained it. A finished cell that records other
        values (or another code) is stale: a resume computes it again."""
        key = self.key(cell)
        stamp = {"config_sha": key["config_sha"], "version": key["version"]}
        spec = registry.lookup(cell[1])
        return {**stamp, "implementation": spec.implementation()} if spec.family == "RL" else stamp

    def roots(self, cell: Cell) -> tuple[str, ...]:
        """Where a cell's computation starts (:func:`~ilc_steering.compare.cells.cell_roots`)."""
        return cell_roots(cell[1], self.robots[cell[2]])

    def cost(self, cell: Cell) -> float:
        """A cell's rough cost [s], from its method's cost of a trial and its budget (the cells run
        longest first, and the progress bar's estimate starts from it)."""
        spec = registry.REGISTRY.get(cell[1])  # a user's learner: the spec's default cost of a trial
        budget = self.budgets[cell[:3]]
        return 1.0 + (spec.expected_seconds(budget) if spec else registry.LearnerSpec.trial_seconds * budget)

    def scenario_of(self, name: str) -> str:
        """The scenario as given (a name or a YAML path) of a config name."""
        return next(scenario for scenario, n in self.names.items() if n == name)


def _configs(args: Args, committed: CommittedRun | None) -> tuple[dict[str, str], dict[str, SteeringConfig]]:
    """Each scenario loaded once and checked as a task (a cyclic config, two scenarios of one name,
    an ill-posed task, one the ``committed`` run has no cells of are refused): scenario -> config
    name, and config name -> config."""
    from ilc_steering.config import load_config
    from ilc_steering.runner import check_task

    loaded: dict[str, SteeringConfig] = {}
    names: dict[str, str] = {}
    for scenario in args.scenarios:
        config = load_config(scenario)
        if committed is not None and config.name not in committed.scenarios:
            raise BadInput(
                f"--scenarios {scenario}: the committed run --against {committed.folder} has no cells of it; its "
                f"scenarios: {' '.join(committed.scenarios)}"
            )
        if config.is_cyclic:
            raise BadInput(
                f"--scenarios {scenario}: a cyclic config; compare runs one-trial tasks "
                "(use ilc-steering run for cycles)"
            )
        if config.name in names.values():
            raise BadInput(f"--scenarios {scenario}: another scenario is also named {config.name!r}")
        env = gym.make(ENV_ID, config=config)
        check_task(env, f"--scenarios {scenario}")
        env.close()
        names[scenario] = config.name
        loaded[config.name] = config
    return names, loaded


def plan(args: Args) -> Plan:
    """The frozen plan of ``args``: resolved, checked, every config loaded once (see the module)."""
    from ilc_steering.runner import step_warning

    committed = None if args.against is None else read_committed(args.against)
    if committed is not None:
        args = against_args(args, committed)
    args = resolve(args)
    check_options(args)
    names, loaded = _configs(args, committed)
    configs = {name: content_hash(asdict(config)) for name, config in loaded.items()}
    stale = None if committed is None else stale_warning(committed)
    steps = (step_warning(config) for config in loaded.values())
    warnings = tuple(w for w in (stale, *steps) if w is not None)
    table: dict[tuple[str, str, str], int] = {}
    given = budgets(args)

    def budget(prior: str, method: str, name: str) -> int:
        if (prior, method, name) not in table:  # RL: its hyperparameters exist
            table[prior, method, name] = registry.lookup(method).budget(given, name, prior)
        return table[prior, method, name]

    for prior in args.priors:
        for method in args.methods:
            for name in names.values():
                budget(prior, method, name)
    held: dict[Cell, dict[str, Any]] = {}
    if committed is None:
        grid = [
            (p, m, n, s) for p in args.priors for n in names.values() for m in args.methods for s in seeds_of(args, p)
        ]
    else:
        held, configs = committed_cells(args, committed, configs, budget)
        grid = joint_cells(args, list(names.values()), held)
        for cell in grid:
            budget(*cell[:3])
    robots = {name: type(config.plant).__module__ for name, config in loaded.items()}
    return Plan(args, names, configs, tuple(grid), table, warnings, committed, held, robots)
