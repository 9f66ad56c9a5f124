"""Stairs from the waist's vertical climb per step (no barometer, no classifier).

The levelled vertical acceleration ``a`` (gravity removed, up positive) is integrated twice,
causally, one sample at a time (:func:`climb_height_kernel`):

* ``b_k = b_{k-1} + g_k (a_k - b_{k-1})``: the accelerometer's vertical bias, a running mean
  (``g_k = max(dt / elapsed, 1 - exp(-dt / bias_s))``: the plain mean over the first
  ``bias_s``, then a first-order low-pass);
* ``v_k = exp(-dt / leak_s) v_{k-1} + (a_k - b_k) dt``: vertical velocity, with a slow leak that
  bounds the drift of an uncorrected integral;
* ``h_k = h_{k-1} + v_k dt``: height, relative (only its change over a step is used).

A step's mean vertical velocity is ``u = (h(t_end) - h(t_start)) / T``: the body's vertical
oscillation has the step's period, so it cancels between two heel strikes and ``u`` keeps the
mean climb (a riser per step on stairs, none on a floor). What is left of the integration drift
varies slowly, and is removed by a *baseline* ``beta`` (:func:`climb_labels_kernel`): a
first-order low-pass of ``u`` over the steps, with time constant ``baseline_s``, started at
the first walking step (again after ``rest_s`` without a step: the person stood or sat, and
the integral drifted or moved with them). The climb of a step is ``c = (u - beta) T``:

* a walking step is upstairs when ``c > threshold_m``, downstairs when ``c < -threshold_m``
  (a stair rise is 0.15-0.18 m); the baseline is not updated on such steps (a flight), for
  at most ``max_flight_s``;
* steps longer than ``max_step_s`` are left out (shuffling, turning on the spot, standing up);
  steps that are not walking are never stairs, and update the baseline unless they climb more
  than twice ``threshold_m`` (standing up from a chair, sitting down);
* a flight does not turn round: a step that climbs against the last stair step, within
  ``settle_s`` of its end, is labelled walking and restarts the baseline at its ``u`` (the
  attitude's errors on a flight, e.g. a filter levelled by the accelerometer while the body
  accelerates, leave some velocity in the integral, which shows as a climb the other way once
  the flight ends).

The vertical velocity at a flight's start and end changes by the climb rate (0.3 m/s on
stairs taken at 0.55 m/s): that change is what the accelerometer sees. The flight rule
(:mod:`hrtls.fusion.floors`) turns the stair steps into floors.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from hrtls.data import Activity
from hrtls.errors import InputError
from hrtls.gait._state import FloatArray
from hrtls.gait.analyzer_state import PendingGait
from hrtls.gait.pll import StepDetection
from hrtls.kernels import njit

__all__ = ["CLIMB_STATE", "ClimbParams", "climb_heights", "climb_labels"]

CLIMB_STATE = ("t_last", "elapsed_s", "bias_m_s2", "velocity_m_s", "height_m", "baseline_m_s",
               "flight_s", "direction", "stair_end_s", "step_end_s")
"""The detector's state: last sample time (NaN before the first), time integrated, vertical
bias, velocity and relative height (:func:`climb_height_kernel`); the steps' baseline vertical
velocity (NaN before the first step), the time since the flight started, the direction of
the last stair step (+1 up, -1 down, 0 none yet) and its end time, the last step's end
(:func:`climb_labels_kernel`). Kept in ``PendingGait.climb``."""


@dataclass(frozen=True, kw_only=True, slots=True)
class ClimbParams:
    """Parameters of the climb-per-step stairs detector (module notes).

    Attributes
    ----------
    threshold_m: climb of a step, relative to the baseline, beyond which it is a stair step, m.
    baseline_s: time constant of the baseline vertical velocity, s.
    max_flight_s: longest flight; after it the baseline follows again, s.
    bias_s: time constant of the running mean of the vertical acceleration (its bias), s.
    leak_s: time constant of the leak of the integrated vertical velocity, s.
    max_gap_s: a longer gap between samples restarts the velocity at zero, s.
    settle_s: a climb against the last stair step within this time after it is drift, s.
    rest_s: after a pause between steps longer than this the baseline starts again, s.
    max_step_s: longest stair step; longer steps (shuffling, turning on the spot, standing up)
        are neither stairs nor part of the baseline, s.
    """

    threshold_m: float = 0.07
    baseline_s: float = 2.0
    max_flight_s: float = 20.0
    bias_s: float = 20.0
    leak_s: float = 60.0
    max_gap_s: float = 0.5
    settle_s: float = 5.0
    rest_s: float = 3.0
    max_step_s: float = 0.9

    def __post_init__(self) -> None:
        for name in ("threshold_m", "baseline_s", "max_flight_s", "bias_s", "leak_s",
                     "max_gap_s", "settle_s", "rest_s", "max_step_s"):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
                raise InputError(f"{value!r}", where=f"ClimbParams.{name}",
                                 expected="a finite number > 0")


@njit(cache=True, error_model="numpy")
def climb_height_kernel(t: FloatArray, a: FloatArray, st: FloatArray, bias_s: float,
                        leak_s: float, max_gap_s: float,
                        h_out: FloatArray) -> None:  # pragma: no cover - compiled
    """Bias, velocity and height (module notes) of each sample; ``st`` updated in place."""
    for i in range(t.shape[0]):
        if not math.isfinite(st[0]):
            st[2] = a[i]
            dt = 0.0
        else:
            dt = t[i] - st[0]
        st[0] = t[i]
        if dt > max_gap_s:
            st[3] = 0.0                 # a gap: the velocity is unknown, start at rest
        elif dt > 0.0:
            st[1] += dt
            st[2] += max(dt / st[1], 1.0 - math.exp(-dt / bias_s)) * (a[i] - st[2])
            st[3] = math.exp(-dt / leak_s) * st[3] + (a[i] - st[2]) * dt
            st[4] += st[3] * dt
        h_out[i] = st[4]


@njit(cache=True, error_model="numpy")
def climb_labels_kernel(t_start: FloatArray, t_end: FloatArray, dh_m: FloatArray,
                        act: FloatArray, st: FloatArray, threshold_m: float, baseline_s: float,
                        max_flight_s: float, settle_s: float, rest_s: float,
                        max_step_s: float, walking: float,
                        up: float, down: float) -> None:  # pragma: no cover - compiled
    """Stairs labels of the walking steps of ``act`` (in place), baseline ``st[5:10]``."""
    for k in range(act.shape[0]):
        dur = t_end[k] - t_start[k]
        if t_start[k] - st[9] > rest_s:
            st[5] = math.nan            # after a rest the baseline starts again
            st[6] = st[7] = 0.0
        st[9] = t_end[k]
        if not (0.0 < dur <= max_step_s and math.isfinite(dh_m[k])):
            continue                    # standing up, sitting down, shuffling: no stairs
        u = dh_m[k] / dur
        if act[k] != walking:
            # not a stair step; the baseline follows it unless it climbs twice a stair's
            if math.isfinite(st[5]) and abs(u - st[5]) * dur <= 2.0 * threshold_m:
                st[5] += (1.0 - math.exp(-dur / baseline_s)) * (u - st[5])
            continue
        if not math.isfinite(st[5]):
            st[5] = u
        c = (u - st[5]) * dur
        sign = 1.0 if c > threshold_m else -1.0 if c < -threshold_m else 0.0
        if sign != 0.0 and sign == -st[7] and t_end[k] - st[8] <= settle_s:
            st[5] = u                   # against the flight: drift, restart the baseline
            sign = 0.0
        if sign != 0.0:
            act[k] = up if sign > 0.0 else down
            st[7] = sign
            st[8] = t_end[k]
        if sign == 0.0 or st[6] > max_flight_s:
            st[5] += (1.0 - math.exp(-dur / baseline_s)) * (u - st[5])
        st[6] = st[6] + dur if sign != 0.0 else 0.0


def climb_heights(pend: PendingGait, vb_t: FloatArray, t: FloatArray, a: FloatArray,
                  det: StepDetection, params: ClimbParams | None) -> FloatArray:
    """Height change of each new step of ``det``, m (NaN: unknown, or detector off).

    Integrates the chunk ``t, a`` (a suffix of the buffer times ``vb_t``) and sets
    ``pend.vb_h``, the relative heights at ``vb_t`` (NaN where unknown).
    """
    old = pend.vb_h if pend.vb_h.shape[0] == vb_t.shape[0] - t.shape[0] else np.full(
        vb_t.shape[0] - t.shape[0], math.nan)
    h = np.full(t.shape[0], math.nan)
    if params is not None:
        climb_height_kernel(t, a, pend.climb, params.bias_s, params.leak_s, params.max_gap_s,
                            h)
    pend.vb_h = np.concatenate([old, h])
    if params is None or not len(det):
        return np.full(len(det), math.nan)
    inside = (det.t_start >= vb_t[0]) & (det.t_end <= vb_t[-1])
    dh = np.interp(det.t_end, vb_t, pend.vb_h) - np.interp(det.t_start, vb_t, pend.vb_h)
    return np.where(inside, dh, math.nan)


def climb_labels(act: np.ndarray, steps: StepDetection, dh_m: FloatArray, st: FloatArray,
                 params: ClimbParams | None) -> np.ndarray:
    """``act`` with the walking steps that climb labelled up/downstairs (``st`` updated)."""
    if params is None or not len(steps):
        return act
    out = act.astype(np.float64)
    climb_labels_kernel(steps.t_start, steps.t_end, np.asarray(dh_m, dtype=np.float64), out,
                        st, params.threshold_m, params.baseline_s, params.max_flight_s,
                        params.settle_s, params.rest_s, params.max_step_s,
                        float(Activity.WALKING), float(Activity.UPSTAIRS),
                        float(Activity.DOWNSTAIRS))
    return out.astype(np.int64)
