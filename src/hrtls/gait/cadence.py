"""Walking detection and step frequency from the periodicity of vertical acceleration.

A complement to the spread test of Basso Sec. II-B (:mod:`hrtls.gait.motion_detector`): a slow
walker (about 0.9 m/s or less) moves the pelvis so little that the 2 s standard deviation of
vertical acceleration stays below Basso's 1.5 m/s^2, and a phone in a trouser pocket shakes so
much that walking exceeds the 5 m/s^2 running level. What separates walking from other movement is
that it is *periodic* at the step frequency (0.7-4 Hz); what separates running from walking is the
step frequency (Basso Sec. II-D: walking 1.5-2.2 Hz, running 2.7-4.2 Hz).

Method (our design, not from the papers): the vertical acceleration (already low-passed by the
analyzer's step filter) is averaged over blocks of ``decimation`` samples (about 25 Hz). Every
``hop_s`` the last ``window_s`` of these samples, mean removed, give the normalized
autocorrelation

    r(L) = sum_i y_i y_{i-L} / sqrt(sum_i y_i^2 * sum_i y_{i-L}^2),   i = L .. W-1,

at every lag ``L`` between ``min_step_s`` and ``max_step_s``. The best lag (largest ``r``)
refined by a parabola through its neighbours is the step period; if ``r`` at half of it is almost
as large (``r(L/k) >= half_lag_ratio * r(L)``, k = 4, 3, 2, first match) the best lag was a
stride (or several steps) and ``L/k`` is taken.
The window is *walking* when ``r >= r_threshold`` and the standard deviation of the window is at
least ``min_std_m_s2`` (below it the "periodicity" is sensor noise or a vibration). The decision
holds until the next hop. :meth:`CadenceDetector.update` combines it with the Basso spread test
into one motion state: moving when either test says so, running when the spread exceeds the
running level *and* (if periodic) the step frequency is at least ``run_frequency_hz``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hrtls.errors import InputError
from hrtls.gait._state import FloatArray, as_vector, check_positive
from hrtls.kernels import njit

IntArray = NDArray[np.int64]


@dataclass(frozen=True, kw_only=True, slots=True)
class CadenceParams:
    """Parameters of the periodicity (autocorrelation) walking detector.

    Attributes
    ----------
    window_s: length of the autocorrelation window, s (two slow steps fit in it; the onset
        of walking is reported about half a window late).
    hop_s: time between two evaluations, s.
    decimated_rate_hz: rate of the block-averaged signal the autocorrelation runs on, Hz.
    min_step_s, max_step_s: range of step periods searched, s (4 Hz down to about 0.8 Hz).
    r_threshold: smallest normalized autocorrelation of a walking window.
    half_lag_ratio: take a sub-multiple ``L/k`` of the best lag when ``r`` there reaches this
        share of the best.
    min_std_m_s2: smallest standard deviation of a walking window, m/s^2.
    run_frequency_hz: running needs at least this step frequency, Hz (Basso: walking up to
        2.2 Hz, running from 2.7 Hz).
    """

    window_s: float = 2.4
    hop_s: float = 0.5
    decimated_rate_hz: float = 25.0
    min_step_s: float = 0.25
    max_step_s: float = 1.2
    r_threshold: float = 0.4
    half_lag_ratio: float = 0.85
    min_std_m_s2: float = 0.2
    run_frequency_hz: float = 2.4


@njit(cache=True)
def _lagged_products(y: FloatArray, lag: int, n_lags: int,
                     out: FloatArray) -> None:  # pragma: no cover - compiled
    """``out[l] = sum_k y[k] y[k - l]`` (k from l up) for ``n_lags`` (1 or 4) lags from ``lag``.

    Four lags share one pass with four independent sums, each added in the order of ``k``.
    """
    n = y.shape[0]
    if n_lags == 1:
        s = 0.0
        for k in range(lag, n):
            s += y[k] * y[k - lag]
        out[lag] = s
        return
    s0 = s1 = s2 = s3 = 0.0
    for k in range(lag, lag + 3):   # terms before the fourth lag's first one
        s0 += y[k] * y[k - lag]
        if k >= lag + 1:
            s1 += y[k] * y[k - lag - 1]
        if k >= lag + 2:
            s2 += y[k] * y[k - lag - 2]
    for k in range(lag + 3, n):
        s0 += y[k] * y[k - lag]
        s1 += y[k] * y[k - lag - 1]
        s2 += y[k] * y[k - lag - 2]
        s3 += y[k] * y[k - lag - 3]
    out[lag] = s0
    out[lag + 1] = s1
    out[lag + 2] = s2
    out[lag + 3] = s3


@njit(cache=True)
def cadence_kernel(x: FloatArray, sigma: FloatArray, ipars: IntArray, fpars: FloatArray,
                   buf: FloatArray, ist: IntArray, fst: FloatArray, walk_out: IntArray,
                   freq_out: FloatArray, r_out: FloatArray,
                   state_out: IntArray) -> None:  # pragma: no cover
    """Block-average ``x``, evaluate the autocorrelation every hop, hold the decision.

    ``ipars = [decimation, window_n, lag_min, lag_max, hop_n]`` (decimated samples);
    ``fpars = [r_threshold, half_lag_ratio, min_std, decimated_rate_hz, still_threshold,
    run_threshold, run_frequency_hz]``; ``sigma`` is the Basso spread of the same samples
    (the combined state is written to ``state_out``; pass an empty ``sigma`` to skip it).
    State: ``buf`` ring buffer of ``window_n`` decimated samples; ``ist = [head, count,
    block_n, hop_count, walking]``; ``fst = [block_sum, frequency_hz, r]``.
    Outputs per input sample: walking flag (0/1), step frequency (Hz, NaN when not
    periodic) and the best ``r``.
    """
    dec, wn, lmin, lmax, hop = ipars[0], ipars[1], ipars[2], ipars[3], ipars[4]
    r_thr, half_ratio, min_std, rate = fpars[0], fpars[1], fpars[2], fpars[3]
    still_thr, run_thr, run_f = fpars[4], fpars[5], fpars[6]
    combine = sigma.shape[0] == x.shape[0]
    head, count, bn, hc, walking = ist[0], ist[1], ist[2], ist[3], ist[4]
    bsum, freq, rbest = fst[0], fst[1], fst[2]
    y = np.empty(wn)
    rr = np.empty(lmax + 2)
    cum = np.empty(wn + 1)
    for i in range(x.shape[0]):
        bsum += x[i]
        bn += 1
        if bn == dec:
            buf[head] = bsum / dec
            head = (head + 1) % wn
            if count < wn:
                count += 1
            bsum = 0.0
            bn = 0
            hc += 1
            if hc >= hop and count == wn:
                hc = 0
                # window in time order, mean removed
                m = 0.0
                for k in range(wn):
                    y[k] = buf[(head + k) % wn]
                    m += y[k]
                m /= wn
                var = 0.0
                for k in range(wn):
                    y[k] -= m
                    var += y[k] * y[k]
                std = np.sqrt(var / wn)
                # prefix sums of y^2: the energies of the two overlapping parts
                cum[0] = 0.0
                for k in range(wn):
                    cum[k + 1] = cum[k] + y[k] * y[k]
                best = -1
                rbest = -1.0
                lag = lmin - 1
                while lag < lmax + 2:
                    if lag < 1 or lag >= wn - 2:
                        rr[lag] = 0.0
                        lag += 1
                        continue
                    n_lags = 4 if lag + 3 < min(lmax + 2, wn - 2) else 1
                    _lagged_products(y, lag, n_lags, rr)
                    for j in range(lag, lag + n_lags):
                        s0 = cum[wn] - cum[j]
                        s1 = cum[wn - j]
                        rr[j] = rr[j] / np.sqrt(s0 * s1) if s0 > 0.0 and s1 > 0.0 else 0.0
                    lag += n_lags
                for lag in range(lmin, lmax + 1):
                    if lag < wn - 2 and rr[lag] > rbest:
                        rbest = rr[lag]
                        best = lag
                if best > 0:
                    # the best lag may be a stride or a few steps (a fast sinusoid sampled at
                    # 25 Hz correlates best at the multiple closest to a whole lag): take the
                    # shortest sub-multiple best/k whose r is almost as large
                    for k in range(4, 1, -1):
                        lo = best // k
                        if lo < lmin:
                            continue
                        hb = lo
                        if best % k != 0 and lo + 1 <= lmax and rr[lo + 1] > rr[lo]:
                            hb = lo + 1
                        if rr[hb] >= half_ratio * rbest:
                            best = hb
                            break
                    # parabolic refinement of the peak position
                    a = rr[best - 1]
                    b = rr[best]
                    c = rr[best + 1]
                    den = a - 2.0 * b + c
                    off = 0.5 * (a - c) / den if den < 0.0 else 0.0
                    if off > 0.5:
                        off = 0.5
                    elif off < -0.5:
                        off = -0.5
                    rbest = rr[best]
                    walking = 1 if (rbest >= r_thr and std >= min_std) else 0
                    freq = rate / (best + off) if walking == 1 else np.nan
                else:
                    walking = 0
                    freq = np.nan
        walk_out[i] = walking
        freq_out[i] = freq
        r_out[i] = rbest
        if combine:
            sg = sigma[i]
            if sg > run_thr and (walking == 0 or freq >= run_f):
                state_out[i] = 2
            elif sg > still_thr or walking == 1:
                state_out[i] = 1
            else:
                state_out[i] = 0
    ist[0], ist[1], ist[2], ist[3], ist[4] = head, count, bn, hc, walking
    fst[0], fst[1], fst[2] = bsum, freq, rbest


@dataclass
class CadenceState:
    """Ring buffer and counters of :func:`cadence_kernel` (JSON-able with ``to_dict``)."""

    buf: FloatArray
    ints: IntArray = field(default_factory=lambda: np.zeros(5, dtype=np.int64))
    floats: FloatArray = field(default_factory=lambda: np.array([0.0, np.nan, -1.0]))

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON-able values (NaN written as None)."""
        return {"buf": self.buf.tolist(), "ints": self.ints.tolist(),
                "floats": [None if not np.isfinite(v) else float(v) for v in self.floats]}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> CadenceState:
        """Inverse of :meth:`to_dict`."""
        try:
            return cls(np.asarray(data["buf"], dtype=np.float64),
                       np.asarray(data["ints"], dtype=np.int64),
                       np.array([np.nan if v is None else v for v in data["floats"]],
                                dtype=np.float64))
        except KeyError as exc:
            raise InputError(f"missing key {exc}", where="CadenceState",
                             expected="a dict written by to_dict()") from None


