"""Walking direction by the Fourier tip-to-tail method (Basso Sec. III, Algorithm 1).

At the end ``t_k`` of each step, the horizontal acceleration over the last stride
``(t_{k-2}, t_k]`` (period ``T_k = t_k - t_{k-2}``) is approximated by its second-order Fourier
series without the constant term,

    a2(t) = sum_{n=1,2} alpha_n cos(2 pi n t / T_k) + beta_n sin(2 pi n t / T_k),
    alpha_n = 2/T_k int a(t) cos(2 pi n t / T_k) dt,  beta_n likewise with sin

(integrals by the rectangle rule over the samples, ``t`` counted from ``t_{k-2}``). On the last
step ``(t_{k-1}, t_k]`` the two largest local maxima of ``|a2|`` give the tip (acceleration) and
the tail (deceleration) (maxima are searched cyclically over the stride, so a step boundary is
never taken for a maximum; a step with fewer than two maxima is too irregular and gets no
direction); the step direction is
``theta_k = atan2(a2_y(tip) - a2_y(tail), a2_x(tip) - a2_x(tail))`` and the heading is the
circular mean of ``theta_k`` and ``theta_{k-1}`` (A-HE).

Which of the two maxima is the tip: Basso says the tip is the "starting forward acceleration
followed by the related deceleration", with steps delimited at the peaks of ``a_z`` in NED
(z down), i.e. at the *minima* of the upward acceleration (mid-stance). hrtls delimits steps at
the peaks of the upward acceleration just after heel strike (the peak / zero-crossing detector
and the PLL both lock there), which shifts the step window by half a step: inside it the
deceleration comes first and the forward acceleration second. Measured on the mobgap lab data:
the AP acceleration minimum is ~0.1 s after the initial contact and its maximum ~0.15 s before
the next one. So by default the tip is the later maximum (``tip_is_second=True``), which is
Basso's order on Basso's step window.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from hrtls.gait._state import FloatArray, as_matrix, as_time, as_vector, check_positive
from hrtls.kernels import njit

TWO_PI = 2.0 * np.pi


@dataclass(frozen=True, kw_only=True, slots=True)
class FourierHeadingParams:
    """Parameters of the tip-to-tail heading.

    Attributes
    ----------
    grid_points: evaluation points of ``|a2|`` over the stride (half fall in the last step).
    max_stride_s: longest stride accepted; a longer one (a pause) gives no heading, s.
    tip_is_second: the later of the two maxima is the tip (see module notes).
    """

    grid_points: int = 64
    max_stride_s: float = 3.0
    tip_is_second: bool = True


@njit(cache=True)
def fourier_heading_kernel(t: FloatArray, a: FloatArray, ends: FloatArray, pars: FloatArray,
                           theta: FloatArray) -> None:  # pragma: no cover
    """Step directions ``theta[k]`` (NaN when undefined) for step ends ``ends[k]``, k >= 2.

    ``pars = [grid_points, max_stride_s, tip_is_second]``; ``theta[0:2]`` must be preset.
    """
    m = int(pars[0])
    max_stride = pars[1]
    tip_second = pars[2] > 0.5
    gx = np.empty(m)
    gy = np.empty(m)
    mag = np.empty(m)
    for k in range(2, ends.shape[0]):
        theta[k] = np.nan
        t0 = ends[k - 2]
        t1 = ends[k - 1]
        t2 = ends[k]
        big_t = t2 - t0
        if big_t <= 0.0 or big_t > max_stride or t1 <= t0 or t2 <= t1:
            continue
        i0 = np.searchsorted(t, t0, side="right")
        i1 = np.searchsorted(t, t2, side="right")
        if i1 - i0 < 8 or i0 == 0:
            continue
        # mean (unbiased series) over the stride
        mx = 0.0
        my = 0.0
        wsum = 0.0
        for i in range(i0, i1):
            dt = t[i] - t[i - 1]
            mx += a[i, 0] * dt
            my += a[i, 1] * dt
            wsum += dt
        mx /= wsum
        my /= wsum
        ax1 = 0.0
        bx1 = 0.0
        ax2 = 0.0
        bx2 = 0.0
        ay1 = 0.0
        by1 = 0.0
        ay2 = 0.0
        by2 = 0.0
        w = TWO_PI / big_t
        for i in range(i0, i1):
            dt = t[i] - t[i - 1]
            ph = w * (t[i] - t0)
            c1 = np.cos(ph)
            s1 = np.sin(ph)
            c2 = c1 * c1 - s1 * s1
            s2 = 2.0 * s1 * c1
            x = (a[i, 0] - mx) * dt
            y = (a[i, 1] - my) * dt
            ax1 += x * c1
            bx1 += x * s1
            ax2 += x * c2
            bx2 += x * s2
            ay1 += y * c1
            by1 += y * s1
            ay2 += y * c2
            by2 += y * s2
        sc = 2.0 / big_t
        # evaluate |a2| over the whole stride on a uniform grid (angle-addition recurrence);
        # the series is periodic, so local maxima are found cyclically and only those inside
        # the last step (t1, t2] are candidates
        dph = TWO_PI / m
        cd = np.cos(dph)
        sd = np.sin(dph)
        c1 = 1.0
        s1 = 0.0
        for j in range(m):
            c1, s1 = c1 * cd - s1 * sd, s1 * cd + c1 * sd
            c2 = c1 * c1 - s1 * s1
            s2 = 2.0 * s1 * c1
            gx[j] = sc * (ax1 * c1 + bx1 * s1 + ax2 * c2 + bx2 * s2)
            gy[j] = sc * (ay1 * c1 + by1 * s1 + ay2 * c2 + by2 * s2)
            mag[j] = gx[j] * gx[j] + gy[j] * gy[j]
        j_first = int(np.ceil((t1 - t0) / big_t * m - 1e-9)) - 1  # grid point j is at (j+1)/m
        best1 = -1
        best2 = -1
        for j in range(max(j_first, 0), m):
            left = mag[j - 1] if j > 0 else mag[m - 1]
            right = mag[j + 1] if j < m - 1 else mag[0]
            if mag[j] >= left and mag[j] > right:
                if best1 < 0 or mag[j] > mag[best1]:
                    best2 = best1
                    best1 = j
                elif best2 < 0 or mag[j] > mag[best2]:
                    best2 = j
        if best1 < 0 or best2 < 0:
            continue
        first = best1 if best1 < best2 else best2
        second = best2 if best1 < best2 else best1
        tip = second if tip_second else first
        tail = first if tip_second else second
        theta[k] = np.arctan2(gy[tip] - gy[tail], gx[tip] - gx[tail])


@dataclass(frozen=True, slots=True, eq=False)
class HeadingResult:
    """Per-step headings.

    Attributes
    ----------
    t_end: step ends, s.
    step_direction_rad: ``theta_k`` of one step (NaN when undefined), rad.
    heading_rad: A-HE, the circular mean of the last two ``theta`` (NaN when undefined), rad.
    """

    t_end: FloatArray
    step_direction_rad: FloatArray
    heading_rad: FloatArray


def average_two(theta: FloatArray, previous: float) -> FloatArray:
    """Circular mean of each ``theta[k]`` with ``theta[k-1]`` (``previous`` before the first).

    NaN when either is undefined: a single step direction is biased to its side by the
    pelvis rotation (Basso Sec. III), so it is not used alone.
    """
    prev = np.concatenate([[previous], theta[:-1]])
    out = np.arctan2(np.sin(theta) + np.sin(prev), np.cos(theta) + np.cos(prev))
    return np.asarray(out, dtype=np.float64)


@dataclass
class FourierHeadingState:
    """Buffered samples of the last stride, the last two step ends and the last direction."""

    t: FloatArray = field(default_factory=lambda: np.zeros(0))
    a: FloatArray = field(default_factory=lambda: np.zeros((0, 2)))
    ends: FloatArray = field(default_factory=lambda: np.zeros(0))
    last_theta: float = float("nan")

    def to_dict(self) -> dict[str, Any]:
        """JSON-able (NaN written as None)."""
        return {"t": self.t.tolist(), "a": self.a.tolist(), "ends": self.ends.tolist(),
                "last_theta": None if not np.isfinite(self.last_theta) else self.last_theta}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> FourierHeadingState:
        """Inverse of :meth:`to_dict`."""
        lt = data.get("last_theta")
        return cls(np.asarray(data["t"], dtype=np.float64),
                   np.asarray(data["a"], dtype=np.float64).reshape(-1, 2),
                   np.asarray(data["ends"], dtype=np.float64),
                   float("nan") if lt is None else float(lt))


class FourierHeading:
    """Basso Algorithm 1: tip-to-tail walking direction from horizontal acceleration."""

    def __init__(self, params: FourierHeadingParams | None = None) -> None:
        self.params = params or FourierHeadingParams()
        p = self.params
        check_positive(p.max_stride_s, "max_stride_s")
        if p.grid_points < 8:
            from hrtls.errors import InputError

            raise InputError(f"grid_points = {p.grid_points}", where="grid_points",
                             expected=">= 8")
        self._pars = np.array([float(p.grid_points), p.max_stride_s,
                               1.0 if p.tip_is_second else 0.0])
        self.state = FourierHeadingState()

    def reset(self) -> None:
        """Forget buffered samples and steps."""
        self.state = FourierHeadingState()

    def update(self, t: FloatArray, a_horizontal_m_s2: FloatArray,
               step_ends: FloatArray) -> HeadingResult:
        """Headings of the steps ending in this chunk.

        Parameters
        ----------
        t: sample times of the chunk, s.
        a_horizontal_m_s2: horizontal acceleration (N, 2) in a levelled frame, m/s^2.
        step_ends: end times of the steps completed by this chunk, s (increasing, within
            the samples seen so far).
        """
        s = self.state
        after = float(s.t[-1]) if s.t.size else -np.inf
        tt = as_time(t, where="heading time", after=after)
        a = as_matrix(a_horizontal_m_s2, where="horizontal acceleration", columns=2,
                      length=tt.shape[0])
        new_ends = as_vector(step_ends, where="step ends")
        tb = np.concatenate([s.t, tt])
        ab = np.concatenate([s.a, a])
        ends = np.concatenate([s.ends, new_ends])
        theta = np.full(ends.shape[0], np.nan)
        fourier_heading_kernel(tb, ab, ends, self._pars, theta)
        k0 = s.ends.shape[0]
        th_new = theta[k0:]
        heading = average_two(th_new, s.last_theta) if th_new.size else np.zeros(0)
        if th_new.size:
            s.last_theta = float(th_new[-1])
        # keep the last two ends and the samples of the last stride window
        s.ends = ends[-2:].copy()
        keep_from = tb[-1] - self.params.max_stride_s - 0.1 if tb.size else 0.0
        if s.ends.size:
            keep_from = min(keep_from, float(s.ends[0]) - 0.05)
        sel = tb >= keep_from
        s.t = tb[sel].copy()
        s.a = ab[sel].copy()
        return HeadingResult(new_ends, th_new, heading)

    def process(self, t: FloatArray, a_horizontal_m_s2: FloatArray,
                step_ends: FloatArray) -> HeadingResult:
        """Whole recording (resets first)."""
        self.reset()
        return self.update(t, a_horizontal_m_s2, step_ends)
