"""The learner registry: every method id once, with its factory, family, budget and implementation.

Gymnasium keeps one ``register`` table and one ``make``; this is that table for learners. Each
:class:`LearnerSpec` names its factory by a string (``"module:attr"``), so nothing is imported
before a learner is built, and every command builds learners one way, :meth:`LearnerSpec.make`
``(context, budget)``: ``run --learner``, ``compare --methods``, ``sweep --methods``, the
benchmarks and the tests. A user's factory ``module:attr`` is resolved by the same lookup,
:func:`lookup`, into a spec of family ``"yours"``.

Adding a learner to the library is one line of :data:`REGISTRY` (and its module)::

    LearnerSpec("my_method", "model-based", "ilc_steering.agents.my_module:make_my_method", "model_trials", "...")

The factory of a model-based learner, and a user's, is ``make(context) -> Learner``; the
black-box and RL families are built by :func:`ilc_steering.agents.blackbox.make_learner` and
:func:`ilc_steering.agents.rl.make_learner` from the id. :meth:`LearnerSpec.make` attaches the
config's ``learning.cost`` (:func:`ilc_steering.agents.costs.with_cost`) to every learner it
builds, so no command can drop it.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

from ilc_steering.agents.base import Learner, LearnerContext, LearnerFactory, load_factory
from ilc_steering.entries import load_entry

__all__ = [
    "DEFAULT_METHODS",
    "FAMILIES",
    "METHODS",
    "REGISTRY",
    "Budgets",
    "LearnerSpec",
    "families",
    "ids",
    "is_custom",
    "lookup",
]

FAMILIES = ("model-based", "black-box", "RL", "yours")
"""The families the comparison's figures colour by; ``yours``: a user's ``module:attr``."""


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

    def factory(self) -> LearnerFactory:
        """The factory ``make(context)`` of a model-based or user's learner (imported now)."""
        if self.family == "yours":
            return load_factory(self.id, self.option)
        return load_entry(self.entry_point, f"learner {self.id}")  # type: ignore[no-any-return]

    def budget(self, budgets: Budgets, task: str = "", prior: str = "nominal") -> int:
        """Its budget [trials] under ``budgets`` on the config named ``task`` (RL reads its
        hyperparameter file there when ``budgets.rl_trials`` is None; bayes_opt is capped at its own)."""
        if self.family == "RL" and budgets.rl_trials is None:
            from ilc_steering.agents.rl import hyperparameters

            return int(hyperparameters(self.id, task, prior)["n_timesteps"])
        trials = getattr(budgets, self.budget_key)
        if self.id == "bayes_opt":  # a GP's trial costs about 0.25 s: BO's budget is its own
            from ilc_steering.agents.bayes_opt import MAX_TRIALS

            return min(int(trials), MAX_TRIALS)
        return int(trials)

    def implementation(self) -> str:
        """What made its results: for RL the backend's package and version (SBX or SB3), for a
        black-box method its optimizer's, a user's learner its ``module:attr``, else this library's."""
        from importlib import metadata

        if self.family == "RL":
            from ilc_steering.agents.rl import implementation

            return implementation(self.id)
        if self.family == "yours":
            return self.id
        if self.package is not None:
            return f"{self.package} {metadata.version(self.package)}"
        from ilc_steering import __version__

        return f"ilc-steering {__version__}"

    def make(self, context: LearnerContext, budget: int) -> Learner:
        """The learner for ``context`` and a budget of ``budget`` trials, with the context's
        ``learning.cost`` attached. A factory that raises is a
        :class:`~ilc_steering.errors.LearnerError` naming the learner; one that makes something
        without ``act``, ``learn`` and ``reset`` is a ``ValueError``."""
        from ilc_steering.agents.costs import with_cost
        from ilc_steering.errors import LearnerError

        if self.family == "RL":
            from ilc_steering.agents import rl

            backend = rl.rl_backend()  # a bad ILC_STEERING_RL_BACKEND is bad input, not the learner's fault
            params = rl.hyperparameters(self.id, context.task, context.prior)
            learner: Any = rl.make_learner(self.id, params, budget, context.progress_bar, context, backend)
        elif self.family == "black-box":
            from ilc_steering.agents import blackbox

            learner = blackbox.make_learner(self.id, context)
        else:
            factory = self.factory()
            try:
                learner = factory(context)
            except Exception as error:
                raise LearnerError(f"learner {self.id}: its factory raised {type(error).__name__}: {error}") from error
        if not isinstance(learner, Learner):
            raise ValueError(
                f"{self.option} {self.id}: made {type(learner).__name__}, which has no act, learn and reset"
            )
        return with_cost(learner, context)


