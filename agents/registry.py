"""The learner registry: every method id once, with its factory, family, budget and implementation.

Gymnasium keeps one ``register`` table and one ``make``; this is that table for learners. Each
:class:`LearnerSpec` names its factory by a string (``"module:attr"``), so nothing is imported
before a learner is built, and every command builds learners one way, :meth:`LearnerSpec.make`
``(context, budget)``: ``run --learner``, ``compare --methods``, ``sweep --methods``, the
benchmarks and the tests. A user's factory ``module:attr`` is resolved by the same lookup,
:func:`lookup`, into a spec of family ``"yours"``; so is a learner an installed package names in the
entry-point group :data:`GROUP` (``[project.entry-points."ilc_steering.learners"]`` of its
``pyproject.toml``: ``my_method = "my_package.module:make"``), by its name, as robots are found
(:mod:`ilc_steering.core.robots`): a string until it is named, never replacing an id of the
library (such an entry point, or a malformed one, is skipped with a one-line warning on stderr).

Adding a learner to the library is one line of :data:`REGISTRY` (and its module)::

    LearnerSpec("my_method", "model-based", "ilc_steering.agents.my_module:make_my_method", "model_trials", "...")

The factory of a model-based learner, and a user's, is ``make(context) -> Learner``; a black-box
spec names its optimizer ``optimizer(env, context)``, which
:func:`ilc_steering.agents.blackbox.make_learner` runs as a learner; an RL spec holds its
algorithm (:class:`RLAlgorithm`: the class and module that implement it, the shape of its actor),
which :mod:`ilc_steering.agents.rl` builds. The family modules read the spec; the registry names
them by their entry strings only, so that they may import it.
:meth:`LearnerSpec.make` attaches the config's ``learning.cost``
(:func:`ilc_steering.agents.costs.with_cost`) to every learner it builds, so no command can drop it.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

from ilc_steering.agents import rl_settings
from ilc_steering.agents.base import Learner, LearnerContext, LearnerFactory, load_factory
from ilc_steering.agents.rl_settings import RLAlgorithm
from ilc_steering.entries import load_entry, read_plugins
from ilc_steering.errors import BadInput

__all__ = [
    "DEFAULT_METHODS",
    "FAMILIES",
    "GROUP",
    "METHODS",
    "REGISTRY",
    "Budgets",
    "LearnerSpec",
    "RLAlgorithm",
    "families",
    "ids",
    "installed",
    "is_custom",
    "lookup",
]

FAMILIES = ("model-based", "black-box", "RL", "yours")
"""The families the comparison's figures colour by; ``yours``: a user's ``module:attr`` or an
installed package's learner (:data:`GROUP`)."""
GROUP = "ilc_steering.learners"
"""The entry-point group in which an installed package names its learners: ``name = "module:make"``."""
_INSTALLED: dict[str, tuple[str, str]] = {}  # name -> (entry, package), read once per process
_READ: list[bool] = []
_RL = "ilc_steering.agents.rl"
_BLACKBOX = "ilc_steering.agents.blackbox"


@dataclass(frozen=True)
class Budgets:
    """The trials each family is given in a comparison (``compare --model-trials`` ...)."""

    model_trials: int = 30
    """Budget of the model-based learners [trials]."""
    blackbox_trials: int = 3000
    """Budget of each black-box optimizer [trials]."""
    rl_trials: int | None = None
    """Budget of each RL algorithm [trials]; None: ``n_timesteps`` of its hyperparameter file."""
    custom_trials: int = 300
    """Budget of a user's learner (``module:attr``) [trials]."""


