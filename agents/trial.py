"""A model-based learner's record of one measured trial, and a model family's outcome of trials.

The parts of ``newton_ilc`` and ``robust_ilc`` (:mod:`~ilc_steering.agents.identifier`,
:mod:`~ilc_steering.agents.solver`, :mod:`~ilc_steering.agents.scatter_band`) exchange trials as
:class:`Trial` records; they see only the nominal model (through a
:class:`~ilc_steering.core.family.ModelFamily`) and what was measured.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from ilc_steering.core.family import ModelFamily
from ilc_steering.core.nominal import NominalModel

__all__ = ["Trial", "final_chained", "measure"]

Array = npt.NDArray[np.float64]
Mask = npt.NDArray[np.bool_]


@dataclass
class Trial:
    """One measured trial."""

    c: Array
    """The coefficients it ran."""
    z: Array
    """Its measured final chained coordinates (meaningless if it left the chart)."""
    q: Array
    """Its measured final configuration (NaN if it left the chart)."""
    error: float
    """The norm of the measured configuration error [m and rad] (inf if it left the chart)."""
    ok: bool = True
    """Whether it stayed in the chart."""


def measure(model: NominalModel, family: ModelFamily, goal_q: Array, info: Mapping[str, Any]) -> Trial:
    """The :class:`Trial` of a trial's ``info`` (its ``action``, ``error`` and ``left_chart``)."""
    c = np.asarray(info["action"], dtype=np.float64)
    z = model.z_goal - np.asarray(info["error"], dtype=np.float64)
    ok = not bool(info.get("left_chart", False)) and bool(np.all(np.isfinite(z)))
    q = family.to_configuration(z) if ok else np.full(goal_q.shape, np.nan)
    return Trial(c, z, q, float(np.linalg.norm(q - goal_q)) if ok else np.inf, ok)


def final_chained(family: ModelFamily, thetas: Array, c: Array) -> tuple[Array, Mask]:
    """Final chained coordinates of trials ``c`` ``(B, 1 + q)`` on hypotheses ``thetas`` ``(B, size)``
    (NaN where a trial left the chart), and whether each stayed in it."""
    q, ok = family.configurations_many(thetas, c)
    z = np.full_like(q, np.nan)
    z[ok] = family.to_chained(q[ok])
    return z, ok
