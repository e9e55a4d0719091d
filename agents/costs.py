r"""Section 7: learning that also minimizes a cost, with the coefficients eqs. 33-34 do not need.

With ``q > n - 1`` coefficients of ``v2``, ``W`` (eq. 25) has a null space: moving ``c2`` along
it leaves the nominal final state, hence the error dynamics of eq. 36, untouched. After the
eq. 34 update, :class:`NullSpaceCost` moves ``c2`` within that null space to where the cost is
least,

.. math::

    c_2 \leftarrow c_2 + W^{+}(\dots) + N y^*, \qquad y^* = \arg\min_y J(c_2 + N y),

with ``N`` an orthonormal basis of the null space of ``W`` at the next trial's ``c11`` (the limit
of the projected-gradient steps :math:`-\alpha (I - W^+ W) \nabla J`, found here by Nelder-Mead
over the few coordinates ``y``, since ``J`` has kinks). ``J`` is evaluated on the *nominal*
plant (:class:`~ilc_steering.core.family.ModelFamily` at ``theta = 0``, without its steering stop:
the motion eq. 23 predicts), simulated with the trajectory recorded. No trial is spent.

Costs (per trial, of the nominal motion):

- ``path_length``: the distance the robot's reference point travels [m] (a chained plant: of ``z``);
- ``curvature``: the integral of the squared curvature along the path, ``int (tan(phi)/ell)^2 ds``
  [1/m] for the car, ``int (dtheta/ds)^2 ds`` of the reference point's heading for the other
  robots (a unicycle, a trailer's axle) (a chained plant: ``int v2^2 dt``);
- ``steering_margin``: the integral of ``max(0, |phi| - (1 - STEERING_MARGIN) * limit)^2`` [rad^2 s]
  of the commanded wheel angle, which keeps the wheel off its stop by a margin (a robot with a
  steering limit only: a car, a car towing a trailer).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import numpy as np
import numpy.typing as npt

from ilc_steering.agents.base import Learner, LearnerContext
from ilc_steering.agents.ilc import ILCAgent
from ilc_steering.core.family import ModelFamily
from ilc_steering.core.integrate import OK
from ilc_steering.core.nominal import NominalModel
from ilc_steering.core.simulate import Trials, simulate
from ilc_steering.errors import BadInput

__all__ = [
    "COSTS",
    "COST_BOX",
    "MAX_EVALUATIONS",
    "PREDICTION_TOLERANCE",
    "STEERING_MARGIN",
    "NullSpaceCost",
    "with_cost",
]

Array = npt.NDArray[np.float64]

COSTS = ("none", "path_length", "curvature", "steering_margin")
"""``learning.cost``."""
STEERING_MARGIN = 0.1
"""``steering_margin`` keeps ``|phi|`` below ``(1 - STEERING_MARGIN)`` times the steering limit."""
COST_BOX = 3.0
"""The search keeps every ``|c2j|`` within this many times its natural magnitude
(:meth:`~ilc_steering.core.nominal.NominalModel.action_scale`), or the current ``|c2j|`` if larger:
the least cost of a nominal motion can lie at coefficients so large that the true plant's
motion, a few per cent off, is no longer near it (path length is least for a car that drives
straight and then turns on the spot)."""
PREDICTION_TOLERANCE = 1e-7
"""The largest relative gap between a simulated nominal motion's final ``z`` and eq. 23's for its cost to count."""
MAX_EVALUATIONS = 2000
"""The most cost evaluations (simulations of the nominal plant, no trial) of one update."""


class NullSpaceCost:
    """A cost of the nominal motion and its descent step in the null space of ``W``."""

    def __init__(self, model: NominalModel, name: str) -> None:
        if name not in COSTS[1:]:
            raise BadInput(f"learning.cost must be one of {list(COSTS)}, got {name!r}")
        if name == "steering_margin" and model.steering_limit is None:
            raise BadInput("learning.cost steering_margin needs a robot with a steering_limit")
        if model.profile.v2_terms <= model.dimension - 1:
            raise BadInput(
                f"learning.cost {name} needs v2_terms > n - 1 = {model.dimension - 1} (a null space of W), "
                f"got {model.profile.v2_terms}"
            )
        self.model = model
        self.name = name
        # The nominal plant without its stop: the motion eq. 23 predicts, whose commanded wheel angle
        # the steering margin bounds (at the stop itself the cost would have no gradient).
        self._family = ModelFamily(dataclasses.replace(model, steering_limit=None))
        self._plant = self._family.plant(np.zeros(self._family.size))
        self._box = COST_BOX * model.action_scale()[1:]
        per_trial: dict[str, Callable[[Array, Array], Array]] = {
            "path_length": self._path_length,
            "curvature": self._curvature,
            "steering_margin": self._steering_margin,
        }
        self._per_trial = per_trial[name]

    def values(self, c: Array) -> Array:
        """``J`` of a batch of coefficient vectors ``(B, 1 + q)`` on the nominal plant."""
        c = np.ascontiguousarray(np.atleast_2d(c), dtype=np.float64)
        start = self._plant.initial_state(self._family.to_configuration(self.model.z_start))
        x0 = np.broadcast_to(start, (len(c), start.size))
        trials = simulate(self._plant, self.model.profile, np.ascontiguousarray(x0), c, record=True)
        assert trials.states is not None and trials.times is not None
        q = self._plant.configuration(trials.states)
        return np.where(self._resolved(c, trials), self._per_trial(q, np.diff(trials.times)), np.inf)

    def _resolved(self, c: Array, trials: Trials) -> npt.NDArray[np.bool_]:
        """Whether each simulated nominal motion is the one eq. 23 predicts: it stayed in the chart and
        ends within ``PREDICTION_TOLERANCE`` of ``V z0 + W c2``. A motion that halts at the chart's edge,
        or one the fixed step does not resolve (near the edge the field is stiff), is no solution, but
        it could pass for a short or straight one."""
        inside = trials.status == OK
        ok = np.zeros(len(c), dtype=bool)
        if np.any(inside):
            z = self._family.to_chained(self._plant.configuration(trials.final[inside]))
            predicted = np.array([self.model.final_state(ci) for ci in c[inside]])
            gap = np.max(np.abs(z - predicted), axis=1) / (1.0 + np.max(np.abs(predicted), axis=1))
            ok[inside] = gap <= PREDICTION_TOLERANCE
        return ok

    def of_motion(self, q: Array, t: Array) -> Array:
        """``J`` of recorded motions: configurations ``(B, S, nq)`` at times ``(S,)`` [s] (any frame:
        every cost is invariant to a rotation of the plane), e.g. a true trial's trajectory."""
        return self._per_trial(np.asarray(q, dtype=np.float64), np.diff(np.asarray(t, dtype=np.float64)))

    def step(self, c: Array, W: Array) -> Array:
        """``c`` with its ``c2`` moved within the null space of ``W`` to the least ``J`` there:
        ``c2 + N y`` with ``N`` an orthonormal basis of the null space and ``y`` minimized by
        Nelder-Mead, from ``y = 0`` (so ``J`` never rises)."""
        from scipy.linalg import null_space
        from scipy.optimize import minimize

        basis = null_space(W)
        if basis.shape[1] == 0:
            return c
        scale = float(np.max(np.abs(c[1:]))) or 1.0
        bound = np.maximum(self._box, np.abs(c[1:]))

        def shifted(y: Array) -> Array:
            out = np.array(c, dtype=np.float64)
            out[1:] += basis @ (scale * y)
            return out

        def J(y: Array) -> float:
            candidate = shifted(y)
            if np.any(np.abs(candidate[1:]) > bound):
                return float("inf")
            return float(self.values(candidate)[0])

        start = np.zeros(basis.shape[1])
        # J is inf outside the box; Nelder-Mead's convergence test subtracts two such values (NaN, which
        # it treats as not converged): numpy's warning of it is noise from scipy's files, not the user's
        with np.errstate(invalid="ignore"):
            result = minimize(
                J, start, method="Nelder-Mead", options={"xatol": 1e-9, "fatol": 1e-14, "maxfev": MAX_EVALUATIONS}
            )
        return shifted(result.x) if result.fun < J(start) else np.array(c, dtype=np.float64)

    # Costs of recorded configurations q (B, S, nq) with step lengths dt (S - 1,) [s].
    def _path_length(self, q: Array, dt: Array) -> Array:
        points = q[..., :2] if self.model.chained_map.has_pose else q
        return np.asarray(np.sum(np.linalg.norm(np.diff(points, axis=1), axis=-1), axis=1), dtype=np.float64)

    def _curvature(self, q: Array, dt: Array) -> Array:
        return self.model.chained_map.curvature_cost(q, dt)

    def _steering_margin(self, q: Array, dt: Array) -> Array:
        bound = (1 - STEERING_MARGIN) * float(self.model.steering_limit or 0.0)
        excess = np.maximum(0.0, np.abs(0.5 * (q[:, 1:, 3] + q[:, :-1, 3])) - bound)
        return np.asarray(np.sum(excess**2 * dt, axis=1), dtype=np.float64)


def with_cost(learner: Learner, context: LearnerContext) -> Learner:
    """``learner`` with the context's ``learning.cost`` attached, if it is an eq. 33-34 learner
    (:class:`~ilc_steering.agents.ilc.ILCAgent`) and the cost is not ``none``; other learners are
    returned as they are. It lives here, not in ``agents/ilc.py``, because the cost simulates the
    nominal plant: the plain learner reaches no plant class."""
    if context.cost != "none" and isinstance(learner, ILCAgent):
        learner.cost = NullSpaceCost(context.model, context.cost)
    return learner
