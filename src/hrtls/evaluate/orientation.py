"""Orientation errors against a reference, split into heading and inclination (as BROAD does).

The error quaternion is ``e = q_est * conj(q_ref)`` (a rotation in the navigation frame). It is
split into a rotation about the vertical (the heading error) and the rest (the inclination error,
the angle between the estimated and the true vertical). A constant heading offset between the
reference's frame and magnetic north is unknown for magnetometer-aided filters; with
``remove_heading_offset=True`` the circular mean of the heading error over the scored samples is
removed before the RMS (the BROAD benchmark's treatment of 9-D filters).

:func:`score_orientation` scores an estimate on its own clock against a reference on another:
the estimate is interpolated (slerp) at the reference times inside its span, one heading offset
is removed over all scored samples (it is a property of the frames), and the RMS is given per
segment (runs of scored samples without gaps longer than ``segment_gap_s``) and overall.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
from numpy.typing import ArrayLike

from hrtls.errors import InputError
from hrtls.frames import (
    FloatArray,
    as_quat_array,
    quat_conjugate,
    quat_from_rotation,
    quat_multiply,
    quat_to_rotation,
    wrap_angle,
)

__all__ = ["OrientationErrors", "OrientationScore", "SegmentScore", "orientation_errors",
           "score_orientation"]


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
        Quaternions ``[w, x, y, z]``, shape (N, 4). Rows with NaN are skipped.
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


@dataclass(frozen=True)
class SegmentScore:
    """RMS errors over one time span, rad (``n`` scored samples)."""

    t_start_s: float
    t_end_s: float
    n: int
    inclination_rms_rad: float
    heading_rms_rad: float

    def to_dict(self) -> dict[str, float | int]:
        """JSON-able form (degrees added for reading)."""
        d: dict[str, float | int] = asdict(self)
        d["inclination_rms_deg"] = float(np.rad2deg(self.inclination_rms_rad))
        d["heading_rms_deg"] = float(np.rad2deg(self.heading_rms_rad))
        return d


@dataclass(frozen=True)
class OrientationScore:
    """Overall and per-segment scores of an orientation estimate and the removed offset."""

    overall: SegmentScore
    segments: list[SegmentScore]
    heading_offset_rad: float
    n_reference: int

    def to_dict(self) -> dict[str, object]:
        """JSON-able form."""
        return {"overall": self.overall.to_dict(),
                "segments": [s.to_dict() for s in self.segments],
                "heading_offset_rad": self.heading_offset_rad,
                "n_reference": self.n_reference}


def _rms(values: FloatArray) -> float:
    return float(np.sqrt(np.mean(values**2))) if values.size else float("nan")


def score_orientation(t_est: ArrayLike, q_est: ArrayLike, t_ref: ArrayLike, q_ref: ArrayLike,
                      *, mask: ArrayLike | None = None, segment_gap_s: float = 1.0,
                      remove_heading_offset: bool = True) -> OrientationScore:
    """Score an orientation estimate against a reference (module text).

    Parameters
    ----------
    t_est, q_est:
        Estimate times (s, strictly increasing) and quaternions ``q_nb`` (N, 4).
    t_ref, q_ref:
        Reference times and quaternions (M, 4), same frame convention; NaN rows are skipped.
    mask:
        Boolean (M,) of reference samples to score (e.g. BROAD's ``movement``).
    segment_gap_s:
        A gap between scored samples longer than this starts a new segment, s.
    remove_heading_offset:
        Remove one constant heading offset over all scored samples.
    """
    te = np.asarray(t_est, dtype=np.float64)
    tr = np.asarray(t_ref, dtype=np.float64)
    qe = as_quat_array(q_est, name="estimate")
    qr = as_quat_array(q_ref, name="reference")
    for name, t, q in (("estimate", te, qe), ("reference", tr, qr)):
        if t.ndim != 1 or q.shape != (len(t), 4):
            raise InputError(f"times {t.shape}, quaternions {q.shape}", where=name,
                             expected="(N,) times and (N, 4) quaternions")
        if not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0.0):
            raise InputError("times not finite and strictly increasing", where=name,
                             expected="strictly increasing times, s")
    if not (np.isfinite(segment_gap_s) and segment_gap_s > 0.0):
        raise InputError(f"segment_gap_s = {segment_gap_s}", where="score_orientation",
                         expected="a positive number of seconds")
    ok_est = np.all(np.isfinite(qe), axis=1)
    if ok_est.sum() < 2:
        raise InputError("fewer than two finite estimates", where="estimate",
                         expected="an orientation time series")
    from scipy.spatial.transform import Slerp

    te_ok = te[ok_est]
    inside = (tr >= te_ok[0]) & (tr <= te_ok[-1])
    q_at = np.full((len(tr), 4), np.nan)
    if inside.any():
        slerp = Slerp(te_ok, quat_to_rotation(qe[ok_est]))
        q_at[inside] = quat_from_rotation(slerp(tr[inside]))
    err = orientation_errors(q_at, qr, mask, remove_heading_offset=remove_heading_offset)
    t_sc = tr[err.index]
    overall = SegmentScore(float(t_sc[0]) if t_sc.size else float("nan"),
                           float(t_sc[-1]) if t_sc.size else float("nan"), int(t_sc.size),
                           _rms(err.inclination_rad), _rms(err.heading_rad))
    segments = []
    if t_sc.size:
        cuts = np.flatnonzero(np.diff(t_sc) > segment_gap_s) + 1
        for lo, hi in zip(np.r_[0, cuts], np.r_[cuts, t_sc.size], strict=True):
            segments.append(SegmentScore(float(t_sc[lo]), float(t_sc[hi - 1]), int(hi - lo),
                                         _rms(err.inclination_rad[lo:hi]),
                                         _rms(err.heading_rad[lo:hi])))
    return OrientationScore(overall, segments, err.offset_rad, len(tr))
