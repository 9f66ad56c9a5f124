"""Yaw correction by trajectory stretching between two position fixes (Colombo eq. 24-28).

Between two accepted fixes at ``t_a`` and ``t_b`` the position filter runs open loop. Let
``l_a = c_a - p_a`` be the residual left after the update at ``t_a`` (small) and
``l_b = c_b - p_b`` the offset between the fix at ``t_b`` and the prediction there. Each estimated
point is shifted by a linear blend of the two (eq. 24) so that the stretched track ends on the fix.
The stretched track must still obey the nonholonomic model, so every sample's displacement
becomes (eq. 25-26)::

    D_k = dt_k v_k s(theta_k) + (l_b - l_a) dt_k / (t_b - t_a)

whose direction and length give the synthesized yaw and speed (eq. 27-28)::

    theta_bar_k = atan2(D_k,y, D_k,x)        v_bar_k = |D_k| / dt_k

Readings: (i) the paper spreads ``l_b - l_a`` equally over the ``m`` samples of period ``T_c``; we
spread it in proportion to each sample's ``dt`` (identical for a constant rate, robust to gaps).
(ii) The yaw to inject into the attitude filter is eq. 28 at ``j = 0`` (the last sample); when the
user stands still at the end that sample carries no direction, so we take the last sample whose
speed exceeds ``min_speed_m_s``. (iii) The paper gives no variance for the pseudo-measurement; we
use the angular uncertainty of the end-point offset over the segment,
``var = (sigma_a^2 + sigma_b^2) / path^2 + sigma_floor^2`` (fix 1-sigmas in m, path length in m),
plus, with ``drift_fraction`` (our addition), the open-loop shape uncertainty
``(drift_fraction * walked)^2 / path^2`` (``chord^2`` for the rotation method).

Eq. 28 at ``j = 0`` is exact for a straight segment but wrong on curved ones: the per-sample shift
``(l_b - l_a)/m`` is added to the *last* displacement whatever its direction, so when the segment
turns by more than about 90 deg (a lap of Colombo's circle at ``Tp >= 8 s``) the correction can
even change sign. ``method="rotation"`` (our addition, the default) therefore takes the yaw
correction as the rotation between the estimated chord ``p_b - p_a`` and the fixed chord
``c_b - c_a`` -- the same value as eq. 28 on a straight segment, and correct for a constant yaw
bias on any path whose chord is longer than ``min_chord_m``; the stretched inputs of eq. 27-28
are returned in both cases.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike

from hrtls.errors import InputError
from hrtls.frames import wrap_angle
from hrtls.fusion._checks import FloatArray, finite_scalar, finite_vector, non_decreasing_time


@dataclass(frozen=True, kw_only=True)
class YawStretchParams:
    """Parameters of the yaw pseudo-measurement.

    Attributes
    ----------
    min_path_m:
        Segments shorter than this (path length between the fixes) give no yaw.
    min_speed_m_s:
        The yaw is read at the last sample at least this fast.
    sigma_floor_rad:
        Added 1-sigma of the pseudo-measurement.
    max_correction_rad:
        Larger corrections are rejected (usually a wrong fix or a turn in place).
    method:
        ``"rotation"`` (chord rotation, default) or ``"paper"`` (eq. 28 at ``j = 0``).
    min_chord_m:
        ``"rotation"`` needs the estimated and fixed chords at least this long.
    drift_fraction:
        Dead-reckoning drift per metre walked between the fixes (our addition): the shape of
        the open-loop segment is uncertain by about ``drift_fraction * path``, which adds
        ``(drift_fraction * path / chord)^2`` to the variance of the yaw (a lap of a small loop
        has a long path and a short chord: its chord rotation says little about the yaw).
    """

    min_path_m: float = 1.0
    min_speed_m_s: float = 0.2
    sigma_floor_rad: float = 0.02
    max_correction_rad: float = 0.6
    method: Literal["rotation", "paper"] = "rotation"
    min_chord_m: float = 1.0
    drift_fraction: float = 0.0

    def __post_init__(self) -> None:
        for name in ("min_path_m", "min_speed_m_s", "sigma_floor_rad", "max_correction_rad",
                     "min_chord_m", "drift_fraction"):
            finite_scalar(getattr(self, name), where=f"YawStretchParams.{name}",
                          non_negative=True)
        if self.method not in ("rotation", "paper"):
            raise InputError(f"method {self.method!r}", where="YawStretchParams.method",
                             expected="'rotation' or 'paper'")


@dataclass(frozen=True, slots=True, eq=False)
class YawStretchResult:
    """Outcome of eq. 24-28 for one segment.

    Attributes
    ----------
    valid: whether ``yaw_rad`` may be injected.
    reason: why not, when invalid.
    yaw_rad: synthesized yaw (eq. 28 at the end of the segment), rad.
    var_yaw_rad2: its variance.
    correction_rad: ``yaw_rad`` minus the estimated yaw at that sample (wrapped).
    speed_scale: ``v_bar / v`` at that sample (eq. 27).
    stretched_yaw: eq. 28 for every sample, rad (m,).
    stretched_speed: eq. 27 for every sample, m/s (m,).
    stretched_xy: stretched track ``p_bar`` from ``p_a + l_a`` to ``c_b``, m (m + 1, 2).
    """

    valid: bool
    reason: str
    yaw_rad: float
    var_yaw_rad2: float
    correction_rad: float
    speed_scale: float
    stretched_yaw: FloatArray
    stretched_speed: FloatArray
    stretched_xy: FloatArray


def stretch_yaw(*, t_start: float, t: ArrayLike, speed_m_s: ArrayLike, yaw_rad: ArrayLike,
                start_xy: ArrayLike, offset_start: ArrayLike, offset_end: ArrayLike,
                sigma_start_m: float, sigma_end_m: float,
                params: YawStretchParams | None = None,
                path_m: float | None = None) -> YawStretchResult:
    """Stretch the open-loop segment between two fixes and synthesize the yaw (eq. 24-28).

    Parameters
    ----------
    t_start:
        Time of the first fix ``t_a``, s.
    t, speed_m_s, yaw_rad:
        The inputs used by the prediction on ``(t_a, t_b]`` (m samples, time non-decreasing).
    start_xy:
        Estimated position right after the update at ``t_a``, m (2,).
    offset_start:
        ``l_a`` = fix at ``t_a`` minus ``start_xy``, m (2,).
    offset_end:
        ``l_b`` = fix at ``t_b`` minus the prediction at ``t_b``, m (2,).
    sigma_start_m, sigma_end_m:
        1-sigma of the two fixes, m.
    params:
        Thresholds; defaults of :class:`YawStretchParams`.
    path_m:
        Distance walked between the fixes, m, for the drift term of the variance; None: the
        path of the given samples (a caller passing the chord as one sample passes the path).
    """
    prm = params or YawStretchParams()
    tt = finite_vector(t, where="stretch t")
    m = tt.shape[0]
    v = finite_vector(speed_m_s, where="stretch speed_m_s", length=m)
    th = finite_vector(yaw_rad, where="stretch yaw_rad", length=m)
    p0 = finite_vector(start_xy, where="stretch start_xy", length=2)
    la = finite_vector(offset_start, where="stretch offset_start", length=2)
    lb = finite_vector(offset_end, where="stretch offset_end", length=2)
    t0 = finite_scalar(t_start, where="stretch t_start")
    sa = finite_scalar(sigma_start_m, where="stretch sigma_start_m", non_negative=True)
    sb = finite_scalar(sigma_end_m, where="stretch sigma_end_m", non_negative=True)
    non_decreasing_time(tt, where="stretch t", after=t0)

    def invalid(reason: str) -> YawStretchResult:
        return YawStretchResult(False, reason, float("nan"), float("nan"), 0.0, 1.0,
                                th.copy(), v.copy(), np.zeros((0, 2)))

    if m == 0:
        return invalid("no samples between the fixes")
    duration = float(tt[-1] - t0)
    if duration <= 0.0:
        return invalid("fixes at the same time")
    dt, step, theta_bar, v_bar, xy = _stretched_track(tt, v, th, t_start=t0, start_xy=p0 + la,
                                                      shift=lb - la)
    path = float(np.sum(dt * v))
    walked = path if path_m is None else finite_scalar(path_m, where="stretch path_m",
                                                        non_negative=True)
    drift2 = (prm.drift_fraction * walked) ** 2
    if path < prm.min_path_m:
        return YawStretchResult(False, f"path {path:.2f} m shorter than {prm.min_path_m} m",
                                float("nan"), float("nan"), 0.0, 1.0, theta_bar, v_bar, xy)
    moving = np.flatnonzero((v >= prm.min_speed_m_s) & (dt > 0.0))
    if moving.size == 0:
        return YawStretchResult(False, "no moving sample", float("nan"), float("nan"), 0.0, 1.0,
                                theta_bar, v_bar, xy)
    j0 = int(moving[-1])
    synth = _synthesized_yaw(prm, step=step, shift=lb - la, yaw_est=float(th[j0]),
                             yaw_stretched=float(theta_bar[j0]),
                             noise2=sa * sa + sb * sb + drift2, path_m=path)
    if isinstance(synth, str):
        return YawStretchResult(False, synth, float("nan"), float("nan"), 0.0, 1.0,
                                theta_bar, v_bar, xy)
    yaw, corr, var = synth
    scale = float(v_bar[j0] / v[j0]) if v[j0] > 0.0 else 1.0
    if abs(corr) > prm.max_correction_rad:
        return YawStretchResult(False, f"correction {corr:.3f} rad beyond "
                                f"{prm.max_correction_rad} rad", yaw, var, corr, scale,
                                theta_bar, v_bar, xy)
    if not np.isfinite(var):
        raise InputError("non-finite yaw variance", where="stretch_yaw")
    return YawStretchResult(True, "", yaw, var, corr, scale, theta_bar, v_bar, xy)


def _stretched_track(tt: FloatArray, v: FloatArray, th: FloatArray, *, t_start: float,
                     start_xy: FloatArray, shift: FloatArray
                     ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray]:
    """Sample spacing, open-loop steps, stretched yaw and speed, and the stretched track.

    ``shift`` is ``l_b - l_a``, spread over the segment in proportion to time (eq. 26);
    ``start_xy`` is ``p_a + l_a``.
    """
    duration = float(tt[-1] - t_start)
    dt = np.diff(np.concatenate(([t_start], tt)))
    s = np.column_stack([np.cos(th), np.sin(th)])
    step = (dt * v)[:, None] * s                        # T_c s(theta) v   (eq. 16)
    d = step + np.outer(dt / duration, shift)          # (l(k) - l(k-m)) / m  (eq. 26)
    theta_bar = np.where(dt > 0.0, np.arctan2(d[:, 1], d[:, 0]), th)      # eq. 28
    with np.errstate(divide="ignore", invalid="ignore"):
        v_bar = np.where(dt > 0.0, np.hypot(d[:, 0], d[:, 1]) / dt, v)  # eq. 27
    xy = np.vstack([start_xy, start_xy + np.cumsum(d, axis=0)])         # eq. 24-25
    return dt, step, theta_bar, v_bar, xy


def _synthesized_yaw(prm: YawStretchParams, *, step: FloatArray, shift: FloatArray,
                     yaw_est: float, yaw_stretched: float, noise2: float,
                     path_m: float) -> tuple[float, float, float] | str:
    """Yaw, correction and variance at the last moving sample, or why there is none.

    ``"paper"``: the stretched yaw itself (eq. 28, j = 0). Else the estimated yaw turned by
    the angle between the estimated chord and the chord of the fixes. ``noise2`` is the sum of
    the fixes' variances and the squared drift, m^2.
    """
    if prm.method == "paper":
        yaw = float(wrap_angle(yaw_stretched))
        corr = float(wrap_angle(yaw - yaw_est))
        return yaw, corr, noise2 / (path_m * path_m) + prm.sigma_floor_rad**2
    chord_est = np.sum(step, axis=0)                                 # p_b - p_a
    chord_fix = chord_est + shift                                    # c_b - c_a
    n_est = float(np.hypot(*chord_est))
    n_fix = float(np.hypot(*chord_fix))
    if min(n_est, n_fix) < prm.min_chord_m:
        return f"chord {min(n_est, n_fix):.2f} m shorter than {prm.min_chord_m} m"
    corr = float(wrap_angle(np.arctan2(chord_fix[1], chord_fix[0])
                            - np.arctan2(chord_est[1], chord_est[0])))
    yaw = float(wrap_angle(yaw_est + corr))
    return yaw, corr, noise2 / (n_fix * n_fix) + prm.sigma_floor_rad**2
