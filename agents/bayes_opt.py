"""Bayesian optimization of the trial's log error: TuRBO-1 with BoTorch (the ``bo`` extra).

A Gaussian process (BoTorch's ``SingleTaskGP``: Matérn-5/2 kernel with one length scale per
coefficient, its hyperparameters fitted by maximum marginal likelihood before every trial) models
``-log10(cost)`` over the ``[-1, 1]`` units of
:class:`~ilc_steering.agents.adapters.SearchBox`; the cost spans ten decades, and a GP on the raw
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
TuRBO's model is local, and this bounds the cost of a trial (``docs/benchmarks/baselines.md``).
"""

from __future__ import annotations

import math
from itertools import count
from typing import Any

import gymnasium as gym
import numpy as np
import numpy.typing as npt

from ilc_steering.agents.base import LearnerContext

__all__ = ["MAX_TRIALS", "bayes_opt"]

Array = npt.NDArray[np.float64]
MAX_TRIALS = 300
"""The budget ``compare`` gives ``bayes_opt`` at most [trials]: BO is the method for a few hundred
expensive trials, and its GP costs about 0.25 s a trial here (2 cores, ``max_points`` = 64),
against under 2 ms for every other black-box method."""
COST_FLOOR = 1e-12
"""The smallest cost the log model tells apart [m + rad]."""


def _objective(env: gym.Env[Any, Any], x: Array) -> float:
    """One trial at search point ``x``: ``-log10(cost)``, to be maximized."""
    env.reset()
    _, reward, _, _, _ = env.step(x)
    return -math.log10(max(-float(reward), COST_FLOOR))


def _next_point(x: Array, y: Array, centre: Array, length: float, seed: int, candidates: int) -> Array:
    """The maximizer of the log expected improvement of a GP on ``(x, y)`` over ``candidates``
    scrambled-Sobol points of the trust region (edge ``length`` at ``centre``, stretched by the GP's
    length scales, within the box)."""
    import torch
    from botorch.acquisition.analytic import LogExpectedImprovement
    from botorch.exceptions.errors import ModelFittingError
    from botorch.fit import fit_gpytorch_mll
    from botorch.models import SingleTaskGP
    from gpytorch.mlls import ExactMarginalLogLikelihood

    train_x = torch.as_tensor(0.5 * (x + 1.0), dtype=torch.float64)  # the GP's inputs in [0, 1]
    train_y = torch.as_tensor(y, dtype=torch.float64).unsqueeze(-1)
    model = SingleTaskGP(train_x, train_y)  # standardizes y itself
    try:
        fit_gpytorch_mll(ExactMarginalLogLikelihood(model.likelihood, model))
    except ModelFittingError:  # a failed fit keeps the prior hyperparameters, as BoTorch's own loops do
        pass
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
    return np.asarray(2.0 * points[int(values.argmax())].numpy() - 1.0, dtype=np.float64)


def bayes_opt(
    env: gym.Env[Any, Any],
    context: LearnerContext,
    initial_length: float = 0.8,
    min_length: float = 1e-6,
    max_length: float = 1.6,
    success_tolerance: int = 3,
    max_points: int = 64,
    candidates: int = 1024,
) -> None:
    """TuRBO-1 on ``-log10(cost)`` in the search box: lengths in ``[-1, 1]`` box units, tolerances
    in trials; restarts whenever the trust region shrinks below ``min_length``."""
    import torch

    threads = torch.get_num_threads()
    torch.set_num_threads(1)  # GPs of 64 points: more threads only cost; the caller's count comes back
    try:
        _turbo(env, context, initial_length, min_length, max_length, success_tolerance, max_points, candidates)
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
) -> None:
    import torch

    size = context.model.profile.num_coefficients
    failure_tolerance = max(4, size)
    for restart in count():
        start = context.start_point(restart)
        rng = np.random.default_rng([context.seed, restart, 1])
        sobol = torch.quasirandom.SobolEngine(size, scramble=True, seed=int(rng.integers(2**31)))  # type: ignore[no-untyped-call]
        design = start + 0.5 * initial_length * (2.0 * sobol.draw(2 * size, dtype=torch.float64).numpy() - 1.0)
        xs = [start, *np.clip(design, -1.0, 1.0)]
        ys = [_objective(env, x) for x in xs]
        length, successes, failures = initial_length, 0, 0
        while length >= min_length:
            x, y = np.asarray(xs), np.asarray(ys)
            centre = x[int(y.argmax())]
            near = np.argsort(np.max(np.abs(x - centre), axis=1), kind="stable")[:max_points]
            candidate = _next_point(x[near], y[near], centre, length, int(rng.integers(2**31)), candidates)
            value = _objective(env, candidate)
            improved = value > y.max() + 1e-3 * abs(y.max())
            successes, failures = (successes + 1, 0) if improved else (0, failures + 1)
            if successes == success_tolerance:
                length, successes = min(2.0 * length, max_length), 0
            elif failures == failure_tolerance:
                length, failures = 0.5 * length, 0
            xs.append(candidate)
            ys.append(value)
