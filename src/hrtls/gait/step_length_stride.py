"""Stride lengths from step lengths, the turning correction and daily-life scale transfer.

Not from the project papers; helpers to score and correct step-length models against a
stride reference (e.g. the Mobilise-D INDIP strides) and to use them on curved paths.

* :func:`prorated_stride_lengths`: the length of a stride ``[s0, s1]`` (two consecutive
  contacts of the same foot) estimated from detected steps whatever their count: every step
  ``k`` with interval ``[a_k, b_k]`` and length ``l_k`` contributes the share of its length that
  its interval overlaps the stride,

      L = sum_k l_k * |[a_k, b_k] ∩ [s0, s1]| / (b_k - a_k).

  With two detected steps that tile the stride this is their sum; a missed step leaves a hole
  (the estimate is short), an extra step splits a length (unchanged total). ``coverage`` (the
  summed overlap share, 2 for a tiled stride) tells how many steps the stride got. A step of
  zero duration contributes nothing.
* :func:`chord_factor`: a foot displacement measured as a straight line (the chord) over a
  path that turned by ``theta`` along a circular arc is ``arc * sin(theta/2) / (theta/2)``;
  step-length models give the travelled (arc) length. :func:`rotation_over` integrates the
  rate about the vertical (:meth:`hrtls.gait.turns.TurnDetector.vertical_rate`) over intervals.
* :func:`fit_scale` (least-squares ``K`` of ``true = K * unit``) and :func:`transfer_scale`:
  a per-person ``K`` calibrated on straight walks overestimates slow, short daily-life
  strides; the ratio ``K_daily / K_straight`` learnt on *other* persons (where daily-life
  references exist) is applied to a new person's straight-walk ``K``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from hrtls.errors import InputError
from hrtls.gait._state import FloatArray, as_vector


@dataclass(frozen=True, slots=True, eq=False)
class StrideEstimate:
    """Stride lengths from prorated steps.

    Attributes
    ----------
    length_m: estimated stride lengths, m.
    coverage: summed overlap share of the steps (2 when two steps tile the stride).
    """

    length_m: FloatArray
    coverage: FloatArray


def prorated_stride_lengths(step_t_start: ArrayLike, step_t_end: ArrayLike,
                            step_length_m: ArrayLike, stride_start_s: ArrayLike,
                            stride_end_s: ArrayLike) -> StrideEstimate:
    """Stride lengths from the steps overlapping each stride (see module notes).

    Parameters
    ----------
    step_t_start, step_t_end: step intervals, s (``t_end >= t_start``; steps sorted by start).
    step_length_m: step lengths, m.
    stride_start_s, stride_end_s: strides, s (``end > start``).
    """
    a = as_vector(step_t_start, where="step_t_start")
    b = as_vector(step_t_end, where="step_t_end", length=a.shape[0])
    ln = as_vector(step_length_m, where="step_length_m", length=a.shape[0])
    s0 = as_vector(stride_start_s, where="stride_start_s")
    s1 = as_vector(stride_end_s, where="stride_end_s", length=s0.shape[0])
    if np.any(b < a):
        k = int(np.flatnonzero(b < a)[0])
        raise InputError(f"step {k} ends before it starts", where="step_t_end",
                         expected="t_end >= t_start")
    if np.any(np.diff(a) < 0):
        raise InputError("steps not sorted", where="step_t_start",
                         expected="non-decreasing step starts")
    if np.any(s1 <= s0):
        k = int(np.flatnonzero(s1 <= s0)[0])
        raise InputError(f"stride {k} has end <= start", where="stride_end_s",
                         expected="stride_end_s > stride_start_s")
    span = np.maximum(b - a, 1e-9)
    # steps whose start precedes the stride end; among them those ending after its start
    longest = float(np.max(span)) if span.size else 0.0
    length = np.zeros(s0.shape[0])
    cover = np.zeros(s0.shape[0])
    for i in range(s0.shape[0]):
        lo = int(np.searchsorted(a, s0[i] - longest, side="left"))
        hi = int(np.searchsorted(a, s1[i], side="left"))
        if hi <= lo:
            continue
        ov = np.clip(np.minimum(b[lo:hi], s1[i]) - np.maximum(a[lo:hi], s0[i]), 0.0, None)
        share = ov / span[lo:hi]
        length[i] = float(np.sum(share * ln[lo:hi]))
        cover[i] = float(np.sum(share))
    return StrideEstimate(length, cover)


def chord_factor(angle_rad: ArrayLike) -> FloatArray:
    """``sin(theta/2) / (theta/2)``: chord over arc length of a circular arc turning ``theta``.

    1 for a straight path; ``2 sqrt(2) / pi ~ 0.90`` for a quarter turn; ``2 / pi`` for a half
    turn. ``|theta|`` above ``2 pi`` is clipped (the chord of a full circle is 0).
    """
    th = np.abs(np.asarray(angle_rad, dtype=np.float64))
    if np.any(~np.isfinite(th)):
        raise InputError("non-finite angle", where="chord_factor", expected="finite radians")
    half = 0.5 * np.minimum(th, 2.0 * np.pi)
    safe = np.where(half > 1e-8, half, 1.0)
    return np.asarray(np.where(half > 1e-8, np.sin(safe) / safe, 1.0 - half * half / 6.0),
                      dtype=np.float64)


def rotation_over(t: ArrayLike, omega_z_rad_s: ArrayLike, t_start: ArrayLike,
                  t_end: ArrayLike) -> FloatArray:
    """Signed rotation about the vertical (rad) over each ``[t_start, t_end]``.

    ``omega_z_rad_s[i]`` is the rate over ``(t[i-1], t[i]]`` (as returned by
    :meth:`~hrtls.gait.turns.TurnDetector.vertical_rate`); the running integral is linearly
    interpolated at the interval ends (clamped to the recording).
    """
    tt = as_vector(t, where="rotation time")
    if tt.shape[0] < 2 or np.any(np.diff(tt) <= 0):
        raise InputError("fewer than 2 samples or non-increasing times", where="rotation time",
                         expected="strictly increasing times")
    w = as_vector(omega_z_rad_s, where="omega_z", length=tt.shape[0])
    t0 = as_vector(t_start, where="interval starts")
    t1 = as_vector(t_end, where="interval ends", length=t0.shape[0])
    cum = np.concatenate([[0.0], np.cumsum(w[1:] * np.diff(tt))])
    return np.asarray(np.interp(t1, tt, cum) - np.interp(t0, tt, cum), dtype=np.float64)


def fit_scale(unit_length_m: ArrayLike, true_length_m: ArrayLike) -> float:
    """Least-squares ``K`` of ``true = K * unit`` (``sum u d / sum u^2``)."""
    u = as_vector(unit_length_m, where="unit lengths")
    d = as_vector(true_length_m, where="true lengths", length=u.shape[0])
    den = float(np.sum(u * u))
    if den <= 0:
        raise InputError("all unit lengths are zero", where="fit_scale",
                         expected="at least one non-zero model length")
    return float(np.sum(u * d)) / den


def transfer_scale(k_straight: float, others: Sequence[tuple[float, float]]) -> float:
    """Daily-life ``K`` of a person from their straight-walk ``K`` and other persons' ratios.

    ``others``: ``(K_straight_j, K_daily_j)`` of other persons; the mean ratio
    ``K_daily_j / K_straight_j`` multiplies ``k_straight``.
    """
    if not (np.isfinite(k_straight) and k_straight > 0):
        raise InputError(f"k_straight = {k_straight}", where="transfer_scale",
                         expected="a finite K > 0")
    if not others:
        raise InputError("no other persons", where="transfer_scale",
                         expected="at least one (K_straight, K_daily) pair")
    ratios = []
    for j, (ks, kd) in enumerate(others):
        if not (np.isfinite(ks) and ks > 0 and np.isfinite(kd) and kd > 0):
            raise InputError(f"pair {(ks, kd)}", where=f"transfer_scale others[{j}]",
                             expected="finite K values > 0")
        ratios.append(kd / ks)
    return float(k_straight * np.mean(ratios))


__all__ = ["StrideEstimate", "chord_factor", "fit_scale", "prorated_stride_lengths",
           "rotation_over", "transfer_scale"]
