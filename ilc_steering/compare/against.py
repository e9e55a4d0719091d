"""``compare --against DIR``: a new method's cells beside a committed run's, which is only read.

The committed run is read once (:func:`~ilc_steering.compare.committed.read_committed`); this
module holds the arguments against it. :func:`against_args` takes its settings (budgets, seeds,
``quick``: :func:`resolve_settings` takes every setting the user left at its default from it and
refuses one given otherwise, naming the option), its scenarios and priors, and keeps the output
out of its folder (:func:`check_out`); :func:`committed_cells` checks its cells one by one against
the plan's keys and :func:`joint_cells` lays out the joint grid; :mod:`ilc_steering.compare.execute`
copies the committed cells into ``--out`` as they are (:func:`copy_committed`) and computes only
the cells the committed run lacks, so the report in ``--out`` is the joint one and the folder
resumes like any other.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import asdict, fields, replace
from pathlib import Path
from typing import Any

from ilc_steering import __version__
from ilc_steering.agents.base import PRIORS
from ilc_steering.agents.registry import METHODS, is_custom
from ilc_steering.compare.args import Args, seeds_of
from ilc_steering.compare.cells import check_cell
from ilc_steering.compare.committed import CommittedRun
from ilc_steering.compare.settings import UNRECORDED, run_settings
from ilc_steering.config import packaged_configs
from ilc_steering.engine.staleness import staleness
from ilc_steering.errors import BadInput
from ilc_steering.output import differences, write_json

__all__ = [
    "against_args",
    "check_out",
    "committed_cells",
    "copy_committed",
    "describe",
    "joint_cells",
    "resolve_settings",
    "stale_warning",
]

Cell = tuple[str, str, str, int]
"""A cell's (prior, method, scenario name, seed)."""
Budget = Callable[[str, str, str], int]
"""The budget of (prior, method, scenario name) [trials]."""


def _refuse(label: str, problem: str) -> ValueError:
    return BadInput(f"{label}: {problem}")


def _same(a: Any, b: Any) -> bool:
    """Equal as JSON: a tuple of seeds equals the list a run record holds."""
    return json.dumps(a, default=str) == json.dumps(b, default=str)


def _option(name: str, value: Any) -> str:
    """A setting as its command-line option."""
    flag = f"--{name.replace('_', '-')}"
    if isinstance(value, bool):
        return flag if value else f"no {flag}"
    if value is None:
        return f"no {flag}"
    if isinstance(value, (list, tuple)):
        return f"{flag} {' '.join(map(str, value))}"
    return f"{flag} {value}"


def describe(settings: dict[str, Any]) -> str:
    """A run's settings as the options that give them (its version last)."""
    options = [_option(name, value) for name, value in settings.items() if name != "version"]
    return f"{' '.join(options)}, ilc-steering {settings.get('version')}"


def resolve_settings(
    committed: CommittedRun, given: dict[str, Any], defaults: dict[str, Any], version: str
) -> dict[str, Any]:
    """The settings to run with: the committed run's wherever ``given`` holds the default (an
    option left out, or given at its default value: the run says which it took, :func:`describe`).

    ``ValueError`` naming ``--against`` and the option if the committed run was made by another
    ``version`` of the package, holds a setting this version has no option for or lacks one it
    records, or if ``given``
    sets an option otherwise than the committed run (its cells would not be comparable)."""
    stored = committed.settings
    if stored.get("version") != version:
        raise _refuse(
            committed.label,
            f"made by ilc-steering {stored.get('version')}, this is {version}: its cells are not comparable "
            f"with this version's; recompute it with {version}, or install {stored.get('version')}",
        )
    missing = [name for name in defaults if name not in UNRECORDED and name not in stored]
    if missing:
        raise _refuse(committed.label, f"its run.json records no {missing[0]!r}, so its cells cannot be held against")
    values = {}
    for name, value in stored.items():
        if name == "version":
            continue
        if name not in defaults:
            raise _refuse(committed.label, f"its run.json holds a setting {name!r} that this version has no option for")
        if _same(given[name], defaults[name]):
            values[name] = tuple(value) if isinstance(value, list) else value
        elif not _same(given[name], value):
            raise _refuse(
                committed.label,
                f"it was run with {_option(name, value)}, not {_option(name, given[name])}; leave the option out "
                "to take the committed run's",
            )
    return values


def check_out(out: Path, folder: Path) -> None:
    """``ValueError`` if ``out`` is the committed ``folder`` or lies inside it: it is never written."""
    inside = out.resolve()
    committed = folder.resolve()
    if inside == committed or committed in inside.parents:
        raise BadInput(
            f"--out {out}: inside the committed run --against {folder}, which is only read; give another folder"
        )


