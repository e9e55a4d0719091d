"""Black-box baselines: optimizers that see only the result of each trial, never the model.

Each one drives a one-trial env through ``env.step`` until it is stopped; as learners
(:func:`make_learner`) they drive the :class:`~ilc_steering.agents.adapters.TrialPort` of a
:class:`~ilc_steering.agents.adapters.PullLearner`, so the trial loop runs and counts every
trial they ask for, probes included. They search the ``[-1, 1]`` units of
:class:`~ilc_steering.boxes.SearchBox`: the residual box around the nominal solution
under ``prior="nominal"``, the env's whole action box under ``prior="none"``
(:meth:`~ilc_steering.agents.base.LearnerContext.search_box`). Their first trial is the
context's start (under the nominal prior, the nominal solution itself), and when one stalls it
restarts from a new seeded start near the centre, until the trial loop stops it at its budget.

- :func:`least_squares`: ``scipy.optimize.least_squares`` on the residual vector, Levenberg-
  Marquardt with a 2-point Jacobian (every function evaluation one trial), the residual taken
  at the point projected onto the box; its restarts use TRF within the box, which LM cannot;
- :func:`noisy_least_squares`: TRF on the residual averaged over ``repeats`` trials, with
  forward-difference probes sized to move the residual well above the measurement noise
  (scipy's default step differences noise), restarted where it stops;
- :func:`bayes_opt` (:mod:`ilc_steering.agents.bayes_opt`, the ``bo`` extra): TuRBO-1 with
  BoTorch on the log cost;
- :func:`gauss_newton`: Gauss-Newton on the same residual with a forward-difference Jacobian
  (one probe trial per coefficient) and step halving;
- :func:`nelder_mead`: scipy's Nelder-Mead (adaptive) on the cost;
- :func:`cma_es`: CMA-ES from the ``cma`` package (the ``rl`` extra) on the cost.

The cost is ``-reward``: for the car, Cartesian error [m] + orientation error [rad], plus
:data:`~ilc_steering.core.score.OFF_CHART_PENALTY` for a trial that left the chart. The residual
(:func:`residual`) is the measured ``error`` (``z^d - z(T)``) with one more entry, the same
penalty on a trial that left the chart, so that halting early is no shortcut for them either.
"""

from __future__ import annotations

from collections.abc import Callable
from itertools import count
from typing import Any

import gymnasium as gym
import numpy as np
import numpy.typing as npt
import scipy.optimize

from ilc_steering.agents.adapters import PullLearner
from ilc_steering.agents.base import LearnerContext
from ilc_steering.boxes import SearchBox
from ilc_steering.core.score import OFF_CHART_PENALTY
from ilc_steering.errors import BadInput

__all__ = [
    "cma_es",
    "gauss_newton",
    "least_squares",
    "make_learner",
    "nelder_mead",
    "noisy_least_squares",
    "residual",
]

Array = npt.NDArray[np.float64]
Optimizer = Callable[[gym.Env[Any, Any], LearnerContext], None]


def residual(info: dict[str, Any]) -> Array:
    """The residual a least-squares method minimises: ``info["error"]`` and a last entry that is
    :data:`~ilc_steering.core.score.OFF_CHART_PENALTY` if the trial left the chart, else 0."""
    penalty = OFF_CHART_PENALTY if info["left_chart"] else 0.0
    return np.append(np.asarray(info["error"], dtype=np.float64), penalty)


def _trial(env: gym.Env[Any, Any], x: Array) -> tuple[float, dict[str, Any]]:
    """One trial at search point ``x``: its cost ``-reward`` and its ``info``."""
    env.reset()
    _, reward, _, _, info = env.step(x)  # the SearchBox projects it onto the box
    return -float(reward), info


