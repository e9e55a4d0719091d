"""The lab robot's named layout (:mod:`~ilc_steering.core.robots.car_lab`): its state and parameter
row, and the positions its compiled pieces read, written once here.

The kernel's state has twelve entries, :data:`LAB_LAYOUT`'s; inside a step the kernel works on its
own fourteen, ``(x, y, tan(theta), phi_c, phi_s, omega, psi, tan(phi_s), cos(theta), A, x_hat, y_hat,
theta_hat, k)``: the first :data:`MOVING` move between events, the play's anchor ``A`` and the
estimate jump. Past the row a (sub)step keeps :data:`EXTRA` numbers it fixes (``_lab_constants``).
"""

from __future__ import annotations

from ilc_steering.core.plants import KernelLayout
from ilc_steering.core.tangent import CAR_LAYOUT

__all__ = ["EXTRA", "LAB_LAYOUT", "MOVING", "SERVO_PARAMS"]

SERVO_PARAMS = (*CAR_LAYOUT.params, "steering_offset", "steering_lag", "speed_lag")
"""The servo car's parameters, which the lab robot's row extends (a servo car runs on this kernel
with its play and encoders off)."""
LAB_LAYOUT = KernelLayout(
    ("x", "y", "theta", "phi_c", "phi_s", "omega", "A", "psi", "x_hat", "y_hat", "theta_hat", "k"),
    (*SERVO_PARAMS, "steering_backlash", "encoder_pulses"),
)
ELL, RHO, TRUE_ELL, TRUE_RHO, LIMIT = (LAB_LAYOUT.index(name) for name in CAR_LAYOUT.params)
OFFSET, STEERING_LAG, SPEED_LAG = (LAB_LAYOUT.index(n) for n in ("steering_offset", "steering_lag", "speed_lag"))
BACKLASH, PULSES = LAB_LAYOUT.index("steering_backlash"), LAB_LAYOUT.index("encoder_pulses")
# Past the row, fixed for a step or a substep: eq. 4's gain and eq. 5's two at the estimate,
# tan(offset -+ b/2), tan(A + offset), the reciprocals of true_wheelbase and the lags,
# tan(steering_limit), the |phi_c| past which a servo without a lag carries no tan(phi_c), and the
# estimated heading and the anchor the gains and tan(A + offset) were computed at.
EXTRA = 13
U1, U2_V1, U2_V2, TAN_LO, TAN_HI, TAN_REST = range(len(LAB_LAYOUT.params), len(LAB_LAYOUT.params) + 6)
PER_ELL, PER_STEERING_LAG, PER_SPEED_LAG, TAN_LIMIT, GATE, HAT_AT, ANCHOR_AT = range(TAN_REST + 1, TAN_REST + 8)
# The step's state (the module docstring): the entries after the six of the layout's.
PSI, TAN_SERVO, COS, ANCHOR, HAT = 6, 7, 8, 9, 10
MOVING = ANCHOR
"""The entries of the step's state that move between events (a Runge-Kutta step runs on these)."""
