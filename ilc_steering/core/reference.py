"""Reference trials with scipy's adaptive ``solve_ivp``: slow and tight, for tests and benchmarks.

Each span of the input profile is integrated separately (the inputs jump between spans), and
with a steering limit the integration restarts at every crossing of ``|phi_c| = limit``, where
the vector field has a kink (see :mod:`ilc_steering.core.stepper`). Each robot's field is the
one its module writes from its equations (``Plant.reference_field``; the car's from eqs. 3-5 as
in :mod:`ilc_steering.core.robots.car`), not from the kernel's fused form; the lab robot, whose
events restart the integration, has its own (:func:`lab_car_trial`).
"""

from __future__ import annotations

from collections.abc import Callable
from itertools import pairwise

import numpy as np
import numpy.typing as npt
from scipy.integrate import solve_ivp

from ilc_steering.core.plants import Plant
from ilc_steering.core.profiles import InputProfile
from ilc_steering.core.robots.car import CarPlant, car_velocity, chained_inputs
from ilc_steering.errors import BadInput

__all__ = ["STEERING_COMMAND", "lab_car_trial", "reference_trial", "steering_entry", "trial"]

Array = npt.NDArray[np.float64]
Field = Callable[[float, Array], Array]


def reference_trial(
    field: Field,
    x0: Array,
    breakpoints: Array,
    limit: float = np.inf,
    rtol: float = 1e-12,
    chart: Callable[[float, Array], float] | None = None,
    steering: int = 3,
) -> Array:
    """The state at ``breakpoints[-1]`` of ``dx/dt = field(t, x)`` from ``x0``, by DOP853 at
    ``rtol`` (= atol), restarted at the breakpoints and at every ``|x[steering]| = limit`` (the
    steering command at its stop; :func:`trial` finds its entry by name); the trial halts where
    ``chart(t, x)`` falls to 0 (the robot leaves the chart), if given."""

    def crossing(t: float, x: Array) -> float:
        return float(abs(x[steering]) - limit)

    crossing.terminal = True  # type: ignore[attr-defined]
    if chart is not None:
        chart.terminal = True  # type: ignore[attr-defined]
    x = np.array(x0, dtype=np.float64)
    for t, t1 in pairwise(breakpoints):
        while t < t1:
            # Off an event by a hair, so the restarted solver does not stop on it again.
            events = [crossing] if np.isfinite(limit) and abs(abs(x[steering]) - limit) > 1e-13 else []
            sol = solve_ivp(
                field, (t, t1), x, method="DOP853", rtol=rtol, atol=rtol, events=events + ([chart] if chart else [])
            )
            x, t = sol.y[:, -1], sol.t[-1]
            if chart is not None and sol.status == 1 and sol.t_events[-1].size:
                return np.asarray(x, dtype=np.float64)
            if sol.status == 1 and t < t1:
                nudge = min(1e-12, t1 - t)
                x, t = x + nudge * np.asarray(field(t, x)), t + nudge
    return x


def trial(plant: Plant, profile: InputProfile, x0: Array, c: Array, rtol: float = 1e-12) -> Array:
    """The final state of one trial of ``plant`` from ``x0`` (task frame) by :func:`reference_trial`,
    on the field the plant's robot module writes from its equations
    (:meth:`~ilc_steering.core.plants.Plant.reference_field`)."""
    field, limit, chart = plant.reference_field(profile, c)
    return reference_trial(field, x0, profile.breakpoints, limit, rtol, chart, steering_entry(plant, limit))


STEERING_COMMAND = "phi_c"
"""The name, in a kernel's state layout, of the steering command a steering limit stops."""


def steering_entry(plant: Plant, limit: float) -> int:
    """The state entry the steering stop ``limit`` [rad] acts on: the one the plant's kernel layout
    names :data:`STEERING_COMMAND`; ``ValueError`` for a finite limit and no such entry."""
    state = plant.kernel()[0].layout.state
    if STEERING_COMMAND in state:
        return state.index(STEERING_COMMAND)
    if np.isfinite(limit):
        raise BadInput(
            f"{type(plant).__name__}: a steering limit needs a state entry named {STEERING_COMMAND!r} in its "
            f"kernel's layout (the command the stop acts on), got {list(state)}"
        )
    return 0  # no stop: the entry is never read


