"""The plan of a comparison: its arguments resolved once, checked once, frozen.

:func:`plan` turns the :class:`Args` a user gave into a :class:`Plan` that every later stage
reads and none recomputes: ``quick``'s budgets and seeds applied (here only), ``--against``'s
committed settings taken (:mod:`~ilc_steering.compare.against`), every option checked, every scenario's
config loaded, hashed and checked as a task once (an env each), each (prior, method, scenario)'s
budget read once (for RL from its hyperparameter file) and the grid of cells laid out in the
report's order.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field, fields, replace
from typing import Any

import gymnasium as gym

from ilc_steering import __version__
from ilc_steering.agents import registry
from ilc_steering.agents.base import PRIORS
from ilc_steering.compare.against import Cell, CommittedRun
from ilc_steering.compare.args import MAX_BUDGET, MAX_SEED, QUICK, QUICK_SEEDS, SCENARIOS, SEEDS, Args, seeds_of
from ilc_steering.compare.cells import ENV_ID, budgets, cell_roots
from ilc_steering.config import SteeringConfig
from ilc_steering.engine.options import check_cell_options
from ilc_steering.errors import BadInput
from ilc_steering.output import check_output_dir, content_hash
from ilc_steering.trial_board import require_tensorboard

__all__ = ["MAX_BUDGET", "MAX_SEED", "QUICK", "QUICK_SEEDS", "SCENARIOS", "SEEDS", "Args", "Plan", "plan", "resolve"]


def resolve(args: Args) -> Args:
    """``args`` with ``quick`` applied (its budgets where none was given, its seeds where none
    were) and the seeds filled in: the one place ``quick`` is read. Under ``--against`` the
    committed run's settings are taken instead (:func:`against_args`)."""
    if args.against is None and args.quick:
        quick: dict[str, Any] = {k: v for k, v in QUICK.items() if getattr(args, k) == getattr(Args, k)}
        args = replace(args, **quick)
    if args.seeds is None:
        args = replace(args, seeds=QUICK_SEEDS if args.quick else SEEDS)
    return args


def run_settings(args: Args) -> dict[str, Any]:
    """What ``run.json`` records and a resume (or ``--against``) must match: the budgets, the seeds,
    ``quick`` and the package version; not the grid's axes (a resume may add cells), nor how or
    where cells run, nor where their TensorBoard event files go."""
    skip: tuple[str, ...] = ("out", "against", "progress_bar", "priors", "methods", "scenarios", "workers")
    skip += ("backend", "cell_timeout", "dry_run", "tensorboard")
    settings = {k: v for k, v in asdict(args).items() if k not in skip}
    settings["seeds"] = list(settings["seeds"])
    settings["version"] = __version__
    return settings


@dataclass(frozen=True)
class Plan:
    """A comparison as it will run: read by every stage, recomputed by none."""

    args: Args
    """The arguments resolved (:func:`resolve`): budgets and seeds concrete."""
    names: dict[str, str]
    """Each scenario as given -> its config's name."""
    configs: dict[str, str]
    """Each config name (the committed run's too) -> the content hash of its config."""
    grid: tuple[Cell, ...]
    """Every cell, in the report's order."""
    budgets: dict[tuple[str, str, str], int]
    """(prior, method, config name) -> budget [trials]."""
    warnings: tuple[str, ...] = ()
    """Warnings on the configs (a coarse step), printed once."""
    committed: CommittedRun | None = None
    """The committed run of ``--against``."""
    held: dict[Cell, dict[str, Any]] = field(default_factory=dict)
    """The committed run's cells, each checked."""
    robots: dict[str, str] = field(default_factory=dict)
    """Each config name of this run -> the module of its robot (a root of its cells' code)."""

    @property
    def settings(self) -> dict[str, Any]:
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

    def scenario_of(self, name: str) -> str:
        """The scenario as given (a name or a YAML path) of a config name."""
        return next(scenario for scenario, n in self.names.items() if n == name)


def check_options(args: Args) -> Args:
    """Every option that needs no config: ``ValueError`` naming it: unknown or repeated priors,
    methods, scenarios or seeds, a user's learner that cannot be imported, a seed outside
    ``[0, 2**32)``, a budget outside ``[1, MAX_BUDGET]``, a worker count outside ``[0,
    MAX_WORKERS]``, a ``cell_timeout`` that is not a time > 0 s, a ``--tensorboard`` without its
    extra or that cannot be written. Returns ``args``."""
    check_cell_options(args.backend, args.workers, args.cell_timeout)
    if args.tensorboard is not None:
        require_tensorboard("--tensorboard")
        if not args.dry_run:
            check_output_dir(args.tensorboard, "--tensorboard")
    options = (("--priors", args.priors), ("--methods", args.methods), ("--scenarios", args.scenarios))
    for option, values in (*options, ("--seeds", args.seeds or ())):
        if not values:
            raise BadInput(f"{option}: give at least one")
        repeated = sorted({str(v) for v in values if list(values).count(v) > 1})
        if repeated:
            raise BadInput(f"{option}: {repeated[0]} is given twice; each cell is counted once")
    unknown_priors = [p for p in args.priors if p not in PRIORS]
    if unknown_priors:
        raise BadInput(f"--priors: unknown prior {unknown_priors[0]!r}; choose from {list(PRIORS)}")
    if any(registry.lookup(method).family == "RL" for method in args.methods):
        from ilc_steering.agents.rl_settings import rl_backend

        rl_backend()  # ILC_STEERING_RL_BACKEND checked before any cell, not in each RL cell
    bad = [s for s in args.seeds or () if isinstance(s, bool) or not isinstance(s, int) or not 0 <= s <= MAX_SEED]
    if bad:
        raise BadInput(f"--seeds: {bad[0]!r} is not a whole number in [0, {MAX_SEED}]")
    for option in ("model_trials", "blackbox_trials", "rl_trials", "custom_trials"):
        value = getattr(args, option)
        if value is not None and (
            isinstance(value, bool) or not isinstance(value, int) or not 1 <= value <= MAX_BUDGET
        ):
            raise BadInput(
                f"--{option.replace('_', '-')}: the budget must be a whole number in [1, {MAX_BUDGET}], got {value!r}"
            )
    k = args.ablation_seeds
    if isinstance(k, bool) or not isinstance(k, int) or not 1 <= k <= MAX_SEED:
        raise BadInput(f"--ablation-seeds: a whole number of seeds >= 1, got {k!r}")
    return args