def against_args(args: Args, committed: CommittedRun) -> Args:
    """``args`` held against the ``committed`` run: its settings (budgets, seeds, ``quick``) where
    ``args`` holds the defaults, its scenarios and priors unless a subset of them is given.
    ``ValueError`` (one line, naming the option) for a run of another version or other settings,
    an ``--out`` inside it, a method list left at the default, a prior it has no cells of, or a
    scenario of its that is not packaged and not given as a YAML file. (A scenario given that it
    has no cells of is refused when its config is loaded, :func:`~ilc_steering.compare.plan.plan`.)"""
    folder = committed.folder
    check_out(args.out, folder)
    if args.methods == Args.methods:
        raise _refuse(committed.label, "name the methods to add with --methods, e.g. --methods my_learners:make")
    defaults = {f.name: f.default for f in fields(Args)}
    args = replace(args, **resolve_settings(committed, asdict(args), defaults, __version__))
    scenarios = committed.scenarios
    if args.scenarios == Args.scenarios:
        unknown = [name for name in scenarios if name not in packaged_configs()]
        if unknown:
            raise _refuse(
                committed.label,
                f"its scenario {unknown[0]!r} is not a packaged config; give its YAML file with --scenarios, "
                f"beside those of its other scenarios to run ({' '.join(scenarios)})",
            )
        args = replace(args, scenarios=scenarios)
    if args.priors == Args.priors:
        args = replace(args, priors=committed.priors)
    elif not set(args.priors) <= set(committed.priors):
        raise BadInput(f"--priors: the committed run --against {folder} has cells of {' '.join(committed.priors)} only")
    settings = run_settings(args)
    if settings != committed.settings:
        raise _refuse(committed.label, f"it was run with other settings: {differences(committed.settings, settings)}")
    return args


def stale_warning(committed: CommittedRun) -> str | None:
    """A warning if some of the committed run's cells are stale for the code in this tree: they
    are taken as they were made, beside cells this code computes (``ilc-steering current`` says more)."""
    stale = sum(bool(staleness(cell, committed.codes, {})) for _, cell in committed.cells)
    if not stale:
        return None
    return (
        f"warning: --against {committed.folder}: {stale} of its {len(committed.cells)} cells are stale for the "
        f"code in this tree (made by other code); they are taken as they were made (ilc-steering current "
        f"{committed.folder} says what changed)"
    )


def committed_cells(
    args: Args, committed: CommittedRun, configs: dict[str, str], budget: Budget
) -> tuple[dict[Cell, dict[str, Any]], dict[str, str]]:
    """The committed run's cells, each checked against its key and value by value, and the
    content hash of every scenario's config; ``ValueError`` if a scenario to run has another
    config than the committed run's cells of that name, or a committed cell is not one of its run."""
    for name, digest in configs.items():
        theirs = committed.configs.get(name)
        if theirs != digest:
            raise BadInput(
                f"{committed.label}: its {name!r} cells were computed with another config (content hash {theirs}, "
                f"this one's {digest}): the same name, another content"
            )
    hint = f"the committed run {committed.label} is not consistent; recompute it"
    held: dict[Cell, dict[str, Any]] = {}
    for where, cell in committed.cells:
        prior, method, scenario, seed = (cell[name] for name in ("prior", "method", "scenario", "seed"))
        known = isinstance(method, str) and (method in METHODS or is_custom(method))
        ours = isinstance(scenario, str) and scenario in committed.configs
        if prior not in PRIORS or not known or not ours or seed not in (args.seeds or ()):
            raise BadInput(
                f"{where}: not a cell of its run (prior {prior!r}, method {method!r}, scenario {scenario!r}, "
                f"seed {seed!r}); {hint}"
            )
        key = {
            "prior": prior,
            "method": method,
            "scenario": scenario,
            "seed": seed,
            "budget": budget(prior, method, scenario),
            "config_sha": committed.configs[scenario],
            "version": __version__,
        }
        held[(prior, method, scenario, seed)] = check_cell(cell, key, where, hint)
    scenarios = dict.fromkeys(cell[2] for cell in held)
    return held, {**{name: committed.configs[name] for name in scenarios}, **configs}


def joint_cells(args: Args, names: list[str], held: dict[Cell, dict[str, Any]]) -> list[Cell]:
    """The cells of an ``--against`` run, in the report's order: every committed one, and those of
    ``args.methods`` on ``names`` under ``args.priors`` that it lacks."""
    priors = [prior for prior in PRIORS if prior in args.priors or any(cell[0] == prior for cell in held)]
    scenarios = list(dict.fromkeys([*(cell[2] for cell in held), *names]))
    methods = list(dict.fromkeys([*(cell[1] for cell in held), *args.methods]))
    return [
        (prior, method, name, seed)
        for prior in priors
        for name in scenarios
        for method in methods
        for seed in seeds_of(args, prior)
        if (prior, method, name, seed) in held or (method in args.methods and prior in args.priors and name in names)
    ]


def copy_committed(
    held: dict[Cell, dict[str, Any]], paths: dict[Cell, Path], read: Callable[[Path, Cell], Any]
) -> None:
    """Write each committed cell into the run folder (its file ``paths[cell]``) as it is, where it
    lacks it; ``ValueError`` if the folder holds another result for one of them (``read``: the
    resume checker; it is never overwritten)."""
    for cell, path in paths.items():
        found = held.get(cell)
        if found is None:
            continue
        if not path.exists():
            write_json(path, found)
        elif read(path, cell) != found:
            raise BadInput(f"{path}: holds another result than the committed run's; use another --out folder")
