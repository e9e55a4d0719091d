"""A robot's :class:`~ilc_steering.core.plants.Kernel` from its field: the batch runners every robot
shares, compiled once per robot.

A robot writes its vector field, its chart test and its named layout; one call here makes the rest:

- :func:`trial_kernel`: each trial on its own (:func:`~ilc_steering.core.stepper.drive`), the
  trials of a batch in turn or shared among numba's threads: the robots whose steps split at
  events (a steering stop, an encoder pulse);
- :func:`lane_kernel`: the trials of a batch in blocks of :data:`LANES`, every stage of a step run
  over a block's lanes at once (:func:`lane_block`), so a field without transcendental functions
  vectorizes across trials;
- :func:`block_kernel`: the same runners around a robot's own block (the batched car's, which
  splits a lane's step at its stop).

Per robot, not per closure: numba keys its on-disk cache and names its compiled symbols by a
function's file, module and qualified name, and two closures of one factory share all three (a
process that loads one from the cache and compiles the other links one in place of the other:
heap corruption, ``tests/test_memory_safety.py``). So each runner is a copy of a template below
(no closure: its robot's pieces are globals of the copy, constants to the compiler), filed under
the robot's module, with a qualified name made from the kernel's name (``car_lab__trial``): its
cache lives beside the robot's module, keyed to that module's source, and no two robots share a
name (``tests/test_kernels.py`` runs two robots in one process and in a fresh one on a warm
cache). The cache knows the robot's source and the template's bytecode, not the inlined pieces of
:mod:`~ilc_steering.core.stepper` (as for any cached numba function that calls another module).
"""

from __future__ import annotations

import re
import sys
import types
from collections.abc import Callable
from typing import Any

import numpy as np
from numba import njit, prange

from ilc_steering.core.plants import Kernel, KernelLayout
from ilc_steering.core.stepper import LEFT_CHART, OK, STAGES, announce_compile, drive, lanes_rk, rk_step
from ilc_steering.errors import BadInput

__all__ = ["LANES", "block_kernel", "inside", "lane_block", "lane_kernel", "plain_step", "trial_kernel"]

LANES = 64
"""Trials per block of a lane kernel: one block's stages (12 x 4 x 64 float64, 24 KB) stay in the
L1 cache; 32 lanes were up to a tenth slower and 128 no faster, in one timing of the car's kernel
at N = 4096."""
_SINGLE_LANES = 10  # a last, partial block of at most this many trials runs them one by one
_OWNERS: dict[str, Any] = {}  # "module.qualname" of a compiled runner -> the module that made it


@njit(cache=True, inline="always")
def plain_step(rhs, n, params, x, tau, h, v1c, v2c, out, work, probe):  # type: ignore[no-untyped-def]
    """A step of :func:`~ilc_steering.core.stepper.drive` for a field without kinks or events."""
    rk_step(rhs, n, params, x, tau, h, v1c, v2c, out, work)


@njit(cache=True, inline="always")
def inside(params, x):  # type: ignore[no-untyped-def]
    """The chart test of a robot without a chart (every finite state is inside)."""
    return True


@njit(cache=True, inline="always")
def lane_block(  # type: ignore[no-untyped-def]
    load, field, chart, store, nx, nparams, n, params, x0, durations, steps, v1c, v2c, out, status, traj, start, stop
):
    """Trials ``start:stop`` (at most ``n``) of a batch on a lane kernel, laid out lane by lane (lanes
    past ``stop`` repeat its last trial and are dropped): ``load(row, x0, p, x, j)`` puts a trial's
    parameter row and start state into lane ``j`` of the lanes' parameters ``p`` ``(nparams, n)`` and
    state ``x`` ``(nx, n)`` (in the kernel's coordinates); ``field`` is
    :func:`~ilc_steering.core.stepper.lanes_rk`'s; ``chart(x, j)`` says whether lane ``j``'s state is
    finite and inside the chart; ``store(x, j, dst)`` writes it back in the robot's state layout.
    The arguments after ``n`` are those of :func:`ilc_steering.core.integrate.integrate`'s kernels."""
    p = np.empty((nparams, n))
    x = np.empty((nx, n))
    nxt = np.empty((nx, n))
    tmp = np.empty((nx, n))
    kst = np.empty((STAGES, nx, n))
    v1 = np.empty(n)
    v2 = np.empty(n)
    coef1 = np.empty((n, v1c.shape[2]))
    coef = np.empty((n, v2c.shape[2]))
    alive = np.empty(n, dtype=np.bool_)
    record = traj.shape[1] > 0
    used = stop - start
    for j in range(n):
        b = start + min(j, used - 1)
        load(params[b], x0[b], p, x, j)
        alive[j] = True
    for j in range(used):
        status[start + j] = OK
        if record:
            store(x, j, traj[start + j, 0])
    row = 1
    for piece in range(durations.shape[0]):
        h = durations[piece] / steps[piece]
        for j in range(n):
            b = start + min(j, used - 1)
            for d in range(coef1.shape[1]):
                coef1[j, d] = v1c[b, piece, d]
            for d in range(coef.shape[1]):
                coef[j, d] = v2c[b, piece, d]
        for step in range(steps[piece]):
            lanes_rk(field, nx, n, p, x, step * h, h, coef1, coef, nxt, kst, tmp, v1, v2)
            for j in range(used):
                if not alive[j]:
                    continue
                if chart(nxt, j):
                    for i in range(nx):
                        x[i, j] = nxt[i, j]
                else:
                    alive[j] = False
                    status[start + j] = LEFT_CHART
            if record:
                for j in range(used):
                    store(x, j, traj[start + j, row])
                row += 1
    for j in range(used):
        store(x, j, out[start + j])


