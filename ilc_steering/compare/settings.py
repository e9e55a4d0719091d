"""A comparison's arguments made concrete and checked, once, for its plan (:mod:`~ilc_steering.compare.plan`).

:func:`resolve` applies ``quick`` (its budgets where none was given, its seeds where none were:
the one place ``quick`` is read), :func:`check_options` checks every option that needs no config,
and :func:`run_settings` says what of the arguments a run folder's ``run.json`` records: what a
resume, or a run held against a committed one (:mod:`~ilc_steering.compare.against`), must match.
"""

from __future__ import annotations

from dataclasses import asdict, replace
from typing import Any

from ilc_steering import __version__
from ilc_steering.agents import registry
from ilc_steering.agents.base import PRIORS
from ilc_steering.compare.args import MAX_BUDGET, MAX_SEED, QUICK, QUICK_SEEDS, SEEDS, Args
from ilc_steering.engine.options import check_cell_options
from ilc_steering.errors import BadInput
from ilc_steering.output import check_output_dir
from ilc_steering.trial_board import require_tensorboard

__all__ = ["UNRECORDED", "check_options", "resolve", "run_settings"]


def resolve(args: Args) -> Args:
    """``args`` with ``quick`` applied (its budgets where none was given, its seeds where none
    were) and the seeds filled in: the one place ``quick`` is read. Under ``--against`` the
    committed run's settings are taken instead (:func:`~ilc_steering.compare.against.against_args`)."""
    if args.against is None and args.quick:
        quick: dict[str, Any] = {k: v for k, v in QUICK.items() if getattr(args, k) == getattr(Args, k)}
        args = replace(args, **quick)
    if args.seeds is None:
        args = replace(args, seeds=QUICK_SEEDS if args.quick else SEEDS)
    return args


UNRECORDED: tuple[str, ...] = ("out", "against", "progress_bar", "priors", "methods", "scenarios", "workers")
UNRECORDED += ("backend", "cell_timeout", "dry_run", "tensorboard")
"""The options ``run.json`` does not record (:func:`run_settings`): where and how cells run, the grid's axes."""


def run_settings(args: Args) -> dict[str, Any]:
    """What ``run.json`` records and a resume (or ``--against``) must match: the budgets, the seeds,
    ``quick`` and the package version; not the grid's axes (a resume may add cells), nor how or
    where cells run, nor where their TensorBoard event files go."""
    settings = {k: v for k, v in asdict(args).items() if k not in UNRECORDED}
    settings["seeds"] = list(settings["seeds"])
    settings["version"] = __version__
    return settings


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
