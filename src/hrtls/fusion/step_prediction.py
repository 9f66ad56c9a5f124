"""Step-and-heading prediction in 3-D with stairs (Inderst thesis Sec. 4.3.1, eq. 4.23-4.25).

Per detected step ``j`` the position moves by a displacement ``l_j`` that depends on the
recognized activity (eq. 4.23):

* standing still: ``l_j = 0`` and the covariance does not grow;
* walking / running / unknown: ``l_j = [L cos(phi), L sin(phi), dz]`` with the step length ``L``
  (e.g. Weinberg eq. 4.24, computed by :mod:`hrtls.gait`) and the step heading ``phi`` (the
  average heading over the step);
* upstairs / downstairs (eq. 4.25): ``l_j = [rho cos(phi), rho sin(phi), +-zeta]`` with the stair
  depth ``rho`` and riser height ``zeta``; with ``stairs_from_model=False`` the measured step
  length and height change of the step are used instead.

Covariance (eq. 4.23, ``P+ = P + Q_j`` with ``Q_j = l_j Q^p l_j^T``): we read ``Q^p`` as a
dimensionless 3x3 matrix expressed in the frame of the step (along, across, vertical) and scale it
by the squared step size, ``Q_j = |l_j|^2 R(phi) Q^p R(phi)^T``, so that the uncertainty grows with
the distance walked and not with time. The heading uncertainty enters through the Jacobian of the
displacement with respect to the heading (``F = I + d l_j / d heading``), as in Colombo eq. 17.

Heading handling (``heading_mode``):

* ``"input"`` (the papers): the step heading is a parameter taken from the attitude filter; the
  state heading is set to it with the given variance, and its cross-covariances are cleared.
* ``"state"``: the *change* of the input heading since the previous step is added to the state
  heading (variance grows by ``sigma_heading_increment_rad^2`` per step). Heading corrections
  (tag bearings, position fixes through the cross-covariance) then persist for later steps.
  The first input heading only sets the reference, unless the state heading is less certain
  than the input (e.g. an unknown start heading): then the state adopts it. Our addition: the
  reference is the mean over the first stride. A single step's heading carries half the pelvis
  sway, and the first step after standing (gait initiation) carries it unbalanced; so the second
  step adds only half its change, unless the two steps turn by more than
  ``FIRST_STRIDE_MAX_TURN_RAD`` (a start into a turn). Measured on ``hrtls bench papers``
  (ten seeds): Basso tests 1-6 0.87/0.87/0.70/1.01/0.93/0.41 % -> 0.72/0.68/0.53/0.80/0.81/0.39 %.

One step is the compiled :func:`predict_step` on plain arrays and a
:data:`STEP_PREDICTION_DTYPE` record; :meth:`StepPredictor.predict` validates its inputs and
calls it, and so does the tracker's event loop.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np

from hrtls.data.results import Activity, StepEvents
from hrtls.errors import InputError
from hrtls.fusion._checks import FloatArray, finite_scalar
from hrtls.fusion._records import to_record
from hrtls.fusion.gating import symmetrize_in_place, wrap_rad
from hrtls.fusion.state import IH, N_STATE, FilterState
from hrtls.kernels import njit

HeadingMode = Literal["input", "state"]
FIRST_STRIDE_MAX_TURN_RAD = float(np.deg2rad(10.0))
"""The first two step headings are averaged into the reference only when they differ by less."""


@dataclass(frozen=True, kw_only=True)
class StepPredictionParams:
    """Parameters of the step-and-heading prediction.

    Attributes
    ----------
    q_along:
        Variance of the along-track error per squared step size (``Q^p`` (1,1)); 0.01 means a
        10 % 1-sigma step-length error.
    q_across:
        Same across the track (lateral sway of the step).
    q_vertical:
        Same on the vertical axis.
    stair_depth_m:
        ``rho`` of eq. 4.25, horizontal advance per stair step, m.
    stair_height_m:
        ``zeta`` of eq. 4.25, height change per stair step, m.
    stairs_from_model:
        Use ``rho``/``zeta`` on stairs (eq. 4.25); False uses the step's own length and dz.
    heading_mode:
        ``"input"`` or ``"state"`` (see the module docstring).
    sigma_heading_rad:
        1-sigma of the input heading when the caller gives no variance.
    sigma_heading_increment_rad:
        Heading random walk per step in ``"state"`` mode.
    """

    q_along: float = 0.01
    q_across: float = 0.0025
    q_vertical: float = 0.0025
    stair_depth_m: float = 0.30
    stair_height_m: float = 0.17
    stairs_from_model: bool = True
    heading_mode: HeadingMode = "input"
    sigma_heading_rad: float = 0.05
    sigma_heading_increment_rad: float = 0.02

    def __post_init__(self) -> None:
        for name in ("q_along", "q_across", "q_vertical", "sigma_heading_rad",
                     "sigma_heading_increment_rad"):
            finite_scalar(getattr(self, name), where=f"StepPredictionParams.{name}",
                          non_negative=True)
        for name in ("stair_depth_m", "stair_height_m"):
            finite_scalar(getattr(self, name), where=f"StepPredictionParams.{name}",
                          positive=True)
        if self.heading_mode not in ("input", "state"):
            raise InputError(f"heading_mode {self.heading_mode!r}",
                             where="StepPredictionParams.heading_mode",
                             expected="'input' or 'state'")

    def record(self) -> np.ndarray:
        """The parameters as a one-element :data:`STEP_PREDICTION_DTYPE` array."""
        return to_record(STEP_PREDICTION_DTYPE, self,
                         heading_from_state=self.heading_mode == "state")


@dataclass(frozen=True, slots=True, eq=False)
class StepPredictionResult:
    """States after each step.

    Attributes
    ----------
    t: step end times, s (N,).
    xyz: positions, m (N, 3).
    heading_rad: state heading, rad (N,).
    P: covariances (N, 4, 4).
    state: state after the last step.
    """

    t: FloatArray
    xyz: FloatArray
    heading_rad: FloatArray
    P: FloatArray
    state: FilterState


STEP_PREDICTION_DTYPE = np.dtype([
    ("q_along", np.float64), ("q_across", np.float64), ("q_vertical", np.float64),
    ("stair_depth_m", np.float64), ("stair_height_m", np.float64),
    ("stairs_from_model", np.bool_), ("heading_from_state", np.bool_),
    ("sigma_heading_rad", np.float64), ("sigma_heading_increment_rad", np.float64)])
"""Record of :class:`StepPredictionParams` for compiled code (``heading_from_state``:
``heading_mode == "state"``)."""

_STANDING, _UPSTAIRS, _DOWNSTAIRS = (int(Activity.STANDING), int(Activity.UPSTAIRS),
                                     int(Activity.DOWNSTAIRS))


@njit(cache=True, error_model="numpy")
def predict_step(prm: np.record, x: FloatArray, p: FloatArray, input_heading_rad: float,
                 has_input_heading: bool, reference_pending: bool, length_m: float,
                 heading_rad: float, dz_m: float, activity: int, var_heading_rad2: float
                 ) -> tuple[float, bool, bool]:  # pragma: no cover - compiled
    """One step of eq. 4.23-4.25 on plain arrays, in place (see the module docstring).

    ``prm`` is a :data:`STEP_PREDICTION_DTYPE` record; ``x`` (4,) and ``p`` (4, 4) the state;
    ``input_heading_rad``, ``has_input_heading``, ``reference_pending`` the heading input
    memory of :class:`~hrtls.fusion.state.FilterState`. ``heading_rad``
    NaN: unknown (the state heading is used); ``var_heading_rad2`` NaN: ``sigma_heading_rad^2``.
    Returns the new ``(input_heading_rad, has_input_heading, reference_pending)``.

    The covariance is ``P+ = F P F^T + R(phi) Qf R(phi)^T`` with ``F = I`` except
    ``F[0:2, 3] = d(l_xy)/d(heading)`` and ``Qf = |l_j|^2 diag(q_along, q_across, q_vertical)``
    (eq. 4.23 with the Jacobian of Colombo eq. 17), expanded in place.
    """
    var_h = prm.sigma_heading_rad ** 2 if not np.isfinite(var_heading_rad2) \
        else var_heading_rad2
    pending = reference_pending
    if np.isfinite(heading_rad):
        h_in = wrap_rad(heading_rad)
        if not prm.heading_from_state:
            x[3] = h_in
            for i in range(4):
                p[3, i] = 0.0
                p[i, 3] = 0.0
            p[3, 3] = var_h
        elif has_input_heading:
            inc = wrap_rad(h_in - input_heading_rad)
            if reference_pending and abs(inc) < FIRST_STRIDE_MAX_TURN_RAD:
                inc *= 0.5   # reference = mean of the first two step headings
            x[3] = wrap_rad(x[3] + inc)
            p[3, 3] += prm.sigma_heading_increment_rad ** 2
        elif p[3, 3] > var_h:
            # first input, and it knows the heading better than the state: adopt it
            x[3] = h_in
            for i in range(4):
                p[3, i] = 0.0
                p[i, 3] = 0.0
            p[3, 3] = var_h
        pending = not has_input_heading
        input_heading_rad = h_in
        has_input_heading = True
    x[3] = wrap_rad(x[3])
    if activity == _STANDING:
        # eq. 4.23 with l_j = 0: nothing moves, nothing grows
        return input_heading_rad, has_input_heading, pending
    if activity in (_UPSTAIRS, _DOWNSTAIRS) and prm.stairs_from_model:
        horiz = prm.stair_depth_m
        vert = prm.stair_height_m if activity == _UPSTAIRS else -prm.stair_height_m
    else:
        horiz = length_m
        vert = dz_m
    c = math.cos(x[3])
    s = math.sin(x[3])
    size2 = horiz * horiz + vert * vert
    qa = size2 * prm.q_along
    qc = size2 * prm.q_across
    qv = size2 * prm.q_vertical
    # F P F^T with F = I + f0 e0 e3^T + f1 e1 e3^T
    f0 = -horiz * s
    f1 = horiz * c
    for j in range(4):
        p[0, j] += f0 * p[3, j]
        p[1, j] += f1 * p[3, j]
    for i in range(4):
        p[i, 0] += f0 * p[i, 3]
        p[i, 1] += f1 * p[i, 3]
    # + R diag(qa, qc, qv) R^T
    p[0, 0] += c * c * qa + s * s * qc
    p[0, 1] += c * s * qa - s * c * qc
    p[1, 0] += s * c * qa - c * s * qc
    p[1, 1] += s * s * qa + c * c * qc
    p[2, 2] += qv
    symmetrize_in_place(p)
    x[0] += horiz * c
    x[1] += horiz * s
    x[2] += vert
    return input_heading_rad, has_input_heading, pending


class StepPredictor:
    """Inderst eq. 4.23-4.25 step-and-heading prediction of a :class:`FilterState`."""

    def __init__(self, params: StepPredictionParams | None = None) -> None:
        self.params = params or StepPredictionParams()
        self._record: tuple[StepPredictionParams, np.ndarray] | None = None

    def predict(self, state: FilterState, *, t: float, length_m: float, heading_rad: float,
                dz_m: float = 0.0, activity: int = int(Activity.WALKING),
                var_heading_rad2: float | None = None) -> FilterState:
        """Apply one step ending at ``t``.

        Parameters
        ----------
        state:
            State before the step.
        t:
            Step end time, s (>= ``state.t``).
        length_m:
            Horizontal step length, m (>= 0).
        heading_rad:
            Walking direction of the step (rad, ENU CCW from east); NaN means unknown: the
            state heading is used.
        dz_m:
            Height change of the step, m (used off stairs, and on stairs when
            ``stairs_from_model`` is False).
        activity:
            :class:`~hrtls.data.results.Activity` code.
        var_heading_rad2:
            Variance of ``heading_rad``; default ``sigma_heading_rad^2``.
        """
        t = finite_scalar(t, where="step t")
        if t < state.t:
            raise InputError(f"step at {t} s is before the filter time {state.t} s",
                             where="step t", expected="steps in time order")
        length = finite_scalar(length_m, where="step length_m", non_negative=True)
        dz = finite_scalar(dz_m, where="step dz_m")
        act = int(activity)
        var_h = (math.nan if var_heading_rad2 is None
                 else finite_scalar(var_heading_rad2, where="step var_heading",
                                    non_negative=True))
        x = state.x.copy()
        p = state.P.copy()
        heading, has_input, pending = predict_step(
            self.record()[0], x, p, state.input_heading_rad, state.has_input_heading,
            state.reference_pending, length, float(heading_rad), dz, act, var_h)
        return FilterState(t, x, p, heading, has_input, pending)

    def record(self) -> np.ndarray:
        """:attr:`params` as a one-element :data:`STEP_PREDICTION_DTYPE` array."""
        if self._record is None or self._record[0] is not self.params:
            self._record = (self.params, self.params.record())
        return self._record[1]

    def run(self, state: FilterState, steps: StepEvents,
            var_heading_rad2: FloatArray | float | None = None) -> StepPredictionResult:
        """Apply all steps in order (each at its ``t_end``)."""
        n = len(steps)
        var_h: FloatArray | None = None
        if var_heading_rad2 is not None:
            var_h = np.broadcast_to(np.asarray(var_heading_rad2, dtype=np.float64), (n,))
        t_out = np.empty(n)
        xyz = np.empty((n, 3))
        head = np.empty(n)
        covs = np.empty((n, N_STATE, N_STATE))
        for i in range(n):
            state = self.predict(
                state, t=float(steps.t_end[i]), length_m=float(steps.length_m[i]),
                heading_rad=float(steps.heading_rad[i]), dz_m=float(steps.dz_m[i]),
                activity=int(steps.activity[i]),
                var_heading_rad2=None if var_h is None else float(var_h[i]))
            t_out[i] = state.t
            xyz[i] = state.x[:3]
            head[i] = state.x[IH]
            covs[i] = state.P
        return StepPredictionResult(t_out, xyz, head, covs, state)