# The templates: their arguments are those of ilc_steering.core.integrate.integrate's kernels, and
# the upper-case names below are the robot's pieces, bound as globals of each robot's copy (_compile).
FIELD: Any = None
STEP: Any = None
CHART: Any = None
LOAD: Any = None
STORE: Any = None
TRIAL: Any = None
BLOCK: Any = None
FULL: Any = None
SIZE = NX = NPARAMS = 0


def _trial(params, x0, durations, steps, v1c, v2c, out, traj):  # type: ignore[no-untyped-def]
    return drive(FIELD, STEP, CHART, SIZE, params, x0, durations, steps, v1c, v2c, out, traj)


def _trial_any_size(params, x0, durations, steps, v1c, v2c, out, traj):  # type: ignore[no-untyped-def]
    return drive(FIELD, STEP, CHART, x0.shape[0], params, x0, durations, steps, v1c, v2c, out, traj)


def _serial(params, x0, durations, steps, v1c, v2c, out, status, traj):  # type: ignore[no-untyped-def]
    for b in range(x0.shape[0]):
        status[b] = TRIAL(params[b], x0[b], durations, steps, v1c[b], v2c[b], out[b], traj[b])


def _parallel(params, x0, durations, steps, v1c, v2c, out, status, traj):  # type: ignore[no-untyped-def]
    for b in prange(x0.shape[0]):
        status[b] = TRIAL(params[b], x0[b], durations, steps, v1c[b], v2c[b], out[b], traj[b])


def _lanes(n, params, x0, durations, steps, v1c, v2c, out, status, traj, start, stop):  # type: ignore[no-untyped-def]
    lane_block(
        LOAD,
        FIELD,
        CHART,
        STORE,
        NX,
        NPARAMS,
        n,
        params,
        x0,
        durations,
        steps,
        v1c,
        v2c,
        out,
        status,
        traj,
        start,
        stop,
    )


def _block_one(params, x0, durations, steps, v1c, v2c, out, status, traj, start, stop):  # type: ignore[no-untyped-def]
    BLOCK(1, params, x0, durations, steps, v1c, v2c, out, status, traj, start, stop)


def _block_full(params, x0, durations, steps, v1c, v2c, out, status, traj, start, stop):  # type: ignore[no-untyped-def]
    BLOCK(LANES, params, x0, durations, steps, v1c, v2c, out, status, traj, start, stop)