@dataclass(frozen=True, slots=True, eq=False)
class CadenceResult:
    """Per-sample output of :class:`CadenceDetector`.

    Attributes
    ----------
    periodic: 1 where the last evaluated window was periodic walking or running, else 0.
    frequency_hz: step frequency of that window, Hz (NaN when not periodic).
    r: best normalized autocorrelation of that window (-1 before the first evaluation).
    state: combined motion state (0 still, 1 walking, 2 running, as
        :mod:`hrtls.gait.motion_detector`); empty from :meth:`CadenceDetector.periodicity`.
    """

    periodic: IntArray
    frequency_hz: FloatArray
    r: FloatArray
    state: IntArray


class CadenceDetector:
    """Autocorrelation walking detector and step-frequency estimate (see module notes).

    Parameters
    ----------
    params: detector parameters.
    rate_hz: nominal sampling rate of the input, Hz (sizes the decimation and the window).
    """

    def __init__(self, params: CadenceParams | None = None, *, rate_hz: float = 100.0) -> None:
        self.params = params or CadenceParams()
        p = self.params
        for name in ("window_s", "hop_s", "decimated_rate_hz", "min_step_s", "max_step_s",
                     "r_threshold", "half_lag_ratio", "min_std_m_s2", "run_frequency_hz"):
            check_positive(getattr(p, name), name)
        check_positive(rate_hz, "rate_hz")
        self.rate_hz = float(rate_hz)
        dec = max(1, round(rate_hz / p.decimated_rate_hz))
        rate_dec = rate_hz / dec
        wn = max(8, round(p.window_s * rate_dec))
        lmin = max(2, int(np.floor(p.min_step_s * rate_dec)))
        lmax = min(wn - 3, int(np.ceil(p.max_step_s * rate_dec)))
        if lmax <= lmin or p.max_step_s >= p.window_s or p.min_step_s >= p.max_step_s:
            raise InputError(f"step periods {p.min_step_s}-{p.max_step_s} s in a "
                             f"{p.window_s} s window at {rate_dec:.1f} Hz",
                             where="CadenceParams",
                             expected="max_step_s well below window_s and above min_step_s")
        self._ipars = np.array([dec, wn, lmin, lmax, max(1, round(p.hop_s * rate_dec))],
                               dtype=np.int64)
        self._fpars = np.array([p.r_threshold, p.half_lag_ratio, p.min_std_m_s2, rate_dec,
                                0.0, 0.0, p.run_frequency_hz])
        self.reset()

    def reset(self) -> None:
        """Empty window, not walking."""
        self.state = CadenceState(np.zeros(int(self._ipars[1])))

    def to_dict(self) -> dict[str, Any]:
        """The savable state."""
        return self.state.to_dict()

    def from_dict(self, data: dict[str, Any]) -> None:
        """Restore a state written by :meth:`to_dict`."""
        st = CadenceState.from_dict(data)
        if st.buf.shape != (int(self._ipars[1]),) or st.ints.shape != (5,):
            raise InputError(f"buffer of {st.buf.shape[0]} samples", where="CadenceState",
                             expected=f"{int(self._ipars[1])} samples (same parameters)")
        self.state = st

    def periodicity(self, a_vertical_m_s2: FloatArray) -> tuple[IntArray, FloatArray, FloatArray]:
        """Run the kernel over a chunk: (periodic flag, step frequency Hz, r) per sample."""
        res = self._run(as_vector(a_vertical_m_s2, where="cadence vertical acceleration"),
                        np.zeros(0), 0.0, 0.0)
        return res.periodic, res.frequency_hz, res.r

    def _run(self, x: FloatArray, sigma: FloatArray, still: float, run: float) -> CadenceResult:
        n = x.shape[0]
        walk = np.empty(n, dtype=np.int64)
        freq = np.empty(n)
        r = np.empty(n)
        state = np.zeros(n if sigma.shape[0] == n else 0, dtype=np.int64)
        pars = self._fpars.copy()
        pars[4] = still
        pars[5] = run
        s = self.state
        cadence_kernel(x, sigma, self._ipars, pars, s.buf, s.ints, s.floats, walk, freq, r,
                       state)
        return CadenceResult(walk, freq, r, state)

    def update(self, a_vertical_m_s2: FloatArray, sigma_m_s2: FloatArray, *,
               still_threshold_m_s2: float, run_threshold_m_s2: float) -> CadenceResult:
        """Periodicity of a chunk combined with the Basso spread ``sigma_m_s2`` (same samples).

        Moving when the spread exceeds ``still_threshold_m_s2`` (Basso) or the window is
        periodic; running when the spread exceeds ``run_threshold_m_s2`` and the step frequency
        (when periodic) is at least ``run_frequency_hz``.
        """
        x = as_vector(a_vertical_m_s2, where="cadence vertical acceleration")
        sig = as_vector(sigma_m_s2, where="motion sigma", length=x.shape[0])
        return self._run(x, sig, float(still_threshold_m_s2), float(run_threshold_m_s2))


__all__ = ["CadenceDetector", "CadenceParams", "CadenceResult", "CadenceState",
           "cadence_kernel"]
