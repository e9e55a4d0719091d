"""When a run has converged: its :class:`Verdict`, and the plant's scatter estimated from its trials.

A run has converged when its last trials *hold* the tolerance: the last
:data:`~ilc_steering.core.scatter.HOLD` trials (or cycles) in a row, by default, within it. A
stretch within the tolerance that ended before the run did is a relapse, reported with its trials.
A one-trial run also estimates the plant's scatter from its own trials
(:func:`ilc_steering.core.scatter.estimate`, :func:`with_scatter`); when the tolerance is below the
repeatability that scatter allows, the verdict says so, and a run whose last trials are within
that repeatability has converged to the plant's floor.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Protocol

from ilc_steering.config import SteeringConfig
from ilc_steering.core import scatter as scatter_
from ilc_steering.core.nominal import NominalModel
from ilc_steering.core.robots.car import rotate

__all__ = ["APART", "APART_TRIALS", "Trial", "Verdict", "apart", "verdict", "with_scatter"]


class Trial(Protocol):
    """What the scatter's estimate reads of a trial's record (:class:`ilc_steering.runner.TrialRecord`)."""

    @property
    def error_norm(self) -> float: ...
    @property
    def cartesian_error(self) -> float | None: ...
    @property
    def orientation_error(self) -> float | None: ...
    @property
    def final_state(self) -> list[float]: ...
    @property
    def error(self) -> list[float]: ...
    @property
    def action(self) -> list[float]: ...
    @property
    def left_chart(self) -> bool: ...


@dataclass(frozen=True)
class Verdict:
    """What a run's trials (or cycles) say: whether it converged, and how well it could.

    ``converged_at`` is the first trial of the stretch within the tolerance that the run ends
    with, when that stretch is at least ``hold`` trials long (None otherwise): one trial within it
    may be the scatter's luck, and a learner that chases the scatter leaves again (see
    :data:`~ilc_steering.core.scatter.HOLD`)."""

    converged_at: int | None
    hold: int
    """Trials in a row within the tolerance, at the end, that convergence needs."""
    held: int
    """Trials in a row within the tolerance at the end of the run."""
    relapses: list[list[int]] = dataclasses.field(default_factory=list)
    """``[first, last]`` trial of each stretch within the tolerance that the run left again."""
    scatter: dict[str, float] | None = None
    """The plant's scatter estimated from the run's trials, per coordinate (``cartesian`` [m] of
    x and y, ``orientation`` [rad]; ``error`` for a plant without a pose) and ``dof``, the
    residual degrees of freedom; None when too few trials qualify (a cyclic run: never)."""
    below: dict[str, list[float]] = dataclasses.field(default_factory=dict)
    """Each bound of the tolerance that is below the plant's repeatability
    (:data:`~ilc_steering.core.scatter.FLOOR` times its scatter): ``[bound, repeatability]``."""
    floor: bool = False
    """Not converged, but the tolerance is below the repeatability and the last ``hold`` trials
    are within the repeatability: converged to the plant's floor."""

    def to_json(self) -> dict[str, Any]:
        return {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}


def _stretches(met: list[bool]) -> list[list[int]]:
    """``[first, last]`` (1-based) of each run of ``True`` in ``met``."""
    out: list[list[int]] = []
    for k, inside in enumerate(met, start=1):
        if inside and out and out[-1][1] == k - 1:
            out[-1][1] = k
        elif inside:
            out.append([k, k])
    return out


def verdict(met: list[bool], hold: int = scatter_.HOLD) -> Verdict:
    """The :class:`Verdict` of a run whose trial ``k`` met the tolerance when ``met[k - 1]``
    (before any scatter is estimated)."""
    stretches = _stretches(met)
    held = stretches[-1][1] - stretches[-1][0] + 1 if stretches and stretches[-1][1] == len(met) else 0
    relapses = stretches[:-1] if held else stretches
    converged_at = stretches[-1][0] if held >= hold else None
    return Verdict(converged_at, hold, held, relapses)


APART_TRIALS = 5
"""The last in-chart trials whose outcomes :func:`apart` compares with the scatter."""
APART = 1 / 16
"""The least half mean square of consecutive outcomes' differences, in units of the scatter's square,
for the scatter to be the plant's (:func:`apart`)."""


