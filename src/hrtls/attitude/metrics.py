"""Orientation errors against a reference, split into heading and inclination (as BROAD does).

The error quaternion is ``e = q_est * conj(q_ref)`` (a rotation in the navigation frame). It is
split into a rotation about the vertical (the heading error) and the rest (the inclination error,
the angle between the estimated and the true vertical). A constant heading offset between the
reference's frame and magnetic north is unknown for magnetometer-aided filters; with
``remove_heading_offset=True`` the circular mean of the heading error over the scored samples is
removed before the RMS (the BROAD benchmark's treatment of 9-D filters).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from hrtls.errors import InputError
from hrtls.frames import FloatArray, as_quat_array, quat_conjugate, quat_multiply, wrap_angle

__all__ = ["OrientationErrors", "orientation_errors"]


@dataclass(frozen=True)
class OrientationErrors:
    """Per-sample errors on the scored samples and their RMS (rad).

    Attributes
    ----------
    heading_rad:
        Signed heading error (rotation about the vertical), after removing ``offset_rad``.
    inclination_rad:
        Inclination error, in [0, pi].
    offset_rad:
        Removed constant heading offset (0 when not removed).
    index:
        Indices of the scored samples in the input arrays.
    """

    heading_rad: FloatArray
    inclination_rad: FloatArray
    offset_rad: float
    index: np.ndarray

    @property
    def heading_rms_rad(self) -> float:
        """RMS of the heading error, rad."""
        return float(np.sqrt(np.mean(self.heading_rad**2))) if self.heading_rad.size else np.nan

    @property
    def inclination_rms_rad(self) -> float:
        """RMS of the inclination error (roll/pitch combined), rad."""
        if not self.inclination_rad.size:
            return np.nan
        return float(np.sqrt(np.mean(self.inclination_rad**2)))


def orientation_errors(q_est: ArrayLike, q_ref: ArrayLike, mask: ArrayLike | None = None, *,
                       remove_heading_offset: bool = True) -> OrientationErrors:
    """Heading and inclination errors of ``q_est`` against ``q_ref`` (both ``q_nb``, ENU).

    Parameters
    ----------
    q_est, q_ref:
        Quaternions ``[w, x, y, z]``, shape (N, 4). Reference rows with NaN are skipped.
    mask:
        Boolean (N,) of samples to score (e.g. BROAD's ``movement``); ``None`` scores all.
    remove_heading_offset:
        Remove the circular mean of the heading error before computing the RMS.
    """
    qe = as_quat_array(q_est, name="q_est")
    qr = as_quat_array(q_ref, name="q_ref")
    if qe.shape != qr.shape or qe.ndim != 2:
        raise InputError(f"shapes {qe.shape} and {qr.shape}", where="orientation_errors",
                         expected="two (N, 4) arrays")
    keep = np.all(np.isfinite(qr), axis=1) & np.all(np.isfinite(qe), axis=1)
    if mask is not None:
        m = np.asarray(mask, dtype=bool)
        if m.shape != (len(qe),):
            raise InputError(f"mask shape {m.shape}", where="orientation_errors",
                             expected=f"({len(qe)},)")
        keep &= m
    idx = np.flatnonzero(keep)
    e = quat_multiply(qe[idx], quat_conjugate(qr[idx]))
    w, z = e[:, 0], e[:, 3]
    heading = wrap_angle(2.0 * np.arctan2(z, w))
    inclination = 2.0 * np.arccos(np.clip(np.sqrt(w * w + z * z), 0.0, 1.0))
    offset = 0.0
    if remove_heading_offset and heading.size:
        offset = float(np.arctan2(np.mean(np.sin(heading)), np.mean(np.cos(heading))))
        heading = wrap_angle(heading - offset)
    return OrientationErrors(heading, inclination, offset, idx)
