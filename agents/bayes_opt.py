"""Bayesian optimization of the trial's log error: TuRBO-1 with BoTorch (the ``bo`` extra).

A Gaussian process (BoTorch's ``SingleTaskGP``: Matérn-5/2 kernel with one length scale per
coefficient, its hyperparameters fitted by maximum marginal likelihood every ``refit_every`` trials
and after every change of the trust region, and kept in between, the GP conditioned on every new
trial) models
``-log10(cost)`` over the ``[-1, 1]`` units of
:class:`~ilc_steering.boxes.SearchBox`; the cost spans ten decades, and a GP on the raw
cost sees only its largest trials. Each trial maximizes the log expected improvement
(``LogExpectedImprovement``) within a trust region around the best trial so far, as TuRBO does
(Eriksson et al., *Scalable Global Optimization via Local Bayesian Optimization*, NeurIPS 2019):
a box of edge ``length`` (in box units; each edge scaled by the GP's length scale over their
geometric mean, as TuRBO does) that doubles after ``success_tolerance`` improving trials
in a row and halves after ``failure_tolerance`` failing ones (TuRBO's ``max(4, d)``). The default
``min_length`` is far below TuRBO's 2**-7: the tolerances of this task lie 1e-4 of the box from
the solution, so the region must shrink that far before a restart.

Every trial counts, the initial design included: the first is the context's start (under
``prior="nominal"`` the nominal solution), then ``2 d`` scrambled-Sobol points in the first
region. When the region has shrunk below ``min_length``, TuRBO restarts from a new seeded start
with fresh data. The GP sees at most ``max_points`` trials, those nearest the region's centre:
TuRBO's model is local, and this bounds the cost of a trial (``results/benchmarks/baselines.md``).

Fitting the hyperparameters is most of a trial's cost (an L-BFGS run on the marginal likelihood);
between refits the GP keeps its fitted length scales, output scale and noise and is only
conditioned on the new data, as BoTorch's own loops allow. ``refit_every=1`` fits before every
trial, as the first version did (``results/benchmarks/bayes_opt_refit.md`` measures both).
"""

from __future__ import annotations

import math
from itertools import count
from typing import Any

import gymnasium as gym
import numpy as np
import numpy.typing as npt

from ilc_steering.agents.base import LearnerContext
from ilc_steering.errors import BadInput

__all__ = ["bayes_opt"]

Array = npt.NDArray[np.float64]
REFIT_EVERY = 8
"""Trials between two fits of the GP's hyperparameters (a change of the trust region refits too)."""
COST_FLOOR = 1e-12
"""The smallest cost the log model tells apart [m + rad]."""


def _objective(env: gym.Env[Any, Any], x: Array) -> float:
    """One trial at search point ``x``: ``-log10(cost)``, to be maximized."""
    env.reset()
    _, reward, _, _, _ = env.step(x)
    return -math.log10(max(-float(reward), COST_FLOOR))


def _next_point(
    x: Array, y: Array, centre: Array, length: float, seed: int, candidates: int, fitted: dict[str, Any] | None
) -> tuple[Array, dict[str, Any]]:
    """The maximizer of the log expected improvement of a GP on ``(x, y)`` over ``candidates``
    scrambled-Sobol points of the trust region (edge ``length`` at ``centre``, stretched by the GP's
    length scales, within the box), and the GP's hyperparameters: ``fitted`` if given (kept, the GP
    only conditioned on the data), else fitted now."""
    import torch
    from botorch.acquisition.analytic import LogExpectedImprovement
    from botorch.exceptions.errors import ModelFittingError
    from botorch.fit import fit_gpytorch_mll
    from botorch.models import SingleTaskGP
    from gpytorch.mlls import ExactMarginalLogLikelihood

    train_x = torch.as_tensor(0.5 * (x + 1.0), dtype=torch.float64)  # the GP's inputs in [0, 1]
    train_y = torch.as_tensor(y, dtype=torch.float64).unsqueeze(-1)
    model = SingleTaskGP(train_x, train_y)  # standardizes y itself, from this data
    if fitted is None:
        try:
            fit_gpytorch_mll(ExactMarginalLogLikelihood(model.likelihood, model))
        except ModelFittingError:  # a failed fit keeps the prior hyperparameters, as BoTorch's own loops do
            pass
        fitted = {k: v.detach().clone() for k, v in model.state_dict().items() if not k.startswith("outcome_transform")}
    else:
        model.load_state_dict(fitted, strict=False)  # the kernel's, likelihood's and mean's; y's scaling is this data's
    model.eval()
    kernel = model.covar_module
    scales = getattr(kernel, "base_kernel", kernel).lengthscale.detach().numpy().ravel()
    weights = scales / np.exp(np.mean(np.log(scales)))  # TuRBO: the region is stretched like the GP
    low = np.clip(centre - 0.5 * length * weights, -1.0, 1.0)
    high = np.clip(centre + 0.5 * length * weights, -1.0, 1.0)
    sobol = torch.quasirandom.SobolEngine(x.shape[1], scramble=True, seed=seed)  # type: ignore[no-untyped-call]
    unit = sobol.draw(candidates, dtype=torch.float64)
    points = torch.as_tensor(0.5 * (low + 1.0)) + unit * torch.as_tensor(0.5 * (high - low))  # in [0, 1]
    with torch.no_grad():
        values = LogExpectedImprovement(model, best_f=train_y.max())(points.unsqueeze(1))
    return np.asarray(2.0 * points[int(values.argmax())].numpy() - 1.0, dtype=np.float64), fitted


