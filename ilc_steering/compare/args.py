"""The arguments of a comparison (``ilc-steering compare``), each with its unit and default.

A module of its own so that every part of ``compare`` (its plan, its cells, ``--against``) reads
them without importing the others.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from ilc_steering.agents import registry
from ilc_steering.agents.base import PRIORS

__all__ = ["ABLATION_SEEDS", "MAX_BUDGET", "MAX_SEED", "QUICK", "QUICK_SEEDS", "SCENARIOS", "SEEDS", "Args", "seeds_of"]

MAX_SEED = 2**32 - 1
SCENARIOS = (
    "forward_parking",
    "forward_parking_saturated",
    "parallel_parking",
    "forward_parking_noisy",
    "unicycle_parking",
    "trailer_bay",
)
SEEDS = tuple(range(10))
"""The seeds of a comparison when none are given."""
ABLATION_SEEDS = 5
"""How many of the seeds (the first) the ``prior=none`` ablation runs when none is said."""
MAX_BUDGET = 1_000_000
"""The largest budget of any method [trials]: the trial log is kept in memory."""
QUICK = {"model_trials": 6, "blackbox_trials": 40, "rl_trials": 48, "custom_trials": 20}
"""``--quick``'s budgets, where no budget was given."""
QUICK_SEEDS = (0, 1)
"""``--quick``'s seeds, where none were given."""


@dataclass(frozen=True)
class Args:
    quick: bool = False
    """Tiny budgets and two seeds: checks that everything runs and writes well-formed output (CI)."""
    out: Path = Path("runs/compare")
    """Run folder; an existing one is resumed."""
    against: Path | None = None
    """A committed run folder, only read: run the cells of ``methods`` it lacks, with its settings,
    and report both (:mod:`~ilc_steering.compare.against`)."""
    priors: tuple[str, ...] = PRIORS
    """Conditions: ``nominal`` (start from the nominal solution) and ``none`` (no prior)."""
    methods: tuple[str, ...] = registry.DEFAULT_METHODS
    """Methods: the library's ids, or ``module:attr`` for a user's learner factory."""
    scenarios: tuple[str, ...] = SCENARIOS
    """Packaged config names or YAML paths of one-trial tasks."""
    seeds: tuple[int, ...] | None = None
    """Seeds; each (prior, method, scenario, seed) is one cell. None: :data:`SEEDS`, or
    :data:`QUICK_SEEDS` with ``quick``."""
    ablation_seeds: int = ABLATION_SEEDS
    """``prior=none``, the ablation, runs the first this many of ``seeds`` (all of them if fewer)."""
    model_trials: int = 30
    """Budget of the model-based learners (``ilc``, ``ilc_paper``, ``newton``) [trials]."""
    blackbox_trials: int = 3000
    """Budget of each black-box optimizer [trials]."""
    rl_trials: int | None = None
    """Budget of each RL algorithm [trials]; None: ``n_timesteps`` of its hyperparameter file."""
    custom_trials: int = 300
    """Budget of a user's learner (``module:attr``) [trials]."""
    workers: int = 0
    """Worker processes; 0: one per core."""
    progress_bar: bool = False
    """SB3's progress bar on RL cells (with one worker only)."""
    backend: str = "local"
    """Where cells run: ``local`` processes or ``ray`` tasks (:mod:`ilc_steering.engine.backends`)."""
    cell_timeout: float | None = None
    """[s] a cell still running after this is stopped and recorded as failed; None:
    :data:`~ilc_steering.engine.options.DEFAULT_CELL_TIMEOUT`."""
    dry_run: bool = False
    """Compute and write nothing: say which cells a run would compute, and its cost."""
    tensorboard: Path | None = None
    """A folder for TensorBoard's event files of the cells this run computes, one folder per cell
    (:func:`~ilc_steering.trial_board.run_folder`); not a setting: a run folder is the same with
    or without it."""


def seeds_of(args: Args, prior: str) -> tuple[int, ...]:
    """The seeds of ``prior``'s cells: all of ``args.seeds``, the first ``ablation_seeds`` under
    ``prior=none``."""
    seeds = tuple(args.seeds or ())
    return seeds[: args.ablation_seeds] if prior == "none" else seeds