def cma_es(env: gym.Env[Any, Any], context: LearnerContext, sigma0: float = 0.1) -> None:
    """CMA-ES (Hansen's ``cma``) with step size ``sigma0`` in search units, bounded to the box; its
    start is evaluated first, and it restarts whenever its own termination criteria stop it."""
    import cma

    size = context.model.profile.num_coefficients
    options = {"bounds": [[-1.0] * size, [1.0] * size], "verbose": -9}
    own = OwnGlobalRandom()
    for restart in count():
        start = context.start_point(restart)
        if restart == 0:
            _trial(env, start)  # the first trial is the start (the nominal solution, under that prior)
        with own:  # seeds numpy's global RNG: this run's own state, not its neighbours'
            strategy = cma.CMAEvolutionStrategy(start, sigma0, {**options, "seed": context.seed + 1000 * restart + 1})
        while True:
            with own:
                if strategy.stop():
                    break
                candidates = strategy.ask()
            costs = [_trial(env, x)[0] for x in candidates]
            with own:
                strategy.tell(candidates, costs)


class OwnGlobalRandom:
    """numpy's global RNG (``np.random``) with a state of one optimizer's own inside ``with``.

    ``cma`` seeds and draws from the global RNG; two CMA-ES learners stepped together (a sweep's
    row) would draw from one stream, each learner's samples depending on its neighbours. Inside
    ``with`` the global RNG holds this optimizer's state; outside, whatever it held before. The
    optimizer's own draws are then those of a run alone (bit for bit: ``tests/test_purity.py``).
    Never held across a trial, where other learners run."""

    def __init__(self) -> None:
        self._state: Any = None

    def __enter__(self) -> None:
        self._outside = np.random.get_state()
        if self._state is not None:
            np.random.set_state(self._state)

    def __exit__(self, *exc: object) -> None:
        self._state = np.random.get_state()
        np.random.set_state(self._outside)


def nelder_mead(env: gym.Env[Any, Any], context: LearnerContext, step: float = 0.1) -> None:
    """scipy's Nelder-Mead (adaptive) from a simplex of edge ``step`` [search units] at its start
    (evaluated first), restarted whenever it converges."""
    for restart in count():
        start = context.start_point(restart)
        simplex = np.vstack([start, start + step * np.eye(start.size)])
        scipy.optimize.minimize(
            lambda y: _trial(env, y)[0],
            start,
            method="Nelder-Mead",
            options={
                "xatol": 1e-12,
                "fatol": 1e-14,
                "maxfev": 10**9,
                "adaptive": True,
                "initial_simplex": simplex,
            },
        )


def gauss_newton(env: gym.Env[Any, Any], context: LearnerContext, probe: float = 1e-6) -> None:
    """Gauss-Newton on :func:`residual` with a forward-difference Jacobian (``probe`` in search
    units, one trial per coefficient); a step that does not lower the residual is halved, and
    after 30 halvings the method restarts."""
    for restart in count():
        x = context.start_point(restart)
        r = residual(_trial(env, x)[1])
        improved = True
        while improved:
            jacobian = np.empty((r.size, x.size))
            for j in range(x.size):
                h = probe if x[j] + probe <= 1.0 else -probe
                shifted = x.copy()
                shifted[j] += h
                jacobian[:, j] = (residual(_trial(env, shifted)[1]) - r) / h
            step = np.linalg.lstsq(jacobian, -r, rcond=None)[0]
            improved = False
            for _ in range(30):
                candidate = np.clip(x + step, -1.0, 1.0)
                new = residual(_trial(env, candidate)[1])
                if np.linalg.norm(new) < np.linalg.norm(r):
                    x, r, improved = candidate, new, True
                    break
                step *= 0.5


def least_squares(env: gym.Env[Any, Any], context: LearnerContext) -> None:
    """``scipy.optimize.least_squares`` on :func:`residual`, 2-point Jacobian: LM from the start
    (the residual taken at the point projected onto the box), then TRF within the box from each
    new start whenever it stops. LM needs at least as many residuals as coefficients; where there
    are fewer (``v2_terms > n``), every run is TRF."""
    size = context.model.profile.num_coefficients
    lm_fits = context.model.dimension + 1 >= size
    tolerances = {"ftol": 1e-15, "xtol": 1e-15, "gtol": 1e-15}
    for restart in count():
        start = context.start_point(restart)
        if restart == 0 and lm_fits:
            scipy.optimize.least_squares(
                lambda y: residual(_trial(env, y)[1]), start, method="lm", max_nfev=10**9, **tolerances
            )
        else:
            scipy.optimize.least_squares(
                lambda y: residual(_trial(env, y)[1]),
                start,
                method="trf",
                bounds=(-1.0, 1.0),
                x_scale="jac",  # with unit scales TRF stalls at the centre of the box (measured)
                max_nfev=10**9,
                **tolerances,
            )


