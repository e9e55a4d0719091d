r"""The oracle of a robustness map: where the *true* plant can reach the goal at all.

**It knows the true plant.** It is never a learner and never enters a comparison: it marks the
region of a map where a learner *could* converge, so that a learner's map is read against it
(``ilc-steering sweep --oracle``). For every plant of the map it asks whether some coefficients
``c`` of the task's own input profile bring the true robot to the goal, the final error
(``z^d - z(T)`` in the nominal chained coordinates, the learner's own measure, noise-free) below
:data:`SOLVED` without leaving the chart. It searches by Levenberg-Marquardt on the true plant's
final error (free simulations, no trial counted), from

- the nominal solution ``model.solve()``;
- by continuation along the straight path from the map's centre plant (the nominal geometry of a
  ratio map) in :data:`HOMOTOPY_STEPS` steps, each solved from the last;
- by continuation, the solutions of already solved neighbouring plants: the rows are solved from
  the one nearest the config's own plant outwards, each plant from its neighbours in the row
  before, then again from its solved neighbours in its own row until nothing changes.

A plant is *solvable* when any of these searches ends below :data:`SOLVED`. The search is
batched: one compiled call evaluates a Levenberg-Marquardt iteration of every plant of a row.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
import numpy.typing as npt

from ilc_steering.core.integrate import OK
from ilc_steering.core.plants import Plant
from ilc_steering.envs.scenario import PlantGroups, Scenario

__all__ = ["SOLVED", "oracle_map", "solve_plants"]

Array = npt.NDArray[np.float64]

SOLVED = 1e-7
"""A final error norm below this counts as reaching the goal."""
HOMOTOPY_STEPS = 8
"""Points of the straight path from the map's centre plant to each plant."""
_ITERATIONS = 60
_CONVERGED = 1e-10
"""[m or rad] the configuration error where a search stops."""


def _errors(scenario: Scenario, plants: PlantGroups, c: Array) -> tuple[Array, npt.NDArray[np.bool_]]:
    """The final configuration errors (task frame, m and rad) of trials ``c`` on ``plants``, each
    started and measured as its own plant is: better conditioned than the chained coordinates' far
    from the goal, and zero at the same place."""
    q, status = scenario.run_groups(c, plants)
    error = q - scenario.to_task(scenario.goal)
    ok = (status == OK) & np.all(np.isfinite(error), axis=1)
    return np.where(ok[:, None], error, np.inf), ok


def final_errors(scenario: Scenario, plants: Sequence[Plant], c: Array) -> Array:
    """The learner's measure of reaching the goal: the norm of ``z^d - z(T)`` (nominal chained
    coordinates, noise-free) of trial ``c[k]`` on ``plants[k]``; inf off the chart."""
    q, status = scenario.run_groups(np.ascontiguousarray(c), PlantGroups(plants))
    measured = scenario.measure_configurations(q, status)
    return np.where(measured["left_chart"], np.inf, measured["true_error_norm"])


def solve_plants(scenario: Scenario, plants: Sequence[Plant], starts: Array) -> tuple[Array, Array]:
    """Levenberg-Marquardt on each plant's true final error from ``starts`` ``(M, 1 + q)``; returns
    the coefficients reached ``(M, 1 + q)`` and their final error norms ``(M,)`` (inf off the chart)."""
    low, high = scenario_box(scenario)
    scale = scenario.nominal.action_scale()
    m, p = starts.shape
    c = np.clip(starts, low, high)
    groups = PlantGroups(plants)
    probe_groups = PlantGroups([plant for plant in plants for _ in range(p + 1)])
    r, _ = _errors(scenario, groups, c)
    cost = np.einsum("ij,ij->i", r, r)
    damping = np.full(m, 1e-3)
    h = 1e-7 * scale
    active = np.isfinite(cost) & (cost > _CONVERGED**2)
    for _ in range(_ITERATIONS):
        if not active.any():
            break
        probes = np.repeat(c, p + 1, axis=0).reshape(m, p + 1, p)
        probes[:, 1:, :] += np.diag(h)
        values, _ = _errors(scenario, probe_groups, probes.reshape(-1, p))
        values = values.reshape(m, p + 1, -1)
        with np.errstate(invalid="ignore"):  # a probe off the chart: inf - inf, that plant waits
            J = np.swapaxes(values[:, 1:, :] - values[:, :1, :], 1, 2) / h  # (m, n, p)
        finite = np.all(np.isfinite(J), axis=(1, 2))
        J[~finite] = 0.0
        # Gauss-Newton's minimum-norm step, halved until it improves (the problem is badly
        # conditioned where v1 is symmetric: a damped step stalls there), then damped steps.
        newton = -np.einsum("ipn,in->ip", np.linalg.pinv(J), np.where(np.isfinite(r), r, 0.0))
        gradient = np.einsum("inp,in->ip", J, np.where(np.isfinite(r), r, 0.0))
        normal = np.einsum("inp,inq->ipq", J, J)
        improved = np.zeros(m, dtype=np.bool_)
        for attempt in range(12):
            if attempt < 6:
                step = newton * 0.5**attempt
            else:
                diagonal = damping[:, None] * (np.diagonal(normal, axis1=1, axis2=2) + 1e-12)
                system = normal + np.einsum("ip,pq->ipq", diagonal, np.eye(p))
                step = -np.linalg.solve(system, gradient[..., None])[..., 0]
                damping *= 4
            candidate = np.clip(c + step, low, high)
            r_new, _ = _errors(scenario, groups, candidate)
            cost_new = np.einsum("ij,ij->i", r_new, r_new)
            accept = active & ~improved & finite & (cost_new < cost)
            c[accept], r[accept], cost[accept] = candidate[accept], r_new[accept], cost_new[accept]
            damping[accept] = 1e-3
            improved |= accept
            if not (active & finite & ~improved).any():
                break
        active &= improved & (cost > _CONVERGED**2)
    return c, np.sqrt(cost)