def _configs(args: Args) -> tuple[dict[str, str], dict[str, SteeringConfig]]:
    """Each scenario loaded once and checked as a task (a cyclic config, two scenarios of one name,
    an ill-posed task are refused): scenario -> config name, and config name -> config."""
    from ilc_steering.config import load_config
    from ilc_steering.runner import check_task

    loaded: dict[str, SteeringConfig] = {}
    names: dict[str, str] = {}
    for scenario in args.scenarios:
        config = load_config(scenario)
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

    committed = None
    if args.against is not None:
        args, committed = against_args(args)
    args = check_options(resolve(args))
    names, loaded = _configs(args)
    configs = {name: content_hash(asdict(config)) for name, config in loaded.items()}
    warnings = tuple(w for w in (step_warning(config) for config in loaded.values()) if w is not None)
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
        from ilc_steering.compare.against import committed_cells, joint_cells

        held, configs = committed_cells(args, committed, configs, budget)
        grid = joint_cells(args, list(names.values()), held)
        for cell in grid:
            budget(*cell[:3])
    robots = {name: type(config.plant).__module__ for name, config in loaded.items()}
    return Plan(args, names, configs, tuple(grid), table, warnings, committed, held, robots)


def against_args(args: Args) -> tuple[Args, CommittedRun]:
    """``args`` for ``--against`` and the committed run as read: its settings (budgets, seeds,
    ``quick``) where ``args`` holds the defaults, its scenarios and priors unless a subset of them
    is given. ``ValueError`` (one line, naming the option) for a run of another version or other
    settings, an ``--out`` inside it, a method list left at the default, a scenario or prior it
    has no cells of, or a scenario of its that is not packaged and not given as a YAML file."""
    from ilc_steering import __version__
    from ilc_steering.agents.base import PRIORS
    from ilc_steering.config import load_config, packaged_configs
    from ilc_steering.output import differences

    folder = args.against
    if folder is None:
        raise BadInput("--against: give a committed run folder")
    from ilc_steering.compare.against import check_out, read_committed, resolve_settings

    committed = read_committed(folder)
    check_out(args.out, folder)
    _warn_if_stale(committed)
    if args.methods == Args.methods:
        raise BadInput(f"--against {folder}: name the methods to add with --methods, e.g. --methods my_learners:make")
    defaults = {f.name: f.default for f in fields(Args)}
    args = replace(args, **resolve_settings(committed, asdict(args), defaults, __version__))
    cells = [cell for _, cell in committed.cells]
    scenarios = [name for name in committed.configs if any(c["scenario"] == name for c in cells)]
    if args.scenarios == Args.scenarios:
        unknown = [name for name in scenarios if name not in packaged_configs()]
        if unknown:
            raise BadInput(
                f"--against {folder}: its scenario {unknown[0]!r} is not a packaged config; give its YAML file with "
                f"--scenarios, beside those of its other scenarios to run ({' '.join(scenarios)})"
            )
        args = replace(args, scenarios=tuple(scenarios))
    for scenario in args.scenarios:
        if load_config(scenario).name not in scenarios:
            raise BadInput(
                f"--scenarios {scenario}: the committed run --against {folder} has no cells of it; its scenarios: "
                f"{' '.join(scenarios)}"
            )
    priors = [prior for prior in PRIORS if any(c["prior"] == prior for c in cells)]
    if args.priors == Args.priors:
        args = replace(args, priors=tuple(priors))
    elif not set(args.priors) <= set(priors):
        raise BadInput(f"--priors: the committed run --against {folder} has cells of {' '.join(priors)} only")
    settings = run_settings(args)
    if settings != committed.settings:
        raise BadInput(
            f"--against {folder}: it was run with other settings: {differences(committed.settings, settings)}"
        )
    return args, committed


def _warn_if_stale(committed: CommittedRun) -> None:
    """Say on stderr how many of the committed run's cells are stale for the code in this tree:
    they are taken as they were made, beside cells this code computes (``ilc-steering current``
    says more)."""
    import sys

    from ilc_steering.engine.staleness import staleness

    stale = sum(bool(staleness(cell, committed.codes, {})) for _, cell in committed.cells)
    if stale:
        print(
            f"ilc-steering: warning: --against {committed.folder}: {stale} of its {len(committed.cells)} cells are "
            "stale for the code in this tree (made by other code); they are taken as they were made "
            f"(ilc-steering current {committed.folder} says what changed)",
            file=sys.stderr,
            flush=True,
        )
