"""The checks before a run's first trial: a task that is ill-posed for its nominal model is refused
(:func:`check_task`), an integrator's step too coarse for the task is warned of
(:func:`step_warning`). ``run``, ``compare`` and ``sweep`` make them (through
:mod:`ilc_steering.runner`, which re-exports them)."""

from __future__ import annotations

import dataclasses
from typing import Any

import gymnasium as gym

from ilc_steering.config import SteeringConfig
from ilc_steering.core.external import is_external
from ilc_steering.core.nominal import MAX_NOMINAL_MISS
from ilc_steering.errors import BadInput

__all__ = ["MAX_STEP_MISS", "check_task", "step_warning"]


def check_task(env: gym.Env[Any, Any], where: str) -> None:
    """``ValueError`` naming ``where`` (the config) when the task is ill-posed for its nominal
    model: its exact solution (section 2.2) misses the goal, because ``W`` of eq. (23) is singular
    at the solution's ``c11``, or needs an action beyond the env's action box. Either way every
    learner's updates would be clipped or useless in every trial, and a run could only say "not
    converged"."""
    import numpy as np

    model = env.unwrapped.nominal_model  # type: ignore[attr-defined]
    c = model.solve()
    miss = model.miss(c)
    if miss > MAX_NOMINAL_MISS:
        _, W = model.transition(c[0])
        singular = np.linalg.svd(W, compute_uv=False)
        raise BadInput(
            f"{where}: an ill-posed task: the nominal model's exact solution misses the goal by {miss:.2g} of the "
            f"distance to it, W (eq. 23) being singular at c11 = {c[0]:.3g} (singular values down to "
            f"{singular[-1]:.2g}); change task.pieces or task.v1_fixed (v1 on one piece undone by another "
            "makes W singular) or raise task.v2_terms"
        )
    high = np.asarray(env.action_space.high, dtype=np.float64)  # type: ignore[attr-defined]
    beyond = np.flatnonzero(np.abs(c) > high)
    if beyond.size:
        i = int(beyond[0])
        raise BadInput(
            f"{where}: the nominal solution needs |c[{i}]| = {abs(c[i]):.3g}, beyond the action box "
            f"({high[i]:.3g}, task.action_bound); raise task.action_bound or leave it out (10x the nominal scale)"
        )


MAX_STEP_MISS = 0.01
"""The largest change of a trial's final configuration, as a fraction of the tightest tolerance,
when ``simulation.max_step`` is halved, for the step to be fine enough (:func:`step_warning`)."""


def step_warning(config: SteeringConfig) -> str | None:
    """A warning when ``simulation.max_step`` is too coarse for the task (None when it is fine):
    the step-halving test. The nominal solution is simulated at the step and at half of it; a
    final configuration that moves by more than :data:`MAX_STEP_MISS` of the tightest tolerance
    means the counts would be the integrator's, not the plant's. (A warning, not an error: a
    coarse step is a legitimate way to provoke a trial that leaves the chart.)

    It simulates the library's own plant (a simulation: no robot moves), and for an external
    plant (someone else's simulator, or a robot) the nominal model only: such a plant is driven
    once per counted trial and never by a check (``tests/test_scatter.py`` counts its drives)."""
    import numpy as np

    from ilc_steering.core.family import ModelFamily
    from ilc_steering.envs.scenario import Scenario

    if config.is_cyclic:
        return None
    if config.is_segmented:  # each segment is a one-trial task of its own
        return next((w for w in map(step_warning, config.segment_configs()) if w is not None), None)
    step = config.simulation.max_step
    finer = dataclasses.replace(config, simulation=dataclasses.replace(config.simulation, max_step=step / 2))
    coarse, fine = Scenario.from_config(config), Scenario.from_config(finer)
    model = coarse.nominals[0]
    c = model.solve()[None]
    if is_external(coarse.plant):
        families = [ModelFamily(model, max_step) for max_step in (step, step / 2)]
        configurations = [family.configurations(family.origin, c)[0][0] for family in families]
    else:
        configurations = [s.plant.configuration(s.run(c).final)[0] for s in (coarse, fine)]
    miss = float(np.max(np.abs(configurations[0] - configurations[1])))
    tolerance = config.learning.tolerance
    tightest = min(v for v in (tolerance.cartesian, tolerance.orientation, tolerance.error) if v is not None)
    if np.isfinite(miss) and miss <= MAX_STEP_MISS * tightest:
        return None
    return (
        f"warning: {config.name}: simulation.max_step = {step:g} s is too coarse: halving it moves the final "
        f"configuration by {miss:.2g}, over {MAX_STEP_MISS:.0%} of the tolerance {tightest:g}, so the counts are "
        "the integrator's, not the plant's; lower simulation.max_step (default 1/32 s)"
    )