def _block_shared(params, x0, durations, steps, v1c, v2c, out, status, traj, stop):  # type: ignore[no-untyped-def]
    for blk in prange((stop + LANES - 1) // LANES):
        start, end = blk * LANES, min(stop, (blk + 1) * LANES)
        FULL(params, x0, durations, steps, v1c, v2c, out, status, traj, start, end)


def _compile(template: Any, kernel: str, module: str, pieces: dict[str, Any], **options: Any) -> Any:
    """``template`` compiled as a function of robot ``module`` (its ``__name__``) named after the
    kernel, with ``pieces`` as its globals."""
    qualname = f"{re.sub(r'[^0-9A-Za-z]+', '_', kernel)}__{template.__name__.strip('_')}"
    source = sys.modules.get(module)
    path = getattr(source, "__file__", None)
    if source is None or not path:
        raise BadInput(f"a kernel's module must be an imported module with a source file, got {module!r}")
    if _OWNERS.get(f"{module}.{qualname}") is source:  # the same module again (not a re-import)
        raise BadInput(f"{module} has two kernels named {kernel!r}: give each kernel its own name")
    _OWNERS[f"{module}.{qualname}"] = source
    namespace = {**template.__globals__, **pieces, "__name__": module}
    function = types.FunctionType(template.__code__.replace(co_filename=path, co_name=qualname), namespace, qualname)
    function.__qualname__ = qualname
    function.__module__ = module
    function.__doc__ = f"{template.__name__} of the {kernel} kernel (ilc_steering.core.kernels)."
    return njit(**options)(function)


def trial_kernel(
    name: str,
    layout: KernelLayout,
    module: str,
    field: Any,
    chart: Any = inside,
    step: Any = plain_step,
) -> Kernel:
    """The kernel of a robot whose trials run one by one (:func:`~ilc_steering.core.stepper.drive`).

    Parameters
    ----------
    name
        The kernel's name in messages; unique within ``module``.
    layout
        The state and the parameter row ``field`` reads; the state's size is its length (or, for an
        empty state, each trial's own: the chained form's).
    module
        The robot's module, ``__name__``: the compiled runners are filed (and cached) under it.
    field
        ``field(params, x, v1, v2, out)``, ``@njit(inline="always")``: ``x'`` into ``out``.
    chart
        ``chart(params, x)``: whether a state is inside the chart (default: always).
    step
        ``step(rhs, n, params, x, tau, h, v1c, v2c, out, work, probe)``, one step of the field:
        :func:`plain_step` (default), or one split at a kink or events
        (:func:`~ilc_steering.core.stepper.step_with_stop`).
    """
    pieces = {"FIELD": field, "STEP": step, "CHART": chart, "SIZE": len(layout.state)}
    trial = _compile(_trial if layout.state else _trial_any_size, name, module, pieces, cache=True)
    serial = _compile(_serial, name, module, {"TRIAL": trial}, cache=True)
    parallel = _compile(_parallel, name, module, {"TRIAL": trial}, cache=True, parallel=True)
    return Kernel(name, layout, serial, parallel)


def block_kernel(
    name: str, layout: KernelLayout, module: str, block: Any, error_model: str = "python", packs: bool = False
) -> Kernel:
    """The kernel of a robot whose trials run in blocks of :data:`LANES` lanes: ``block(n, params, x0,
    durations, steps, v1c, v2c, out, status, traj, start, stop)``, ``@njit(inline="always")``, runs
    trials ``start:stop`` in ``n`` lanes (:func:`lane_block`'s arguments after ``n``). ``name``,
    ``layout`` and ``module`` as for :func:`trial_kernel`; ``error_model`` numba's (``"numpy"``: a
    division by zero is ``inf`` or ``NaN``, where ``"python"`` raises). A block that ``packs`` its
    lanes (a partial block costs only its trials) compiles no one-lane variant: a partial block runs
    the few trials past the last full one (each variant compiles the whole block once more)."""
    options = {"cache": True, "error_model": error_model}
    one = None if packs else _compile(_block_one, name, module, {"BLOCK": block}, **options)
    full = _compile(_block_full, name, module, {"BLOCK": block, "LANES": LANES}, **options)
    shared = _compile(_block_shared, name, module, {"FULL": full, "LANES": LANES}, parallel=True, **options)
    blocks = (one, full, shared)

    def serial(*args: Any) -> None:
        _run_lanes(blocks, args, False, name)

    def parallel(*args: Any) -> None:
        _run_lanes(blocks, args, True, name)

    return Kernel(name, layout, serial, parallel)


def lane_kernel(
    name: str,
    layout: KernelLayout,
    module: str,
    lanes: tuple[Callable[..., Any], Callable[..., Any], Callable[..., Any], Callable[..., Any]],
    shape: tuple[int, int],
    error_model: str = "python",
) -> Kernel:
    """The kernel of a robot whose field runs across :data:`LANES` trials at once: ``lanes`` are its
    ``(load, field, chart, store)`` and ``shape`` the ``(states, parameters)`` of a lane, in the
    kernel's own coordinates (:func:`lane_block`); the rest as for :func:`block_kernel`."""
    load, field, chart, store = lanes
    pieces = {"LOAD": load, "FIELD": field, "CHART": chart, "STORE": store, "NX": shape[0], "NPARAMS": shape[1]}
    block = _compile(_lanes, name, module, pieces, inline="always")
    return block_kernel(name, layout, module, block, error_model)


def _run_lanes(blocks: tuple[Any | None, Any, Any], args: tuple[Any, ...], parallel: bool, name: str) -> None:
    """A batch of trials on a lane kernel's compiled ``(one, block, shared)``: blocks of :data:`LANES`
    trials (shared among numba's threads with ``parallel``), a last partial block of more than a
    few trials padded, fewer run one by one with ``one`` (without it, in a block of their own)."""
    one, block, shared = blocks
    batch = args[1].shape[0]
    full = batch - batch % LANES if one is not None and batch % LANES <= _SINGLE_LANES else batch
    if parallel and full > LANES:
        announce_compile(shared, name)
        shared(*args, full)
    elif full:
        announce_compile(block, name)
        for start in range(0, full, LANES):
            block(*args, start, min(full, start + LANES))
    if full < batch:
        assert one is not None  # without it every trial ran in a block
        announce_compile(one, name)
        for start in range(full, batch):
            one(*args, start, start + 1)
