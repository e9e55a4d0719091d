"""What a process plant's trial request carries besides its coefficients: the input profile as a
message (eqs. 15-17's pieces), the path the robot would drive were it its nominal model, and that
path's samples at the control rate (``docs/your_robot.md``, protocol 1; the plant that sends them
is :mod:`ilc_steering.core.robots.process`).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt

from ilc_steering.core.profiles import InputProfile, PiecewiseProfile
from ilc_steering.core.simulate import simulate
from ilc_steering.core.trapezoid import TrapezoidProfile
from ilc_steering.errors import BadInput

__all__ = ["nominal_path", "profile_message", "sample"]

Array = npt.NDArray[np.float64]


def profile_message(profile: InputProfile) -> dict[str, Any]:
    """The ``profile`` of a trial request: eqs. 15-17's pieces, fixed ``v1``, ``q``, and section 5's shape."""
    if not isinstance(profile, PiecewiseProfile):
        raise BadInput(f"a process plant sends eqs. 15-17's profiles, got {type(profile).__name__}")
    trapezoid = isinstance(profile, TrapezoidProfile)
    return {
        "pieces": list(profile.durations),
        "v1_fixed": list(profile.v1_fixed),
        "v2_terms": profile.v2_terms,
        "v1_shape": "trapezoid" if trapezoid else "constant",
        "ramp": profile.ramp if isinstance(profile, TrapezoidProfile) else None,
    }


def nominal_path(nominal: Any, profile: InputProfile, x0: Array, c: Array, step: float) -> tuple[Array, Array, Array]:
    """The path the robot would drive were it its nominal model, with its known steering stop: the
    nominal plant (``nominal``, the controller's robot with its true geometry the nominal one)
    simulated from ``x0`` (task frame) under ``c`` by the library's integrator, steps at most
    ``step`` [s] long. Its times [s], configurations (task frame) and the states the robot's
    inputs are computed from (eqs. 4-5), each row a step. Without a steering stop it is eq. 12's
    nominal motion, to the integrator's accuracy (tested)."""
    trials = simulate(nominal, profile, nominal.initial_state(x0)[None], c[None], step, record=True)
    assert trials.times is not None and trials.states is not None  # record=True
    states = trials.states[0]
    return trials.times, nominal.configuration(states), nominal.estimate(states)


def sample(times: Array, values: Array, at: Array) -> Array:
    """``values`` (a row per time of ``times``) at the times ``at`` [s], linear between rows."""
    return np.stack([np.interp(at, times, values[:, i]) for i in range(values.shape[1])], axis=-1)
