"""The car's chart and the task frame: where the chained form of eq. 4 is defined (``|theta|`` and
``|phi| < pi/2``), and the rotation of the x-y frame (the remark at the end of section 4) that puts
a task's orientations inside it, with configurations expressed in the rotated frame.
"""

from __future__ import annotations

from math import pi

import numpy as np
import numpy.typing as npt

from ilc_steering.errors import BadInput

__all__ = ["check_chart", "frame_angle", "rotate"]

Array = npt.NDArray[np.float64]


def check_chart(q: Array) -> None:
    """Raise ``ValueError`` where the chained-form map of eq. 4 is undefined (``|theta|`` or ``|phi| >= pi/2``)."""
    q = np.asarray(q, dtype=np.float64)
    if q.shape[-1] != 4:
        raise BadInput(f"a car configuration is (x, y, theta, phi); got shape {q.shape}")
    if q.size and float(np.abs(q[..., 2:]).max()) < pi / 2 and np.isfinite(q[..., :2]).all():
        return  # the common case, in one pass; the checks below say what is wrong
    if not np.all(np.isfinite(q)):
        raise BadInput(f"configuration must be finite, got {q.tolist()}")
    theta, phi = q[..., 2], q[..., 3]
    if np.any(np.abs(theta) >= pi / 2):
        raise BadInput(
            f"theta = {np.asarray(theta).tolist()} rad: the chained form needs |theta| < pi/2 "
            "in the task frame (z3 = tan(theta)); rotate the frame with frame_angle()"
        )
    if np.any(np.abs(phi) >= pi / 2):
        raise BadInput(f"phi = {np.asarray(phi).tolist()} rad: the chained form needs |phi| < pi/2")


def frame_angle(*thetas: float) -> float:
    """The rotation [rad] of the x-y frame that puts all orientations ``thetas`` in ``(-pi/2, pi/2)``.

    Zero when they already are (so the paper's tasks keep their coordinates); otherwise the middle
    of their range, which works whenever the range is below ``pi`` (end of section 4). Raises
    ``ValueError`` otherwise, suggesting the intermediate configuration the paper prescribes.
    """
    low, high = min(thetas), max(thetas)
    if high - low >= pi:
        middle = 0.5 * (low + high)
        raise BadInput(
            f"orientations {low:.6g} and {high:.6g} rad are pi or more apart: no frame puts both in the "
            f"chained-form chart. Split the task at an intermediate configuration with theta = {middle:.6g} rad "
            "(section 4), or write one orientation 2*pi apart if the same heading by the shorter turn is meant."
        )
    if all(abs(t) < pi / 2 for t in thetas):
        return 0.0
    return 0.5 * (low + high)


def rotate(q: Array, angle: float) -> Array:
    """Express configurations ``q`` (``(..., 4)``) in a frame rotated by ``angle`` [rad]."""
    q = np.asarray(q, dtype=np.float64)
    c, s = np.cos(angle), np.sin(angle)
    out = q.copy()
    out[..., 0] = c * q[..., 0] + s * q[..., 1]
    out[..., 1] = -s * q[..., 0] + c * q[..., 1]
    out[..., 2] = q[..., 2] - angle
    return out