def noisy_least_squares(
    env: gym.Env[Any, Any],
    context: LearnerContext,
    probe: float = 0.1,
    repeats: int = 1,
    resizes: int = 3,
    growth: float = 2.0,
) -> None:
    """Gauss-Newton on :func:`residual` averaged over ``repeats`` trials at each point, built not
    to be fooled by measurement noise:

    - forward-difference probes sized to the residual, not to the coefficients: each column's
      step is rescaled until its probe moves the residual by about ``probe`` [residual units: m,
      rad] (at most ``resizes`` more probes while a change is over 3 times off). A noise of sigma
      then perturbs a column by about sigma / probe of its size; scipy's fixed step (1.5e-8 of the
      coefficient) differences noise, and no one step fits every column here (the residual's
      sensitivities to the coefficients differ by 300 times);
    - full steps with no acceptance test, as ILC takes them: near the noise floor a test of
      "did the residual fall?" rejects good steps at random and stalls (scipy's TRF and LM do);
      only a residual ``growth`` times the best one so far counts as a failed step, and sends it
      back to the best point with a Jacobian measured there.

    The Jacobian is measured again whenever a step fails. Every trial counts, probes and repeats
    included."""
    if not probe > 0 or repeats < 1 or resizes < 0 or not growth > 1:
        raise BadInput(
            "noisy_least_squares: probe > 0, repeats >= 1, resizes >= 0 and growth > 1, "
            f"got {probe!r}, {repeats!r}, {resizes!r}, {growth!r}"
        )
    size = context.model.profile.num_coefficients
    steps = np.full(size, 1e-4)  # [search units]; the first Jacobian resizes them

    def averaged(y: Array) -> Array:
        return np.mean([residual(_trial(env, y)[1]) for _ in range(repeats)], axis=0)  # type: ignore[no-any-return]

    def jacobian(y: Array, r: Array) -> Array:
        columns = []
        for j in range(size):
            for _ in range(resizes + 1):
                h = steps[j] if y[j] + steps[j] <= 1.0 else -steps[j]
                shifted = y.copy()
                shifted[j] += h
                change = averaged(shifted) - r
                moved = float(np.linalg.norm(change))
                steps[j] = np.clip(abs(h) * probe / moved, 1e-9, 0.5) if moved > 0 else min(10 * abs(h), 0.5)
                if probe / 3 <= moved <= 3 * probe:
                    break
            columns.append(change / h)
        return np.column_stack(columns)

    for restart in count():
        best_x = x = context.start_point(restart)
        best_r = r = averaged(x)
        inverse = np.linalg.pinv(jacobian(x, r))
        for _ in range(10 * size + 10):  # a stuck run restarts from a new start
            x = np.clip(x - inverse @ r, -1.0, 1.0)
            r = averaged(x)
            if np.linalg.norm(r) < np.linalg.norm(best_r):
                best_x, best_r = x, r
            elif np.linalg.norm(r) > growth * np.linalg.norm(best_r):
                x, r = best_x, best_r
                inverse = np.linalg.pinv(jacobian(x, r))


def make_learner(optimizer: Optimizer, context: LearnerContext) -> PullLearner:
    """A black-box ``optimizer(env, context)`` (a spec's entry in the registry) as a learner,
    seeded with ``context.seed``, in the search box of the context's prior."""

    def run(env: gym.Env[Any, Any]) -> None:
        optimizer(SearchBox(env, *context.search_box()), context)

    return PullLearner(run, context.action_space, context.observation_space)
