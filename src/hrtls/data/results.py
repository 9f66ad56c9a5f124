"""What the estimators produce: activity labels, step events and trajectories with covariance."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, fields
from enum import IntEnum

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hrtls.data.validation import (
    FloatArray,
    as_float_matrix,
    as_float_vector,
    check_finite,
    check_time,
)
from hrtls.errors import InputError

IntArray = NDArray[np.int64]


class Activity(IntEnum):
    """Activity classes (Inderst Sec. 4.1), stored as small integers; CSV files use the names."""

    UNKNOWN = -1
    STANDING = 0
    WALKING = 1
    RUNNING = 2
    UPSTAIRS = 3
    DOWNSTAIRS = 4

    @property
    def label(self) -> str:
        """Lower-case name used in files (``"walking"``)."""
        return self.name.lower()

    @classmethod
    def parse(cls, text: str) -> Activity:
        """Activity from its file label (case-insensitive) or integer code."""
        key = text.strip()
        try:
            return cls[key.upper()]
        except KeyError:
            pass
        try:
            return cls(int(key))
        except ValueError:
            labels = ", ".join(a.label for a in cls)
            raise InputError(f"unknown activity {text!r}", where="activity",
                             expected=f"one of {labels}") from None


def activity_labels(codes: ArrayLike) -> NDArray[np.str_]:
    """File labels of an array of activity codes."""
    lookup = {int(a): a.label for a in Activity}
    return np.array([lookup.get(int(c), "unknown") for c in np.asarray(codes)], dtype=np.str_)


def activity_codes(labels: ArrayLike, *, where: str = "activity") -> IntArray:
    """Activity codes of an array of labels; unknown labels raise naming the first index."""
    out = np.empty(len(np.asarray(labels)), dtype=np.int64)
    cache: dict[str, int] = {}
    for i, text in enumerate(np.asarray(labels, dtype=np.str_)):
        if text not in cache:
            try:
                cache[text] = int(Activity.parse(str(text)))
            except InputError as exc:
                raise InputError(exc.problem, where=f"{where} index {i}",
                                 expected=exc.expected) from None
        out[i] = cache[text]
    return out


def _as_codes(x: ArrayLike, *, where: str, length: int) -> IntArray:
    arr = np.asarray(x)
    if arr.dtype.kind in "US":
        arr = activity_codes(arr, where=where)
    arr = arr.astype(np.int64)
    if arr.shape != (length,):
        raise InputError(f"shape {arr.shape}", where=where, expected=f"({length},)")
    valid = np.isin(arr, [int(a) for a in Activity])
    if not np.all(valid):
        idx = int(np.flatnonzero(~valid)[0])
        raise InputError(f"code {arr[idx]}", where=f"{where} index {idx}",
                         expected="an Activity code")
    return arr


@dataclass(frozen=True, slots=True, eq=False)
class StepEvents:
    """Detected (or true) steps.

    Attributes
    ----------
    t_start, t_end: step start and end, s (``t_end >= t_start``; starts non-decreasing).
    length_m: horizontal step length, m.
    heading_rad: walking direction of the step, rad (ENU, CCW from east); NaN when unknown.
    dz_m: height change, m (stairs).
    activity: :class:`Activity` codes.
    frequency_hz: step frequency, Hz; NaN when unknown.
    acc_max, acc_min: extremes of vertical acceleration within the step, m/s^2; NaN when unknown.
    """

    t_start: FloatArray
    t_end: FloatArray
    length_m: FloatArray
    heading_rad: FloatArray
    dz_m: FloatArray
    activity: IntArray
    frequency_hz: FloatArray
    acc_max: FloatArray
    acc_min: FloatArray

    def __post_init__(self) -> None:
        n = len(np.asarray(self.t_start))
        t0 = as_float_vector(self.t_start, where="steps t_start")
        check_time(t0, where="steps t_start", strict=False)
        t1 = as_float_vector(self.t_end, where="steps t_end", length=n)
        check_finite(t1, where="steps t_end")
        if np.any(t1 < t0):
            idx = int(np.flatnonzero(t1 < t0)[0])
            raise InputError("step ends before it starts", where=f"steps index {idx}",
                             expected="t_end >= t_start")
        arrays = {"t_start": t0, "t_end": t1}
        for attr, allow_nan in (("length_m", False), ("heading_rad", True), ("dz_m", False),
                                ("frequency_hz", True), ("acc_max", True), ("acc_min", True)):
            arr = as_float_vector(getattr(self, attr), where=f"steps {attr}", length=n)
            check_finite(arr, where=f"steps {attr}", allow_nan=allow_nan)
            arrays[attr] = arr
        if np.any(arrays["length_m"] < 0):
            raise InputError("negative step length", where="steps length_m", expected=">= 0 m")
        for attr, value in arrays.items():
            object.__setattr__(self, attr, value)
        object.__setattr__(self, "activity", _as_codes(self.activity, where="steps activity",
                                                        length=n))

    @classmethod
    def empty(cls) -> StepEvents:
        """No steps."""
        z = np.zeros(0)
        return cls(z, z, z, z, z, np.zeros(0, dtype=np.int64), z, z, z)

    @classmethod
    def build(cls, *, t_start: ArrayLike, t_end: ArrayLike, length_m: ArrayLike,
              heading_rad: ArrayLike | None = None, dz_m: ArrayLike | None = None,
              activity: ArrayLike | None = None, frequency_hz: ArrayLike | None = None,
              acc_max: ArrayLike | None = None, acc_min: ArrayLike | None = None) -> StepEvents:
        """Build from keyword arrays; omitted columns become NaN (or 0 m / walking)."""
        n = len(np.asarray(t_start))
        nan = np.full(n, np.nan)
        return cls(
            np.asarray(t_start, dtype=np.float64), np.asarray(t_end, dtype=np.float64),
            np.asarray(length_m, dtype=np.float64),
            nan if heading_rad is None else np.asarray(heading_rad, dtype=np.float64),
            np.zeros(n) if dz_m is None else np.asarray(dz_m, dtype=np.float64),
            np.full(n, int(Activity.WALKING)) if activity is None else np.asarray(activity),
            nan if frequency_hz is None else np.asarray(frequency_hz, dtype=np.float64),
            nan if acc_max is None else np.asarray(acc_max, dtype=np.float64),
            nan if acc_min is None else np.asarray(acc_min, dtype=np.float64),
        )

    def __len__(self) -> int:
        return len(self.t_start)

    def select(self, keep: NDArray[np.bool_]) -> StepEvents:
        """The steps where ``keep`` is true."""
        return StepEvents(*(getattr(self, f.name)[keep] for f in fields(self)))

    @classmethod
    def concatenate(cls, parts: Sequence[StepEvents]) -> StepEvents:
        """The steps of ``parts`` one after the other (at least one part)."""
        return cls(*(np.concatenate([getattr(p, f.name) for p in parts]) for f in fields(cls)))

    @property
    def distance_m(self) -> float:
        """Sum of step lengths, m."""
        return float(np.sum(self.length_m))


@dataclass(frozen=True, slots=True, eq=False)
class Trajectory:
    """Estimated track in the navigation frame with its uncertainty.

    Attributes
    ----------
    t: times, s (strictly increasing).
    xyz: positions, m, (N, 3).
    heading_rad: heading, rad (ENU, CCW from east, wrapped).
    cov_xy: horizontal position covariance, m^2, (N, 2, 2), symmetric PSD.
    var_heading: heading variance, rad^2.
    activity: :class:`Activity` codes.
    """

    t: FloatArray
    xyz: FloatArray
    heading_rad: FloatArray
    cov_xy: FloatArray
    var_heading: FloatArray
    activity: IntArray

    def __post_init__(self) -> None:
        t = as_float_vector(self.t, where="trajectory time")
        check_time(t, where="trajectory")
        n = len(t)
        xyz = as_float_matrix(self.xyz, where="trajectory xyz", columns=3, length=n)
        check_finite(xyz, where="trajectory xyz")
        heading = as_float_vector(self.heading_rad, where="trajectory heading", length=n)
        check_finite(heading, where="trajectory heading", allow_nan=True)
        cov = np.asarray(self.cov_xy, dtype=np.float64)
        if cov.shape != (n, 2, 2):
            raise InputError(f"shape {cov.shape}", where="trajectory cov_xy",
                             expected=f"({n}, 2, 2)")
        check_finite(cov, where="trajectory cov_xy")
        if n and (np.any(cov[:, 0, 0] < 0) or np.any(cov[:, 1, 1] < 0)
                  or not np.allclose(cov[:, 0, 1], cov[:, 1, 0])):
            raise InputError("covariance not symmetric PSD", where="trajectory cov_xy",
                             expected="symmetric positive semi-definite 2x2 matrices")
        var_h = as_float_vector(self.var_heading, where="trajectory var_heading", length=n)
        check_finite(var_h, where="trajectory var_heading", allow_nan=True)
        for attr, value in (("t", t), ("xyz", xyz), ("heading_rad", heading), ("cov_xy", cov),
                            ("var_heading", var_h)):
            object.__setattr__(self, attr, value)
        object.__setattr__(self, "activity", _as_codes(self.activity, where="trajectory activity",
                                                        length=n))

    @classmethod
    def build(cls, *, t: ArrayLike, xyz: ArrayLike, heading_rad: ArrayLike | None = None,
              cov_xy: ArrayLike | None = None, var_heading: ArrayLike | None = None,
              activity: ArrayLike | None = None) -> Trajectory:
        """Build from keyword arrays; omitted columns become NaN / zero covariance / unknown."""
        n = len(np.asarray(t))
        nan = np.full(n, np.nan)
        return cls(
            np.asarray(t, dtype=np.float64), np.asarray(xyz, dtype=np.float64),
            nan if heading_rad is None else np.asarray(heading_rad, dtype=np.float64),
            np.zeros((n, 2, 2)) if cov_xy is None else np.asarray(cov_xy, dtype=np.float64),
            nan if var_heading is None else np.asarray(var_heading, dtype=np.float64),
            np.full(n, int(Activity.UNKNOWN)) if activity is None else np.asarray(activity),
        )

    def __len__(self) -> int:
        return len(self.t)

    @property
    def path_length_m(self) -> float:
        """Horizontal length of the track, m."""
        return float(np.sum(np.linalg.norm(np.diff(self.xyz[:, :2], axis=0), axis=1)))

    def position_at(self, t_query: ArrayLike) -> FloatArray:
        """Linearly interpolated positions (M, 3) at ``t_query``."""
        tq = np.asarray(t_query, dtype=np.float64)
        return np.column_stack([np.interp(tq, self.t, c) for c in self.xyz.T])
