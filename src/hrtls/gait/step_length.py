"""Step length models.

* :class:`WeinbergModel`: ``l = K (a_max - a_min)^(1/4)`` with the extremes of vertical
  acceleration within the step (Tarrio eq. 3, Inderst eq. 4.24, where ``K`` is called ``beta``).
* :class:`FrequencyLawModel`: step length linear in step frequency, with one line for walking
  and one for running (Basso Sec. II-D, Fig. 4: a piecewise-linear law).
* :class:`~hrtls.gait.step_length_pendulum.PendulumModel`: inverted pendulum on the vertical
  excursion of the pelvis (its own module).
* :class:`StairsModel`: on stairs a step is one stair: horizontal ``rho`` (depth) and vertical
  ``+zeta`` up / ``-zeta`` down (Inderst eq. 4.25).

A standing window gives zero displacement (Inderst Sec. 4.3.1).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from hrtls.data import Activity
from hrtls.errors import InputError
from hrtls.gait._state import FloatArray, check_positive
from hrtls.gait.pll import StepDetection
from hrtls.gait.step_length_pendulum import PendulumModel


@dataclass(frozen=True, kw_only=True, slots=True)
class WeinbergModel:
    """Weinberg step length (Tarrio eq. 3, Inderst eq. 4.24).

    Attributes
    ----------
    k: user constant ``K`` (``beta``), m / (m/s^2)^(1/4).
    """

    k: float = 0.45

    def __post_init__(self) -> None:
        check_positive(self.k, "k")

    def lengths(self, steps: StepDetection) -> FloatArray:
        """Step lengths, m."""
        span = np.clip(steps.acc_max - steps.acc_min, 0.0, None)
        return np.asarray(self.k * np.sqrt(np.sqrt(span)), dtype=np.float64)

    def to_dict(self) -> dict[str, Any]:
        """User-profile form ``{"kind": "weinberg", "k": ...}``."""
        return {"kind": "weinberg", "k": self.k}


@dataclass(frozen=True, kw_only=True, slots=True)
class FrequencyLawModel:
    """Piecewise-linear step length vs step frequency (Basso Sec. II-D).

    Attributes
    ----------
    walk_slope_m_s, walk_intercept_m: ``SL = slope * f + intercept`` for walking (f in Hz).
    run_slope_m_s, run_intercept_m: the same for running.
    split_hz: frequencies at or above this use the running line (between Basso's walking
        range 1.5-2.2 Hz and running range 2.7-4.2 Hz).
    max_length_m: upper clip of the result, m (the result is also clipped at 0).
    """

    walk_slope_m_s: float = 0.35
    walk_intercept_m: float = 0.05
    run_slope_m_s: float = 0.25
    run_intercept_m: float = 0.30
    split_hz: float = 2.45
    max_length_m: float = 2.5

    def length_at(self, frequency_hz: ArrayLike) -> FloatArray:
        """Step length, m, at step frequencies (Hz)."""
        f = np.asarray(frequency_hz, dtype=np.float64)
        if np.any(~np.isfinite(f)):
            raise InputError("non-finite step frequency", where="frequency_hz",
                             expected="finite frequencies in Hz")
        sl = np.where(f < self.split_hz, self.walk_slope_m_s * f + self.walk_intercept_m,
                      self.run_slope_m_s * f + self.run_intercept_m)
        return np.asarray(np.clip(sl, 0.0, self.max_length_m), dtype=np.float64)

    def lengths(self, steps: StepDetection) -> FloatArray:
        """Step lengths, m, from each step's frequency ``1 / T_k``."""
        return self.length_at(steps.frequency_hz)

    def to_dict(self) -> dict[str, Any]:
        """User-profile form ``{"kind": "frequency", ...}``."""
        return {"kind": "frequency", **asdict(self)}


@dataclass(frozen=True, kw_only=True, slots=True)
class StairsModel:
    """Stairs displacement (Inderst eq. 4.25).

    Attributes
    ----------
    depth_m: horizontal depth ``rho`` of one stair, m.
    height_m: height ``zeta`` of one stair, m.
    """

    depth_m: float = 0.30
    height_m: float = 0.17

    def to_dict(self) -> dict[str, Any]:
        """JSON-able dict."""
        return asdict(self)


StepModel = WeinbergModel | FrequencyLawModel | PendulumModel


def step_model_from_dict(data: dict[str, Any]) -> StepModel:
    """Model from a user profile's ``step_model`` dict (kind weinberg, frequency, pendulum)."""
    d = dict(data)
    kind = d.pop("kind", None)
    try:
        if kind == "weinberg":
            return WeinbergModel(**d)
        if kind == "frequency":
            return FrequencyLawModel(**d)
        if kind == "pendulum":
            return PendulumModel(**d)
    except TypeError as exc:
        raise InputError(str(exc), where="step_model", expected="the model's keys") from None
    raise InputError(f"kind {kind!r}", where="step_model",
                     expected="'weinberg', 'frequency' or 'pendulum'")


def displacements(steps: StepDetection, activity: ArrayLike, model: StepModel,
                  stairs: StairsModel | None = None,
                  excursion_m: FloatArray | None = None) -> tuple[FloatArray, FloatArray]:
    """Horizontal length and height change of each step, m.

    Walking/running steps use ``model`` (a :class:`PendulumModel` needs ``excursion_m``, the
    vertical excursion of each step in m); upstairs/downstairs steps use ``stairs``
    (eq. 4.25); steps classified as standing get zero displacement.
    """
    act = np.asarray(activity, dtype=np.int64)
    if act.shape != (len(steps),):
        raise InputError(f"{act.shape} activity codes for {len(steps)} steps",
                         where="activity", expected="one code per step")
    st = stairs or StairsModel()
    if isinstance(model, PendulumModel):
        length = model.lengths(steps, excursion_m)
    else:
        length = model.lengths(steps)
    dz = np.zeros(len(steps))
    up = act == Activity.UPSTAIRS
    down = act == Activity.DOWNSTAIRS
    length = np.where(up | down, st.depth_m, length)
    dz[up] = st.height_m
    dz[down] = -st.height_m
    length = np.where(act == Activity.STANDING, 0.0, length)
    return np.asarray(length, dtype=np.float64), dz
