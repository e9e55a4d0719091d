"""Black-box baselines: optimizers that see only the result of each trial, never the model.

Each one drives a one-trial env through ``env.step`` until it is stopped; as learners
(:func:`make_learner`) they drive the :class:`~ilc_steering.agents.adapters.TrialPort` of a
:class:`~ilc_steering.agents.adapters.PullLearner`, so the trial loop runs and counts every
trial they ask for, probes included. They work in the rescaled ``[-1, 1]`` box of
``RescaleAction`` and minimise ``-reward`` (for the car: Cartesian error [m] + orientation
error [rad]):

- :func:`cma_es`: CMA-ES from the ``cma`` package (the ``rl`` extra);
- :func:`nelder_mead`: scipy's Nelder-Mead;
- :func:`gauss_newton`: Gauss-Newton on the final error vector ``info["error"]``
  (``z^d - z(T)``), with a forward-difference Jacobian (one probe trial per coefficient) and
  step halving when a step does not shrink it.

Every method starts from a seeded point near the centre of the box (near ``c = 0``, the zero
iteration ILC starts from) and restarts from a new seeded point when it stalls: a trial that
leaves the chart leaves the car where it was, so the cost has flat plateaus. Each runs until the
trial loop stops it at its budget.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import gymnasium as gym
import numpy as np
import numpy.typing as npt
from gymnasium.wrappers import RescaleAction
from scipy.optimize import minimize

from ilc_steering.agents.adapters import PullLearner
from ilc_steering.agents.base import LearnerContext

__all__ = ["BLACKBOX_METHODS", "cma_es", "gauss_newton", "make_learner", "nelder_mead", "start_point"]

Array = npt.NDArray[np.float64]


def _box(env: gym.Env[Any, Any]) -> gym.spaces.Box:
    """The env's action space, which must be a ``Box``."""
    space = env.action_space
    if not isinstance(space, gym.spaces.Box):
        raise TypeError(f"a black-box optimizer needs a Box action space, got {space}")
    return space


def _trial(env: gym.Env[Any, Any], x: Array) -> tuple[float, dict[str, Any]]:
    """One trial at action ``x``: its cost ``-reward`` and its ``info``."""
    env.reset()
    _, reward, _, _, info = env.step(np.asarray(x, dtype=env.action_space.dtype))
    return -float(reward), info


def start_point(env: gym.Env[Any, Any], seed: int, spread: float = 0.02) -> Array:
    """A seeded point near the centre of the action box: ``spread`` of its half-widths."""
    space = _box(env)
    centre, half = 0.5 * (space.high + space.low), 0.5 * (space.high - space.low)
    return (centre + spread * half * np.random.default_rng(seed).uniform(-1, 1, size=space.shape)).astype(np.float64)


def cma_es(env: gym.Env[Any, Any], seed: int, sigma0: float = 0.1) -> None:
    """CMA-ES (Hansen's ``cma``), step size ``sigma0`` in action units, bounded to the box;
    restarted from a new seeded point whenever its own termination criteria stop it."""
    import cma

    space = _box(env)
    options = {"bounds": [space.low.tolist(), space.high.tolist()], "verbose": -9}
    for restart in range(10**6):
        strategy = cma.CMAEvolutionStrategy(
            start_point(env, seed + 1000 * restart), sigma0, {**options, "seed": seed + 1000 * restart + 1}
        )
        while not strategy.stop():
            candidates = strategy.ask()
            strategy.tell(candidates, [_trial(env, x)[0] for x in candidates])


def nelder_mead(env: gym.Env[Any, Any], seed: int) -> None:
    """scipy's Nelder-Mead (adaptive), restarted from a new seeded point whenever it converges."""
    space = _box(env)
    for restart in range(10**6):
        minimize(
            lambda y: _trial(env, np.clip(y, space.low, space.high))[0],
            start_point(env, seed + 1000 * restart),
            method="Nelder-Mead",
            options={"xatol": 1e-12, "fatol": 1e-14, "maxfev": 10**9, "adaptive": True},
        )


def gauss_newton(env: gym.Env[Any, Any], seed: int, probe: float = 1e-6) -> None:
    """Gauss-Newton on ``r = info["error"]`` with a forward-difference Jacobian (``probe`` in
    action units, one trial per coefficient); a step that does not lower ``||r||`` is halved,
    and after 30 halvings the method restarts from a new seeded point."""
    space = _box(env)
    for restart in range(10**6):
        x = start_point(env, seed + 1000 * restart)
        residual = np.asarray(_trial(env, x)[1]["error"], dtype=np.float64)
        improved = True
        while improved:
            jacobian = np.empty((residual.size, x.size))
            for j in range(x.size):
                h = probe if x[j] + probe <= space.high[j] else -probe
                shifted = x.copy()
                shifted[j] += h
                jacobian[:, j] = (np.asarray(_trial(env, shifted)[1]["error"]) - residual) / h
            step = np.linalg.lstsq(jacobian, -residual, rcond=None)[0]
            improved = False
            for _ in range(30):
                candidate = np.clip(x + step, space.low, space.high)
                new = np.asarray(_trial(env, candidate)[1]["error"], dtype=np.float64)
                if np.linalg.norm(new) < np.linalg.norm(residual):
                    x, residual, improved = candidate, new, True
                    break
                step *= 0.5


BLACKBOX_METHODS = {"cma_es": cma_es, "nelder_mead": nelder_mead, "gauss_newton": gauss_newton}


def make_learner(method: str, context: LearnerContext) -> PullLearner:
    """Black-box ``method`` (a key of :data:`BLACKBOX_METHODS`) as a learner, seeded with
    ``context.seed``, in the ``[-1, 1]`` rescaling of the context's action box."""
    optimizer: Callable[[gym.Env[Any, Any], int], None] = BLACKBOX_METHODS[method]

    def run(env: gym.Env[Any, Any]) -> None:
        optimizer(RescaleAction(env, np.float32(-1), np.float32(1)), context.seed)

    return PullLearner(run, context.action_space, context.observation_space)