def scenario_box(scenario: Scenario) -> tuple[Array, Array]:
    """The env's action box [physical units] (the oracle searches where a learner may act)."""
    from ilc_steering.envs.trials import task_spaces

    space = task_spaces(scenario)[0]
    return np.asarray(space.low, dtype=np.float64), np.asarray(space.high, dtype=np.float64)


def oracle_map(
    scenario: Scenario, plants_of_row: Callable[[int, float], list[Plant]], size: int, centre: int
) -> dict[str, Any]:
    """The oracle over a ``size x size`` map whose row ``i`` is the plants ``plants_of_row(i, 1.0)``
    (``plants_of_row(i, s)``: the plants a fraction ``s`` of the way from the map's centre plant,
    ``s = 0``, to them): ``error[i][j]``, the smallest final error norm found (None: no search
    stayed in the chart), and
    ``solvable[i][j]`` (below :data:`SOLVED`). Rows are solved from ``centre`` outwards (see the
    module docstring)."""
    nominal = np.clip(scenario.nominal.solve(), *scenario_box(scenario))
    p = nominal.size
    solution = np.full((size, size, p), np.nan)
    error = np.full((size, size), np.inf)
    order = sorted(range(size), key=lambda i: (abs(i - centre), i))
    centre_plants = plants_of_row(centre, 0.0)
    anchor, _ = solve_plants(scenario, centre_plants[:1], nominal[None])
    for i in order:
        plants = plants_of_row(i, 1.0)
        _improve(scenario, plants, np.tile(nominal, (size, 1)), solution[i], error[i])
        before = i - 1 if i > centre else i + 1
        if i != centre and 0 <= before < size:
            for shift in (0, -1, 1):
                _improve(scenario, plants, _shifted(solution[before], shift), solution[i], error[i])
        todo = np.flatnonzero(error[i] >= SOLVED)
        if todo.size:
            # the straight path from the centre plant, solved at each of its points from the last
            c = np.tile(anchor[0], (todo.size, 1))
            for s in np.linspace(0.0, 1.0, HOMOTOPY_STEPS + 1)[1:]:
                on_path = plants_of_row(i, float(s))
                c, _ = solve_plants(scenario, [on_path[k] for k in todo], c)
            start = np.full((size, p), np.nan)
            start[todo] = c
            _improve(scenario, plants, start, solution[i], error[i])
        for _ in range(size):  # continuation along the row, from solved neighbours
            solved = error[i] < SOLVED
            for shift in (-1, 1):
                start = _shifted(np.where(solved[:, None], solution[i], np.nan), shift)
                _improve(scenario, plants, start, solution[i], error[i])
            if int((error[i] < SOLVED).sum()) == int(solved.sum()):
                break
    finite = [[float(e) if np.isfinite(e) else None for e in row] for row in error]
    return {"error": finite, "solvable": (error < SOLVED).tolist()}


def _shifted(solution: Array, shift: int) -> Array:
    """``solution`` moved by ``shift`` plants along the row (NaN where nothing moved in)."""
    out = np.full_like(solution, np.nan)
    if shift == 0:
        out[:] = solution
    elif shift > 0:
        out[shift:] = solution[:-shift]
    else:
        out[:shift] = solution[-shift:]
    return out


def _improve(
    scenario: Scenario,
    plants: list[Plant],
    start: Array,
    solution: Array,
    error: Array,
) -> None:
    """Search from ``start`` (rows with NaN skipped) where the plant is not solved yet,
    keeping the better of the result and ``solution`` / ``error`` (updated in place)."""
    todo = np.all(np.isfinite(start), axis=1) & (error >= SOLVED)
    index = np.flatnonzero(todo)
    if index.size == 0:
        return
    chosen = [plants[k] for k in index]
    c, _ = solve_plants(scenario, chosen, start[index])
    found = final_errors(scenario, chosen, c)
    better = found < error[index]
    solution[index[better]] = c[better]
    error[index[better]] = found[better]
