"""Step headings from the attitude yaw and the walking direction held between steps.

Both keep what a later chunk needs in a :class:`~hrtls.gait.analyzer_state.PendingGait`, so
that a recording processed in chunks gets the same headings as in one call.
"""

from __future__ import annotations

import math
from typing import Literal

import numpy as np

from hrtls.errors import InputError
from hrtls.frames import quat_to_matrix, wrap_angle
from hrtls.gait._state import FloatArray
from hrtls.gait.analyzer_state import PendingGait
from hrtls.kernels import njit

__all__ = ["HEADING_HOLD_DELAY_S", "TURNING_STEP_RAD", "StepYaw", "check_heading_choice",
           "held_heading", "level_forward_axis", "yaw_step_headings"]

StepYaw = Literal["endpoints", "mean", "turns"]
HEADING_HOLD_DELAY_S = 0.5
"""a step heading takes effect on the held walking direction this long after the step end"""
TURNING_STEP_RAD = math.radians(20.0)
"""step_yaw="turns": a step turning more than this uses the time-averaged yaw"""


@njit(cache=True)
def trapezoid_area_kernel(t: FloatArray, y: FloatArray,
                          area: FloatArray) -> None:  # pragma: no cover - compiled
    """``area[i]``: integral of ``y`` over ``[t[0], t[i]]`` by the trapezoid rule (one pass)."""
    area[0] = 0.0
    for i in range(1, t.shape[0]):
        area[i] = area[i - 1] + 0.5 * (y[i] + y[i - 1]) * (t[i] - t[i - 1])



def check_heading_choice(*, heading: str, step_yaw: str) -> None:
    """Raise :class:`InputError` for an unknown heading source or step yaw."""
    if step_yaw not in ("endpoints", "mean", "turns"):
        raise InputError(f"step_yaw {step_yaw!r}", where="step_yaw",
                         expected="'endpoints', 'mean' or 'turns'")
    if heading not in ("fourier", "yaw", "none"):
        raise InputError(f"heading {heading!r}", where="heading",
                         expected="'fourier', 'yaw' or 'none'")

def yaw_step_headings(pend: PendingGait, tt: FloatArray, yaw: FloatArray, t_start: FloatArray,
                      t_end: FloatArray, *, step_yaw: StepYaw, keep_s: float) -> FloatArray:
    """Heading of each step from the yaw of the body forward axis at the samples ``tt``.

    The circular mean of the yaw at the step's start and end (``"endpoints"``), or the time
    average over the step (``"mean"``; ``"turns"``: only for steps turning more than
    ``TURNING_STEP_RAD``). The yaw is unwrapped continuously across chunks and its last
    ``keep_s`` seconds are kept in ``pend``, so that a step starting before this chunk reads
    the same yaw as in a whole run.
    """
    if np.isfinite(pend.yaw_last):
        yaw += 2.0 * np.pi * np.round((pend.yaw_last - yaw[0]) / (2.0 * np.pi))
    yb_t = np.concatenate([pend.yb_t, tt])
    yb_y = np.concatenate([pend.yb_y, yaw])
    y_end = np.interp(t_end, yb_t, yb_y)
    y_start = np.interp(t_start, yb_t, yb_y)
    head = np.arctan2(np.sin(y_start) + np.sin(y_end), np.cos(y_start) + np.cos(y_end))
    if step_yaw != "endpoints" and yb_t.size > 1:
        # time average of the unwrapped yaw over [t_start, t_end] (trapezoid rule)
        area = np.empty(yb_t.size)
        trapezoid_area_kernel(yb_t, yb_y, area)
        span = t_end - t_start
        mean = (np.interp(t_end, yb_t, area)
                - np.interp(t_start, yb_t, area)) / np.where(span > 0, span, 1.0)
        use = span > 0
        if step_yaw == "turns":
            use &= np.abs(y_end - y_start) > TURNING_STEP_RAD
        head = np.where(use, wrap_angle(mean), head)
    pend.yaw_last = float(yaw[-1])
    recent = yb_t >= tt[-1] - keep_s
    pend.yb_t = yb_t[recent]
    pend.yb_y = yb_y[recent]
    out: FloatArray = head
    return out


def held_heading(pend: PendingGait, tt: FloatArray, t_end: FloatArray,
                 head: FloatArray) -> FloatArray:
    """Walking direction at the samples ``tt``: the latest finite step heading (forward fill).

    A heading takes effect ``HEADING_HOLD_DELAY_S`` after its step end, a time by which every
    detector has reported the step, so that chunked and whole runs agree; headings not yet
    in effect wait in ``pend``. NaN before the first heading.
    """
    ok = np.isfinite(head)
    q_t = np.concatenate([pend.hq_t, t_end[ok] + HEADING_HOLD_DELAY_S])
    q_h = np.concatenate([pend.hq_h, head[ok]])
    due = q_t <= tt[-1]
    at = np.searchsorted(tt, q_t[due])
    src = np.full(tt.shape[0], -1, dtype=np.int64)
    src[np.clip(at, 0, tt.shape[0] - 1)] = np.arange(at.shape[0])
    src = np.maximum.accumulate(src)
    psi_held: FloatArray = np.concatenate([[pend.heading_last], q_h[due]])[src + 1]
    if due.any():
        pend.heading_last = float(q_h[due][-1])
    pend.hq_t = q_t[~due]
    pend.hq_h = q_h[~due]
    return psi_held


def level_forward_axis(q_nd: FloatArray) -> FloatArray:
    """The device axis most orthogonal to the vertical of attitude ``q_nd``, made horizontal.

    Its yaw stands for the walking direction when the mounting is unknown: only its yaw
    *changes* are used, and those are well defined only for an axis far from the vertical.
    """
    up_d = quat_to_matrix(q_nd)[2]   # row 2 of R (v_n = R v_d): ENU up, device axes
    axis = np.eye(3)[int(np.argmin(np.abs(up_d)))]
    level = axis - float(axis @ up_d) * up_d   # made horizontal at that sample
    out: FloatArray = level / np.linalg.norm(level)
    return out
