"""Whole-session gait analysis: a :class:`~hrtls.gait.analyzer.GaitAnalyzer` over a session.

:func:`session_inputs` reads what the analyzer needs from a session, :func:`analyze_session`
runs it, and :func:`activity_windows` gives the activity features the analyzer computes (so
that training and classification see the same features).
"""

from __future__ import annotations

import numpy as np

from hrtls.data import Session
from hrtls.errors import DegradedInputWarning, InputError
from hrtls.gait._state import FloatArray
from hrtls.gait.activity_tree import TreeThresholds
from hrtls.gait.analyzer import GaitAnalyzer
from hrtls.gait.features import WindowFeatures
from hrtls.gait.gait_result import GaitResult

__all__ = ["activity_windows", "analyze_session", "session_inputs"]


def activity_windows(t: FloatArray, acc_d_m_s2: FloatArray, *, rate_hz: float,
                     q_nd: FloatArray | None = None, mounting_q_bd: FloatArray | None = None,
                     window_s: float = 2.0, cutoff_hz: float = 6.0,
                     anthropometric_nr: float = 1.0) -> WindowFeatures:
    """Activity features of a whole recording, computed by :class:`GaitAnalyzer` itself.

    Vertical from the levelled acceleration (plus g); AP and ML from the mounting rotation, or
    (mounting unknown) from the levelled horizontal acceleration turned into the Fourier walking
    direction; 5th-order Butterworth at ``cutoff_hz`` (Inderst Sec. 4.1); windows of
    ``window_s``. Training and classification therefore see the same features.
    """
    import warnings

    tree = TreeThresholds(anthropometric_nr=anthropometric_nr)
    ga = GaitAnalyzer(rate_hz=rate_hz, activity=tree, mounting_q_bd=mounting_q_bd,
                      activity_window_s=window_s, activity_cutoff_hz=cutoff_hz)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DegradedInputWarning)
        return ga.process(t, acc_d_m_s2, q_nd).features


def session_inputs(session: Session) -> tuple[FloatArray, FloatArray, FloatArray | None,
                                               FloatArray | None, float]:
    """Accelerometer times and samples, orientation on those times (or None), mounting, rate.

    The orientation stream, when present, is interpolated (slerp) onto the accelerometer times;
    samples outside its span use its first/last value.
    """
    if session.imu is None:
        raise InputError("session has no IMU", where="session",
                         expected="imu.csv with an accelerometer")
    t = session.imu.accel.t
    acc = session.imu.accel.values
    if t.shape[0] < 8:
        raise InputError(f"{t.shape[0]} accelerometer samples", where="imu.csv",
                         expected="at least 8 samples")
    rate = float(1.0 / np.median(np.diff(t)))
    q_nd = None
    if session.orientation is not None and len(session.orientation.t) >= 2:
        from scipy.spatial.transform import Slerp

        from hrtls.frames import quat_from_rotation, quat_to_rotation

        ot = session.orientation.t
        slerp = Slerp(ot, quat_to_rotation(session.orientation.q))
        q_nd = quat_from_rotation(slerp(np.clip(t, ot[0], ot[-1])))
    mount = session.meta.mounting_q_bd
    return t, acc, q_nd, None if mount is None else np.asarray(mount, dtype=np.float64), rate


def analyze_session(session: Session, **analyzer_kwargs: object) -> GaitResult:
    """Run a :class:`GaitAnalyzer` over a whole session.

    The mounting rotation and the user's step model (``meta.user.step_model``) come from the
    session unless given in ``analyzer_kwargs`` (keyword arguments of :class:`GaitAnalyzer`).
    """
    from hrtls.gait.step_length import step_model_from_dict

    t, acc, q_nd, mount, rate = session_inputs(session)
    kwargs: dict[str, object] = {"rate_hz": rate, "mounting_q_bd": mount}
    if session.meta.user.step_model:
        kwargs["step_model"] = step_model_from_dict(session.meta.user.step_model)
    kwargs.update(analyzer_kwargs)
    analyzer = GaitAnalyzer(**kwargs)  # type: ignore[arg-type]
    return analyzer.process(t, acc, q_nd)