def _spec(id: str, family: str, entry: str, budget: str, summary: str, **extra: Any) -> LearnerSpec:
    return LearnerSpec(id, family, entry, budget, summary, **extra)


_BLACKBOX = "ilc_steering.agents.blackbox:make_learner"
_RL = "ilc_steering.agents.rl:make_learner"
REGISTRY: dict[str, LearnerSpec] = {
    spec.id: spec
    for spec in (
        _spec(
            "ilc",
            "model-based",
            "ilc_steering.agents.ilc:make_ilc",
            "model_trials",
            "eqs. 33-34 from the context's first trial (under the nominal prior, the nominal solution)",
        ),
        _spec(
            "ilc_paper",
            "model-based",
            "ilc_steering.agents.ilc:make_ilc_paper",
            "model_trials",
            "the paper's eqs. 33-34 exactly, its fictitious zero iteration first (run's default)",
            reproduce=True,
        ),
        _spec(
            "newton",
            "model-based",
            "ilc_steering.agents.newton:make_newton",
            "model_trials",
            "Newton on the nominal model",
        ),
        _spec(
            "newton_ilc",
            "model-based",
            "ilc_steering.agents.newton_ilc:make_newton_ilc",
            "model_trials",
            "re-identify the model's family from the trials, then Newton on the refit model",
            reproduce=True,
        ),
        _spec(
            "robust_ilc",
            "model-based",
            "ilc_steering.agents.robust_ilc:make_robust_ilc",
            "model_trials",
            "global identification, continuation and a trust region",
            reproduce=True,
        ),
        _spec("least_squares", "black-box", _BLACKBOX, "blackbox_trials", "scipy least_squares (LM)", package="scipy"),
        _spec(
            "noisy_least_squares",
            "black-box",
            _BLACKBOX,
            "blackbox_trials",
            "TRF on averaged residuals",
            package="scipy",
        ),
        _spec("gauss_newton", "black-box", _BLACKBOX, "blackbox_trials", "Gauss-Newton, step halving", package="scipy"),
        _spec("nelder_mead", "black-box", _BLACKBOX, "blackbox_trials", "scipy Nelder-Mead", package="scipy"),
        _spec("cma_es", "black-box", _BLACKBOX, "blackbox_trials", "CMA-ES (cma)", package="cma"),
        _spec("bayes_opt", "black-box", _BLACKBOX, "blackbox_trials", "TuRBO-1 (BoTorch)", package="botorch"),
        _spec("ppo", "RL", _RL, "rl_trials", "PPO"),
        _spec("sac", "RL", _RL, "rl_trials", "SAC"),
        _spec("td3", "RL", _RL, "rl_trials", "TD3"),
        # CrossQ gives NaN actions at trial 5 on unicycle_parking and trailer_bay under prior=nominal,
        # and at trial 110 (10 trials after it starts learning) under prior=none, measured at full
        # budget (docs/tuning/sweep2/crossq.md): run only when named.
        _spec("crossq", "RL", _RL, "rl_trials", "CrossQ", by_default=False),
        _spec("tqc", "RL", _RL, "rl_trials", "TQC"),
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


def is_custom(method: str) -> bool:
    """A user's learner factory, ``module:attr``."""
    return ":" in method


def lookup(name: str, option: str = "--methods") -> LearnerSpec:
    """The spec of ``name``: a registry id, or a user's ``module:attr`` (imported now, so a factory
    that cannot be imported is refused before the first trial). ``ValueError`` naming ``option``
    for anything else."""
    if name in REGISTRY:
        return REGISTRY[name]
    if isinstance(name, str) and is_custom(name):
        spec = LearnerSpec(name, "yours", name, "custom_trials", "a user's learner", option=option)
        spec.factory()
        return spec
    what = "learner" if option == "--learner" else "method"
    raise ValueError(f"{option}: unknown {what} {name!r}; choose from {list(METHODS)} or give module:attr")


def families(methods: Iterable[str] = ()) -> dict[str, tuple[str, ...]]:
    """Every family's ids, read from the registry when called, and ``yours``: the ``module:attr``
    among ``methods``."""
    found = {family: ids(family) for family in FAMILIES[:-1]}
    return {**found, "yours": tuple(dict.fromkeys(m for m in methods if is_custom(m)))}