@dataclass(frozen=True)
class LearnerSpec:
    """One learner of the registry (or a user's, family ``yours``)."""

    id: str
    """The method id (``compare --methods``, ``run --learner``), or a user's ``module:attr``."""
    family: str
    """One of :data:`FAMILIES`."""
    entry_point: str
    """``module:attr`` of its factory: ``make(context) -> Learner`` (model-based and yours), or the
    family's ``make_learner`` (black-box, RL)."""
    budget_key: str
    """The field of :class:`Budgets` that gives its budget."""
    summary: str = ""
    """One line on what it is."""
    package: str | None = None
    """The distribution whose version names its implementation (None: this library's)."""
    by_default: bool = True
    """Run by ``compare`` when ``--methods`` is not given."""
    option: str = "--methods"
    """Where a user's learner was named (for messages)."""
    reproduce: bool = False
    """Reported by ``reproduce``'s table over the seeds of the lab experiments' noise."""
    trial_seconds: float = 0.01
    """A rough cost of one of its trials [s], for the progress bar's estimate and the order of cells
    (measured on the packaged tasks: model-based 0.03, black-box 7e-4, RL 5e-3, bayes_opt 0.1)."""
    max_trials: int | None = None
    """Its own cap on the family's budget [trials] (``bayes_opt``: a GP's trial is costly)."""
    rl: RLAlgorithm | None = None
    """The algorithm of an RL spec."""

    def factory(self) -> LearnerFactory:
        """The factory ``make(context)`` of a model-based or user's learner (imported now)."""
        if self.family == "yours":
            return load_factory(self.entry_point, self.option)
        return load_entry(self.entry_point, f"learner {self.id}")  # type: ignore[no-any-return]

    def sources(self) -> tuple[str, ...]:
        """Where its learner's code starts, as roots of a result's closure
        (:func:`~ilc_steering.engine.closure.closure`): the entries it is built from, which no
        import statement reaches, and for RL its hyperparameter file."""
        if self.family == "RL":
            return (f"{_RL}:make_learner", rl_settings.__name__, f"ilc_steering.configs/rl/{self.id}.yaml")
        if self.family == "black-box":
            return (self.entry_point, f"{_BLACKBOX}:make_learner")
        return (self.entry_point,)

    def expected_seconds(self, budget: int) -> float:
        """A cell's rough cost [s]: its budget times :attr:`trial_seconds`."""
        return self.trial_seconds * budget

    def budget(self, budgets: Budgets, task: str = "", prior: str = "nominal") -> int:
        """Its budget [trials] under ``budgets`` on the config named ``task`` (RL reads its
        hyperparameter file there when ``budgets.rl_trials`` is None; bayes_opt is capped at its own)."""
        if self.family == "RL" and budgets.rl_trials is None:
            return int(rl_settings.hyperparameters(self.id, task, prior)["n_timesteps"])
        trials = int(getattr(budgets, self.budget_key))
        return trials if self.max_trials is None else min(trials, self.max_trials)

    def implementation(self) -> str:
        """What made its results: for RL the backend's package and version (SBX or SB3), for a
        black-box method its optimizer's, a user's learner its ``module:attr``, else this library's."""
        from importlib import metadata

        if self.family == "RL":
            return rl_settings.implementation(self.id)
        if self.family == "yours":
            return self.id if self.entry_point == self.id else self.summary
        if self.package is not None:
            return f"{self.package} {metadata.version(self.package)}"
        from ilc_steering import __version__

        return f"ilc-steering {__version__}"

    def make(self, context: LearnerContext, budget: int) -> Learner:
        """The learner for ``context`` and a budget of ``budget`` trials, with the context's
        ``learning.cost`` attached. A factory that raises (``sys.exit()`` included: anything but an
        interrupt) is a :class:`~ilc_steering.errors.LearnerError` naming the learner; one that makes
        something without ``act``, ``learn`` or ``reset`` is a ``ValueError`` naming what it lacks."""
        from ilc_steering.agents.costs import with_cost
        from ilc_steering.errors import INTERRUPTS, LearnerError, described

        if self.family == "RL":
            backend = rl_settings.rl_backend()  # a bad ILC_STEERING_RL_BACKEND is bad input
            params = rl_settings.hyperparameters(self.id, context.task, context.prior)
            make_rl = load_entry(f"{_RL}:make_learner", self.id)
            learner: Any = make_rl(self.id, params, budget, context.progress_bar, context, backend)
        elif self.family == "black-box":
            optimizer = load_entry(self.entry_point, f"learner {self.id}")
            learner = load_entry(f"{_BLACKBOX}:make_learner", self.id)(optimizer, context)
        else:
            factory = self.factory()
            try:
                learner = factory(context)
            except INTERRUPTS:
                raise
            except BaseException as error:  # a factory's sys.exit() is its failure, not success
                raise LearnerError(f"learner {self.id}: its factory raised {described(error)}") from error
        missing = [name for name in ("act", "learn", "reset") if not callable(getattr(learner, name, None))]
        if missing:
            lacks = " and ".join([", ".join(missing[:-1]), missing[-1]] if len(missing) > 1 else missing)
            raise BadInput(f"{self.option} {self.id}: made {type(learner).__name__}, which has no {lacks} method")
        return with_cost(learner, context)


def _model(id: str, entry: str, summary: str, **extra: Any) -> LearnerSpec:
    return LearnerSpec(
        id, "model-based", f"ilc_steering.agents.{entry}", "model_trials", summary, trial_seconds=0.03, **extra
    )


def _blackbox(id: str, optimizer: str, summary: str, package: str, **extra: Any) -> LearnerSpec:
    entry = optimizer if ":" in optimizer else f"{_BLACKBOX}:{optimizer}"
    extra.setdefault("trial_seconds", 7e-4)
    return LearnerSpec(id, "black-box", entry, "blackbox_trials", summary, package=package, **extra)


def _rl(id: str, **extra: Any) -> LearnerSpec:
    algorithm = rl_settings.ALGORITHMS[id]
    return LearnerSpec(
        id, "RL", f"{_RL}:make_learner", "rl_trials", algorithm.class_name, trial_seconds=5e-3, rl=algorithm, **extra
    )