def apart(outcomes: Any, sigma: Any, groups: Sequence[Sequence[int]]) -> bool:
    """Whether consecutive outcomes ``(m, nq)`` (the last in-chart trials' deviations from the goal)
    differ from one another as draws of a scatter ``sigma`` (one per group) do: half the mean square
    of their differences per coordinate, in units of ``sigma**2``, at least :data:`APART` (von
    Neumann's estimate of the variance, which a learner's slow drift leaves alone).

    Two draws of a plant that scatters by ``sigma`` differ by ``sqrt(2) sigma`` on average, whatever
    the learner sends between them; trials that land within a quarter of that of one another, trial
    after trial, show a plant that repeats itself, and an estimate from a model's residuals is the
    model's misfit (``robust_ilc`` creeping far off on a deterministic MuJoCo car: 0.02 of
    ``sigma**2``; single runs on ``forward_parking_noisy`` and ``mujoco_forward_parking_scatter``,
    per group of coordinates: 0.3-3.6). It sits beside ``core.scatter.consistent`` in spirit; it is
    here, not there, because it judges ``run``'s claim and not a learner's estimate. With fewer
    than two outcomes it says nothing (true). Draws of a normal scatter fall below the bound with a
    probability of 7e-6 over five trials of a pose, 1.5e-3 over three (2e6 simulated runs each)."""
    import numpy as np

    outcomes = np.asarray(outcomes, dtype=np.float64)
    if outcomes.shape[0] < 2:
        return True
    half = 0.5 * np.diff(outcomes, axis=0) ** 2
    scaled = [half[:, list(g)] / max(float(s), scatter_.MIN_SCATTER) ** 2 for s, g in zip(sigma, groups)]
    return float(np.mean(np.concatenate([x.ravel() for x in scaled]))) >= APART


def with_scatter(config: SteeringConfig, model: NominalModel, records: Sequence[Trial], result: Verdict) -> Verdict:
    """``result`` with the plant's scatter estimated from ``records`` (their residuals against
    ``model``, the nominal model's eq. 23, in the world frame), the bounds of the tolerance
    below its repeatability and whether the run converged to the plant's floor; none of it for a
    plant that has repeated itself (:func:`~ilc_steering.core.scatter.repeats`)."""
    import numpy as np

    if len(records) < 2:
        return result
    errors = np.array([np.inf if r.left_chart else float(np.linalg.norm(r.error)) for r in records])
    tolerance = config.learning.tolerance
    predicted = np.array([model.final_state(np.asarray(r.action)) for r in records])
    groups: tuple[tuple[int, ...], ...]
    names: tuple[str, ...]
    bounds: tuple[float | None, ...]
    if config.plant.kind.has_pose:
        predicted = model.chained_map.from_chained(predicted)
        if config.frame():
            predicted = rotate(predicted, -config.frame())
        goal = np.asarray(config.points()[1][1], dtype=np.float64)[:3]
        deviations = np.array([r.final_state[:3] for r in records]) - goal
        outcomes = np.array([r.final_state[:3] for r in records]) - predicted[:, :3]
        groups, names = ((0, 1), (2,)), ("cartesian", "orientation")
        bounds = (tolerance.cartesian, tolerance.orientation)
        true = np.array([[r.cartesian_error or 0.0, r.orientation_error or 0.0] for r in records])
    else:
        deviations = np.array([r.error for r in records])
        outcomes = deviations - (model.z_goal - predicted)
        groups, names = (tuple(range(outcomes.shape[1])),), ("error",)
        bounds = (tolerance.error,)
        true = np.array([[r.error_norm] for r in records])
    finals = np.array([np.asarray(r.final_state, dtype=np.float64) for r in records])
    if scatter_.repeats(np.array([r.action for r in records]), finals):
        return result  # one action sent twice ended twice at one place (in the chart or halted): no scatter
    found = scatter_.estimate(outcomes, errors, groups)
    if found is None:
        return result
    sigma, dof = found
    estimate = {name: float(value) for name, value in zip(names, sigma)}
    reach = [scatter_.repeatability(value) for value in sigma]
    landed = deviations[[not r.left_chart for r in records]][-APART_TRIALS:]
    if not scatter_.consistent(deviations[-result.hold :], sigma, groups) or not apart(landed, sigma, groups):
        reach = [None for _ in sigma]  # the last trials land well inside it: the learner's moves, not the plant's
    below = {
        name: [bound, r]
        for name, bound, r in zip(names, bounds, reach)
        if bound is not None and r is not None and bound < r
    }
    floor = False
    if below and result.converged_at is None and len(records) >= result.hold:
        ceiling = np.array([max(b or np.inf, r or 0.0) for b, r in zip(bounds, reach)])
        last = records[-result.hold :]
        floor = not any(r.left_chart for r in last) and bool(np.all(true[-result.hold :] <= ceiling))
    return dataclasses.replace(result, scatter={**estimate, "dof": dof}, below=below, floor=floor)