def bayes_opt(
    env: gym.Env[Any, Any],
    context: LearnerContext,
    initial_length: float = 0.8,
    min_length: float = 1e-6,
    max_length: float = 1.6,
    success_tolerance: int = 3,
    max_points: int = 64,
    candidates: int = 1024,
    refit_every: int = REFIT_EVERY,
) -> None:
    """TuRBO-1 on ``-log10(cost)`` in the search box: lengths in ``[-1, 1]`` box units, tolerances
    in trials; restarts whenever the trust region shrinks below ``min_length``; the GP's
    hyperparameters refitted every ``refit_every`` trials and whenever the region changes."""
    if isinstance(refit_every, bool) or not isinstance(refit_every, int) or refit_every < 1:
        raise BadInput(f"bayes_opt: refit_every must be a whole number of trials >= 1, got {refit_every!r}")
    import torch

    threads = torch.get_num_threads()
    torch.set_num_threads(1)  # GPs of 64 points: more threads only cost; the caller's count comes back
    try:
        _turbo(
            env, context, initial_length, min_length, max_length, success_tolerance, max_points, candidates, refit_every
        )
    finally:
        torch.set_num_threads(threads)


def _turbo(
    env: gym.Env[Any, Any],
    context: LearnerContext,
    initial_length: float,
    min_length: float,
    max_length: float,
    success_tolerance: int,
    max_points: int,
    candidates: int,
    refit_every: int,
) -> None:
    import torch

    size = context.model.profile.num_coefficients
    failure_tolerance = max(4, size)
    for restart in count():
        start = context.start_point(restart)
        rng = np.random.default_rng([context.seed, restart, 1])
        sobol = torch.quasirandom.SobolEngine(  # type: ignore[no-untyped-call]
            size,
            scramble=True,
            seed=int(rng.integers(2**31)),
        )
        design = start + 0.5 * initial_length * (2.0 * sobol.draw(2 * size, dtype=torch.float64).numpy() - 1.0)
        xs = [start, *np.clip(design, -1.0, 1.0)]
        ys = [_objective(env, x) for x in xs]
        length, successes, failures = initial_length, 0, 0
        fitted: dict[str, Any] | None = None
        since_fit = 0
        while length >= min_length:
            x, y = np.asarray(xs), np.asarray(ys)
            centre = x[int(y.argmax())]
            near = np.argsort(np.max(np.abs(x - centre), axis=1), kind="stable")[:max_points]
            if since_fit >= refit_every:
                fitted = None
            if fitted is None:
                since_fit = 0
            candidate, fitted = _next_point(
                x[near], y[near], centre, length, int(rng.integers(2**31)), candidates, fitted
            )
            since_fit += 1
            value = _objective(env, candidate)
            improved = value > y.max() + 1e-3 * abs(y.max())
            successes, failures = (successes + 1, 0) if improved else (0, failures + 1)
            if successes == success_tolerance:
                length, successes, fitted = min(2.0 * length, max_length), 0, None
            elif failures == failure_tolerance:
                length, failures, fitted = 0.5 * length, 0, None
            xs.append(candidate)
            ys.append(value)