def lab_car_trial(plant: CarPlant, profile: InputProfile, x0: Array, c: Array, rtol: float = 1e-12) -> Array:
    """The final state of one trial of the lab robot ``plant`` (or a servo car) from the kernel's
    initial state ``x0``, in the kernel's layout, by DOP853 at ``rtol`` restarted at every event.

    Internally the wheel angle ``phi_w`` is integrated with a mode: 0 resting, +1 / -1 pushed by
    the servo (``dphi_w/dt = dphi_s/dt``); the mode changes where the gap ``phi_s - phi_w`` reaches
    ``+-b/2`` and where the servo's rate changes sign while pushing; each pulse (``psi`` crossing a
    multiple of ``2 pi / N``) updates the dead-reckoned estimate by the nominal odometry.
    """
    nominal, true = plant.nominal, plant.true
    limit = np.inf if plant.steering_limit is None else plant.steering_limit
    half, pulses = 0.5 * plant.steering_backlash, plant.encoder_pulses
    pitch = 2 * np.pi / pulses if pulses else np.inf
    lag, speed_lag = plant.steering_lag, plant.speed_lag

    def servo(q: Array) -> float:
        return float(q[4]) if lag else float(np.clip(q[3], -limit, limit))

    def rates(t: float, q: Array, estimate: Array) -> tuple[float, float, float]:
        v1, v2 = profile.evaluate(c, np.array(t))
        theta = estimate[2] if pulses else q[2]
        u1, u2 = chained_inputs(theta, servo(q), float(v1), float(v2), nominal.wheelbase, nominal.wheel_radius)
        if lag:
            rate = (float(np.clip(q[3], -limit, limit)) - q[4]) / lag
        else:
            rate = 0.0 if abs(q[3]) >= limit else float(u2)
        return float(u1), float(u2), rate

    # y = (x, y, theta, phi_c, phi_s, omega, phi_w, psi)
    def field(t: float, q: Array, estimate: Array, mode: int) -> Array:
        u1, u2, rate = rates(t, q, estimate)
        omega = q[5] if speed_lag else u1
        phi_w = q[6] if half else servo(q)
        angle = phi_w + plant.steering_offset
        dx, dy, dtheta, _ = car_velocity(q[2], angle, omega, u2, true.wheelbase, true.wheel_radius)
        dphi_s = rate if lag else 0.0
        domega = (u1 - q[5]) / speed_lag if speed_lag else 0.0
        dphi_w = rate if mode else 0.0
        return np.array([dx, dy, dtheta, u2, dphi_s, domega, dphi_w, omega])

    def events(estimate: Array, mode: int, count: float, beyond: bool) -> list[Callable[[float, Array], float]]:
        def at_limit(t: float, q: Array) -> float:
            return float(abs(q[3]) - limit)

        def engage_up(t: float, q: Array) -> float:
            return float(servo(q) - q[6] - half)

        def engage_down(t: float, q: Array) -> float:
            return float(servo(q) - q[6] + half)

        def turn(t: float, q: Array) -> float:
            return rates(t, q, estimate)[2]

        def pulse_up(t: float, q: Array) -> float:
            return float(q[7] - (count + 1) * pitch)

        def pulse_down(t: float, q: Array) -> float:
            return float(q[7] - count * pitch)

        at_limit.direction = -1 if beyond else 1  # type: ignore[attr-defined]
        engage_up.direction, engage_down.direction = 1, -1  # type: ignore[attr-defined]
        turn.direction = -mode  # type: ignore[attr-defined]
        pulse_up.direction, pulse_down.direction = 1, -1  # type: ignore[attr-defined]
        chosen: list[Callable[[float, Array], float]] = [at_limit] if np.isfinite(limit) else []
        if half:
            chosen += [turn] if mode else [engage_up, engage_down]
        if pulses:
            chosen += [pulse_up, pulse_down]
        for event in chosen:
            event.terminal = True  # type: ignore[attr-defined]
        return chosen

    x0 = np.asarray(x0, dtype=np.float64)
    q = np.concatenate([x0[:6], [x0[3] if not lag else x0[4]], x0[7:8]])
    q[6] = x0[6]
    estimate, count, mode = x0[8:11].copy(), float(x0[11]), 0
    for t, t1 in pairwise(profile.breakpoints):
        if mode and np.sign(rates(t, q, estimate)[2]) == -mode:  # the servo turns back as v2 jumps
            mode = 0
        while t < t1:
            beyond = abs(q[3]) > limit
            chosen = events(estimate, mode, count, beyond)
            sol = solve_ivp(
                lambda s, y, e=estimate, m=mode: field(s, y, e, m),
                (t, t1),
                q,
                method="DOP853",
                rtol=rtol,
                atol=rtol,
                events=chosen or None,
            )
            q, t = sol.y[:, -1].copy(), float(sol.t[-1])
            if sol.status != 1:
                continue
            fired = next(event for event, times in zip(chosen, sol.t_events, strict=True) if times.size)
            name = fired.__name__
            if name in ("pulse_up", "pulse_down"):
                ds = (1 if name == "pulse_up" else -1) * pitch * nominal.wheel_radius
                dtheta = ds * np.tan(servo(q)) / nominal.wheelbase
                heading = estimate[2] + dtheta / 2
                estimate = estimate + np.array([ds * np.cos(heading), ds * np.sin(heading), dtheta])
                count += 1 if name == "pulse_up" else -1
            elif name == "engage_up":
                mode, q[6] = 1, servo(q) - half
            elif name == "engage_down":
                mode, q[6] = -1, servo(q) + half
            elif name == "turn":
                mode = 0
            if mode and np.sign(rates(t, q, estimate)[2]) == -mode:  # a pulse flipped the servo's direction
                mode = 0
            # The limit changes the field but not the mode; step a hair off every event so the
            # restarted solver does not stop on it again.
            nudge = min(1e-12, t1 - t)
            q, t = q + nudge * field(t, q, estimate, mode), t + nudge
    return np.concatenate([q[:6], [q[6] if half else servo(q)], q[7:8], estimate, [count]])
