"""Pre-processing and window features for activity recognition (Inderst Sec. 4.1).

* :class:`StreamingButterworth`: the 5th-order Butterworth low-pass at 6 Hz applied to the raw
  body-frame accelerations (second-order sections carried across chunks, so chunked and whole-run
  outputs agree).
* :func:`window_features`: the features of non-overlapping windows of ``j`` samples (eq. 4.2),
  or of sliding windows with a shorter hop: the three decision-tree features (vertical
  variance, vertical dynamics index of eq. 4.3-4.5, medio-lateral amplitude) and the seven LDA
  features of Table 4.1 (std, DFT peak and, for the medio-lateral axis, max - min). The DFT
  peak is read from a 4x zero-padded DFT so that it does not depend on where the cadence falls
  between the 1 / window bins.

Body-frame columns are ``[AP, ML, V]`` = hrtls body ``[x forward, y left, z up]``.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from hrtls.errors import InputError
from hrtls.gait._state import FloatArray, as_matrix, check_positive
from hrtls.gait.butterworth import (
    butter_lowpass_sos,
    sos_kernel,
    sos_response,
    sos_steady_state,
)

TREE_FEATURES = ("vertical_variance", "vertical_dynamics_index", "ml_amplitude")
LDA_FEATURES = ("std_ml", "std_v", "std_ap", "dft_ml", "dft_v", "dft_ap", "range_ml")


@functools.lru_cache(maxsize=64)
def _butter_sos(order: int, cutoff_hz: float, rate_hz: float) -> tuple[FloatArray, FloatArray]:
    """Second-order sections and their unit steady-state memory, designed once per set.

    A restore rebuilds every filter; the cached arrays are read-only and each filter copies them.
    """
    sos = butter_lowpass_sos(order, cutoff_hz, rate_hz)
    zi = sos_steady_state(sos)
    sos.flags.writeable = False
    zi.flags.writeable = False
    return sos, zi


@functools.lru_cache(maxsize=64)
def _group_delay_s(order: int, cutoff_hz: float, rate_hz: float, frequency_hz: float) -> float:
    df = 0.01
    f = np.array([max(frequency_hz - df, 1e-3), frequency_hz + df])
    h = sos_response(_butter_sos(order, cutoff_hz, rate_hz)[0], f, rate_hz)
    ph = np.unwrap(np.angle(h))
    return float(-(ph[1] - ph[0]) / (2.0 * np.pi * (f[1] - f[0])))


class StreamingButterworth:
    """Causal Butterworth low-pass over the columns of a signal, chunk by chunk.

    Parameters
    ----------
    order: filter order (5 in Inderst Sec. 4.1).
    cutoff_hz: corner frequency, Hz (6 Hz in Inderst Sec. 4.1).
    rate_hz: sampling rate, Hz.
    """

    def __init__(self, *, order: int = 5, cutoff_hz: float = 6.0, rate_hz: float) -> None:
        check_positive(cutoff_hz, "cutoff_hz")
        check_positive(rate_hz, "rate_hz")
        if order < 1 or cutoff_hz >= rate_hz / 2:
            raise InputError(f"order {order}, cutoff {cutoff_hz} Hz at {rate_hz} Hz",
                             where="StreamingButterworth",
                             expected="order >= 1 and cutoff below the Nyquist frequency")
        self.rate_hz = float(rate_hz)
        self._design = (order, float(cutoff_hz), self.rate_hz)
        sos, zi_unit = _butter_sos(*self._design)
        self.sos, self._zi_unit = sos.copy(), zi_unit.copy()
        self.zi: FloatArray | None = None

    def group_delay_s(self, frequency_hz: float) -> float:
        """Group delay of the filter at ``frequency_hz``, s (from the unwrapped phase)."""
        return _group_delay_s(*self._design, float(frequency_hz))

    def reset(self) -> None:
        """Forget the filter memory (the next sample starts the filter in steady state)."""
        self.zi = None

    def update(self, x: FloatArray) -> FloatArray:
        """Filter a chunk of shape (N,) or (N, K) along axis 0."""
        arr = np.asarray(x, dtype=np.float64)
        if arr.shape[0] == 0:
            return arr.copy()
        if self.zi is None:
            # steady state for the first sample avoids the start-up transient
            first = arr[0]
            self.zi = np.multiply.outer(self._zi_unit, np.ones(arr.shape[1:])) * first
        columns = np.ascontiguousarray(arr.reshape(len(arr), -1))
        zi = np.ascontiguousarray(self.zi.reshape(len(self.sos), 2, -1))
        y = np.empty_like(columns)
        sos_kernel(self.sos, columns, zi, y)
        self.zi = zi.reshape(self.zi.shape)
        return y.reshape(arr.shape)


@dataclass(frozen=True, slots=True, eq=False)
class WindowFeatures:
    """Features per window.

    Attributes
    ----------
    t_start, t_end: window boundaries (first and last sample time), s.
    tree: (W, 3) decision-tree features, see ``TREE_FEATURES`` (m^2/s^4, m/s^2, m/s^2).
    lda: (W, 7) LDA features of Inderst Table 4.1, see ``LDA_FEATURES`` (m/s^2).
    """

    t_start: FloatArray
    t_end: FloatArray
    tree: FloatArray
    lda: FloatArray

    def __len__(self) -> int:
        return int(self.t_start.shape[0])


DFT_ZERO_PAD = 4
"""Zero-padding factor of the window DFT (the spectrum is sampled ``DFT_ZERO_PAD`` times finer)."""


def window_features(t: FloatArray, acc_body_lp: FloatArray, *, window_samples: int,
                    anthropometric_nr: float = 1.0, dft_zero_pad: int = DFT_ZERO_PAD,
                    hop_samples: int | None = None) -> WindowFeatures:
    """Features of windows of ``window_samples`` samples starting every ``hop_samples``.

    Parameters
    ----------
    t: sample times, s (N,).
    acc_body_lp: low-passed body-frame acceleration [AP, ML, V] in m/s^2 (N, 3), vertical
        including gravity (as measured).
    window_samples: samples per window ``j`` (eq. 4.2); a trailing partial window is dropped.
    anthropometric_nr: ``n_r`` of eq. 4.3 (the vertical threshold is ``mean / n_r``).
    dft_zero_pad: the mean-removed window is zero-padded to ``dft_zero_pad * j`` samples before
        the DFT (1: plain ``j``-point DFT).
    hop_samples: samples between window starts (None: ``j``, consecutive non-overlapping
        windows as in eq. 4.2). A hop shorter than ``j`` gives sliding windows whose label
        can be given to their central ``hop_samples`` samples (finer activity boundaries).

    Notes
    -----
    Vertical dynamics index (eq. 4.3-4.5): the window's vertical samples are split at
    ``gamma = mean / n_r``; ``i_M`` and ``i_m`` are the means of the parts above and below minus
    the window mean; the index is ``sqrt(i_M^2 + i_m^2)``. An empty part contributes 0.
    DFT peak (Table 4.1): the largest DFT magnitude of the mean-removed window, excluding the
    zero frequency, scaled by ``2 / j`` (the amplitude of a sinusoid at that frequency). With
    a plain ``j``-point DFT a 2 s window has 0.5 Hz bins and the peak of a gait harmonic between
    two bins is up to 36 % lower than on a bin, so the feature would depend on where the cadence
    falls on the bin grid; zero-padding samples the same spectrum finer (< 3 % loss at 4x).
    """
    if window_samples < 4:
        raise InputError(f"window of {window_samples} samples", where="window_samples",
                         expected=">= 4")
    check_positive(anthropometric_nr, "anthropometric_nr")
    if int(dft_zero_pad) != dft_zero_pad or dft_zero_pad < 1:
        raise InputError(f"dft_zero_pad = {dft_zero_pad}", where="dft_zero_pad",
                         expected="an integer >= 1")
    acc = as_matrix(acc_body_lp, where="body acceleration", columns=3)
    tt = np.asarray(t, dtype=np.float64)
    if tt.shape[0] != acc.shape[0]:
        raise InputError(f"{tt.shape[0]} times for {acc.shape[0]} rows", where="features",
                         expected="one time per row")
    j = int(window_samples)
    hop = j if hop_samples is None else int(hop_samples)
    if hop < 1 or hop > j:
        raise InputError(f"hop of {hop_samples} samples", where="hop_samples",
                         expected=f"1 <= hop <= window ({j} samples)")
    nw = (acc.shape[0] - j) // hop + 1 if acc.shape[0] >= j else 0
    if hop == j:
        # (3, W, j) contiguous: reductions and the FFT run along the last axis
        a = np.ascontiguousarray(acc[: nw * j].T).reshape(3, nw, j)
        tw = tt[: nw * j].reshape(nw, j)
    else:
        starts = np.arange(nw) * hop
        idx = starts[:, None] + np.arange(j)[None, :]
        a = np.ascontiguousarray(acc.T[:, idx]).reshape(3, nw, j)
        tw = tt[idx].reshape(nw, j)
    mean = a.mean(axis=2)  # (3, W)
    centred = a - mean[:, :, None]
    std = np.sqrt(np.einsum("cwj,cwj->cw", centred, centred) / j)
    v = a[2]
    gamma = mean[2] / anthropometric_nr
    hi = v >= gamma[:, None]
    n_hi = hi.sum(axis=1)
    n_lo = j - n_hi
    sum_all = v.sum(axis=1)
    sum_hi = np.einsum("wj,wj->w", v, hi.astype(np.float64))
    sum_lo = sum_all - sum_hi
    i_m_plus = np.where(n_hi > 0, sum_hi / np.maximum(n_hi, 1) - mean[2], 0.0)
    i_m_minus = np.where(n_lo > 0, sum_lo / np.maximum(n_lo, 1) - mean[2], 0.0)
    vdi = np.hypot(i_m_plus, i_m_minus)
    ml_range = a[1].max(axis=1) - a[1].min(axis=1)
    # bins below the first bin of the unpadded DFT (1 / window) are the zero-frequency lobe
    pad = int(dft_zero_pad)
    spec = np.abs(np.fft.rfft(centred, n=pad * j, axis=2))[:, :, pad:]
    dft_peak = spec.max(axis=2) * (2.0 / j) if spec.shape[2] else np.zeros((3, nw))
    tree = np.column_stack([std[2] ** 2, vdi, ml_range])
    # Table 4.1 order: columns ML, V, AP
    lda = np.column_stack([std[1], std[2], std[0], dft_peak[1], dft_peak[2], dft_peak[0],
                           ml_range])
    return WindowFeatures(tw[:, 0].copy(), tw[:, -1].copy(), tree, lda)


def window_labels(labels: NDArray[np.int64], window_samples: int, *,
                  min_purity: float = 1.0) -> NDArray[np.int64]:
    """Label of each complete window: the majority label when its share is >= ``min_purity``.

    Windows that are not pure enough get ``-1`` (unknown) and are ignored in training.
    """
    y = np.asarray(labels, dtype=np.int64)
    j = int(window_samples)
    nw = y.shape[0] // j
    w = y[: nw * j].reshape(nw, j)
    out = np.full(nw, -1, dtype=np.int64)
    for cls in np.unique(w):
        share = (w == cls).mean(axis=1)
        out[share >= min_purity] = cls
    return out