REGISTRY: dict[str, LearnerSpec] = {
    spec.id: spec
    for spec in (
        _model(
            "ilc",
            "ilc:make_ilc",
            "eqs. 33-34 from the context's first trial (under the nominal prior, the nominal solution)",
        ),
        _model(
            "ilc_paper",
            "ilc:make_ilc_paper",
            "the paper's eqs. 33-34 exactly, its fictitious zero iteration first (run's default)",
            reproduce=True,
        ),
        _model("newton", "newton:make_newton", "Newton on the nominal model"),
        _model(
            "newton_ilc",
            "newton_ilc:make_newton_ilc",
            "re-identify the model's family from the trials, then Newton on the refit model",
            reproduce=True,
        ),
        _model(
            "robust_ilc",
            "robust_ilc:make_robust_ilc",
            "global identification, continuation and a trust region",
            reproduce=True,
        ),
        _blackbox("least_squares", "least_squares", "scipy least_squares (LM)", "scipy"),
        _blackbox("noisy_least_squares", "noisy_least_squares", "TRF on averaged residuals", "scipy"),
        _blackbox("gauss_newton", "gauss_newton", "Gauss-Newton, step halving", "scipy"),
        _blackbox("nelder_mead", "nelder_mead", "scipy Nelder-Mead", "scipy"),
        _blackbox("cma_es", "cma_es", "CMA-ES (cma)", "cma"),
        # BO is the method for a few hundred expensive trials: its GP costs about 0.05-0.2 s a
        # trial here (2 cores, max_points = 64), against under 2 ms for every other black-box method.
        _blackbox(
            "bayes_opt",
            "ilc_steering.agents.bayes_opt:bayes_opt",
            "TuRBO-1 (BoTorch)",
            "botorch",
            trial_seconds=0.1,
            max_trials=300,
        ),
        _rl("ppo"),
        _rl("sac"),
        _rl("td3"),
        # CrossQ gives NaN actions at trial 5 on unicycle_parking and trailer_bay under prior=nominal,
        # and at trial 110 (10 trials after it starts learning) under prior=none, measured at full
        # budget (results/tuning/sweep2/crossq.md): run only when named.
        _rl("crossq", by_default=False),
        _rl("tqc"),
    )
}
"""Every method id of the library, once."""


def ids(family: str | None = None) -> tuple[str, ...]:
    """The registry's ids, in its order (of one family, if given)."""
    return tuple(i for i, spec in REGISTRY.items() if family is None or spec.family == family)


METHODS = ids()
"""Every method id (a view of :data:`REGISTRY`)."""
DEFAULT_METHODS = tuple(i for i, spec in REGISTRY.items() if spec.by_default)
"""What ``compare`` runs when ``--methods`` is not given."""


def installed() -> dict[str, str]:
    """The learners the installed packages name in :data:`GROUP`: name -> ``module:attr``, read once
    per process (:func:`~ilc_steering.entries.read_plugins`: strings only, nothing is imported; an
    entry point that is malformed, names an id of the library or a learner another package names
    is skipped with a one-line warning)."""
    if not _READ:
        _READ.append(True)
        plugins, _ = read_plugins(
            GROUP, "learner", {id: spec.entry_point for id, spec in REGISTRY.items()}, "a learner of the library"
        )
        _INSTALLED.update(
            {plugin.name: (plugin.entry, plugin.package) for plugin in plugins if plugin.name not in REGISTRY}
        )
    return {name: entry for name, (entry, _) in _INSTALLED.items()}


def is_custom(method: str) -> bool:
    """A user's learner: a factory ``module:attr``, or an installed package's learner (:func:`installed`)."""
    return ":" in method or method in installed()


def lookup(name: str, option: str = "--methods") -> LearnerSpec:
    """The spec of ``name``: a registry id, a user's ``module:attr`` or an installed package's
    learner (imported now, so a factory that cannot be imported is refused before the first
    trial). ``ValueError`` naming ``option`` for anything else."""
    if name in REGISTRY:
        return REGISTRY[name]
    if isinstance(name, str) and is_custom(name):
        entry = installed().get(name, name)
        summary = "a user's learner" if entry == name else f"package {_INSTALLED[name][1]}'s learner {entry}"
        spec = LearnerSpec(name, "yours", entry, "custom_trials", summary, option=option)
        spec.factory()
        return spec
    what = "learner" if option == "--learner" else "method"
    plugins = f", an installed learner {sorted(installed())}" if installed() else ""
    raise BadInput(f"{option}: unknown {what} {name!r}; choose from {list(METHODS)}{plugins} or give module:attr")


def families(methods: Iterable[str] = ()) -> dict[str, tuple[str, ...]]:
    """Every family's ids, read from the registry when called, and ``yours``: the ``module:attr``
    among ``methods``."""
    found = {family: ids(family) for family in FAMILIES[:-1]}
    return {**found, "yours": tuple(dict.fromkeys(m for m in methods if is_custom(m)))}
