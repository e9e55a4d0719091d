"""A trial's recorded motion: times, configurations and inputs at every integrator step.

Recording is off by default (the fast path keeps only final states); ask for it with
``record_trajectory=True`` on an env, or ``Scenario.run(..., record=True)`` followed by
``Scenario.trajectory``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from ilc_steering.errors import BadInput

__all__ = ["Trajectory"]

Array = npt.NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class Trajectory:
    """One trial, sampled at the integrator's steps.

    ``t`` ``(S,)`` [s] from the start of the trial (of the segment, in a cyclic task); ``q``
    ``(S, nx)`` the configuration in the world frame (car: ``x`` [m], ``y`` [m], ``theta`` [rad],
    ``phi`` [rad], the wheel angle, at the stop when saturated; chained plant: ``z``); ``u``
    ``(S, 2)`` the inputs the controller commands (car: ``u1`` [rad/s] driving-wheel speed and
    ``u2`` [rad/s] steering rate by eqs. 4-5 with the nominal geometry; chained plant: ``v1``,
    ``v2``). A trial that left the chart ends where the robot halted, with ``left_chart`` set.
    """

    t: Array
    q: Array
    u: Array
    left_chart: bool = False

    def to_json(self) -> dict[str, Any]:
        return {"t": self.t.tolist(), "q": self.q.tolist(), "u": self.u.tolist(), "left_chart": self.left_chart}

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> Trajectory:
        try:
            t, q, u = (np.asarray(data[key], dtype=np.float64) for key in ("t", "q", "u"))
        except KeyError as error:
            raise BadInput(f"a trajectory needs keys t, q and u; {error.args[0]!r} is missing") from None
        if t.ndim != 1 or q.ndim != 2 or u.shape != (t.size, 2) or q.shape[0] != t.size:
            raise BadInput(
                f"trajectory shapes must be t (S,), q (S, nx), u (S, 2); got {t.shape}, {q.shape}, {u.shape}"
            )
        return cls(t, q, u, bool(data.get("left_chart", False)))
