"""The boundary into the compiled simulator: a batch of trials of one robot's kernel, every array
checked against the kernel's layout first.

A robot's compiled field is in its module (:mod:`ilc_steering.core.robots`; the car's batched
kernel in :mod:`ilc_steering.core.tangent`), its batch runners made from it by
:mod:`ilc_steering.core.kernels` out of the integrator's core (:mod:`ilc_steering.core.stepper`:
the DOP853 step with a fixed step length, the event locator, the driver and the chart guard).
Every kernel takes a row of parameters per trial, so one call may run a batch of different
plants. Compiled code reads its arrays by position and checks nothing
(numba does no bounds checking): :func:`integrate` checks their shapes, sizes, dtypes and values
against the kernel's :class:`~ilc_steering.core.plants.KernelLayout` and refuses, with a
``ValueError`` that names what is wrong, whatever does not fit.
"""

from __future__ import annotations

from math import isfinite, isnan
from typing import Any

import numpy as np
import numpy.typing as npt

from ilc_steering.core.plants import Kernel
from ilc_steering.core.stepper import LEFT_CHART, OK, announce_compile
from ilc_steering.errors import BadInput

__all__ = ["LEFT_CHART", "OK", "checked_batch", "integrate"]

Array = npt.NDArray[np.float64]
Int = npt.NDArray[np.int64]


def integrate(
    kernel: Kernel,
    params: Array,
    x0: Array,
    durations: Array,
    steps: Int,
    v1: Array,
    v2: Array,
    record: bool = False,
    parallel: bool = False,
) -> tuple[Array, Int, Array | None]:
    """Integrate a batch of trials of ``kernel``.

    ``x0`` is ``(B, nx)``; ``params`` is ``(P,)`` for every trial or ``(B, P)``, a plant per
    trial, laid out as ``kernel.layout.params``; ``durations`` ``(p,)`` [s] and ``steps`` ``(p,)``
    the pieces and their steps; ``v1`` and ``v2`` are ``(B, p, D)`` piecewise polynomials from an
    input profile. Returns the final states ``(B, nx)``, the status of each trial (``OK`` or
    ``LEFT_CHART``) and, with ``record``, the states at every step ``(B, 1 + sum(steps), nx)``.
    """
    params, x0, durations, steps, v1, v2 = checked_batch(kernel, params, x0, durations, steps, v1, v2)
    batch, n = x0.shape
    out = np.empty((batch, n))
    status = np.empty(batch, dtype=np.int64)
    rows = 1 + int(steps.sum()) if record else 0
    traj = np.empty((batch, rows, n))
    runner = kernel.parallel if parallel else kernel.serial
    announce_compile(runner, kernel.name)
    runner(params, x0, durations, steps, v1, v2, out, status, traj)
    return out, status, traj if record else None


def checked_batch(
    kernel: Kernel, params: Array, x0: Array, durations: Array, steps: Int, v1: Array, v2: Array
) -> tuple[Array, Array, Array, Int, Array, Array]:
    """:func:`integrate`'s arguments as its compiled runners read them (C order, float64 or int64,
    writeable; ``params`` ``(B, P)``), checked against ``kernel``'s layout: ``BadInput`` otherwise."""
    if not isinstance(kernel, Kernel):
        raise BadInput(f"kernel must be a plant's Kernel (plant.kernel()[0]), got {type(kernel).__name__}")
    # One layout for every caller (C order, float64, writeable): a read-only or strided view would
    # compile a second specialization of the kernel, which costs as long as the first.
    x0, params, durations, v1, v2 = (_layout(a, np.float64, name) for a, name in _named(x0, params, durations, v1, v2))
    steps = _layout(steps, np.int64, "steps")
    params = _check_arrays(kernel, params, x0, durations, steps, v1, v2)
    return params, x0, durations, steps, v1, v2


def _named(*arrays: Any) -> list[tuple[Any, str]]:
    return list(zip(arrays, ("x0", "params", "durations", "v1", "v2")))


def _check_arrays(
    kernel: Kernel, params: Array, x0: Array, durations: Array, steps: Int, v1: Array, v2: Array
) -> Array:
    """``ValueError`` unless the arrays fit the kernel's layout and one another (the shapes and sizes
    the compiled code indexes by, and the values a trial cannot start from). Returns the parameter
    table ``(B, P)``. Inputs ``v1``, ``v2`` that are not finite need no check here: the first step
    ends off the chart and the trial stops with ``LEFT_CHART``."""
    layout = kernel.layout
    if x0.ndim != 2 or x0.shape[0] < 1:
        raise BadInput(f"x0 must be a batch of states (B, nx) with B >= 1, got shape {x0.shape}")
    batch = x0.shape[0]
    if params.ndim == 1:
        rows = np.empty((batch, params.shape[0]))
        rows[:] = params
        params = rows
    if params.ndim != 2 or params.shape[0] != batch:
        raise BadInput(f"{batch} trials need {batch} rows of plant parameters, one per trial; got {params.shape}")
    if params.shape[1] != len(layout.params):
        raise BadInput(
            f"a parameter row of the {kernel.name} kernel has {len(layout.params)} entries {list(layout.params)}, "
            f"got {params.shape[1]}"
        )
    if isnan(params.sum()):  # a sum is NaN where an entry is (a steering limit may be inf)
        raise BadInput("plant parameters must not be NaN")
    sizes = {len(layout.state)} if layout.state else set(np.unique(params[:, layout.index("dimension")]).tolist())
    if sizes != {x0.shape[1]}:
        raise BadInput(f"the state of the {kernel.name} kernel has {sorted(sizes)} entries, got {x0.shape[1]}")
    if not isfinite(x0.sum()):  # finite where every entry is (they are within 1e6 of 0)
        raise BadInput("start states x0 must be finite")
    pieces = durations.shape[0] if durations.ndim == 1 else -1
    if pieces < 1 or not durations.min() > 0:
        raise BadInput(f"durations must be a vector of piece lengths > 0 [s], got {durations.tolist()}")
    if steps.shape != (pieces,) or steps.min() < 1:  # the recorded rows are counted from them
        raise BadInput(f"steps must give each of the {pieces} pieces at least 1 step, got {steps.tolist()}")
    for name, v in (("v1", v1), ("v2", v2)):
        if v.ndim != 3 or v.shape[:2] != (batch, pieces) or v.shape[2] < 1:
            raise BadInput(
                f"{name} must be polynomials (B, pieces, D) = ({batch}, {pieces}, D >= 1) for {batch} trials "
                f"of {pieces} pieces, got shape {v.shape}"
            )
    return params


def _layout(a: Any, dtype: Any, name: str) -> Any:
    if isinstance(a, np.ndarray) and a.dtype == dtype and a.flags.c_contiguous and a.flags.writeable:
        return a
    try:
        return np.require(a, dtype, ["C", "W"])
    except (TypeError, ValueError):
        raise BadInput(f"{name} must be an array of numbers, got {type(a).__name__}") from None
