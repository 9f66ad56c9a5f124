"""Pass-through of an orientation the device computed itself (Basso et al. 2017, Sec. II-A).

Phones run their own AHRS and report the device attitude (Android rotation vector, Sensor Logger
``Orientation.csv``, IPIN ``AHRS`` lines). Basso uses that attitude to project the device-frame
measurements into a fixed ground frame (NED in the paper). Here the orientation arrives as an
:class:`~hrtls.data.OrientationSeries` ``q_nd`` whose reference frame the reader already turned
into ENU; :func:`frame_to_enu` does that conversion for readers (from NED or NWU references).
The method only converts frames, applies the mounting ``q_bd`` and resamples onto the requested
times (spherical linear interpolation; held constant outside the recorded span, where ``valid``
is False).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar, Literal

import numpy as np
from numpy.typing import ArrayLike

from hrtls.attitude import _kernels as K
from hrtls.attitude.base import AttitudeResult
from hrtls.data import OrientationSeries
from hrtls.errors import InputError
from hrtls.frames import (
    FloatArray,
    as_quat_array,
    quat_conjugate,
    quat_from_rotation,
    quat_multiply,
    quat_normalize,
    quat_rotate,
    quat_to_rotation,
)

__all__ = ["DeviceOrientation", "DeviceParams", "frame_to_enu", "rotate_to_navigation"]

_S = float(np.sqrt(0.5))
# q_{ENU <- frame}: rotations taking vectors of the named reference frame into ENU
_TO_ENU = {
    "enu": np.array([1.0, 0.0, 0.0, 0.0]),
    # NED: x north, y east, z down -> [[0,1,0],[1,0,0],[0,0,-1]]
    "ned": np.array([0.0, _S, _S, 0.0]),
    # NWU: x north, y west, z up -> +90 deg about z
    "nwu": np.array([_S, 0.0, 0.0, _S]),
}

ReferenceFrame = Literal["enu", "ned", "nwu"]


def frame_to_enu(q: ArrayLike, frame: ReferenceFrame) -> FloatArray:
    """Convert device orientations given w.r.t. ``frame`` (ENU, NED or NWU) into ``q_nd`` (ENU).

    ``q`` rotates device vectors into ``frame``; the result rotates them into ENU.
    """
    if frame not in _TO_ENU:
        raise InputError(f"reference frame {frame!r}", where="frame_to_enu",
                         expected="'enu', 'ned' or 'nwu'")
    return quat_normalize(quat_multiply(_TO_ENU[frame], as_quat_array(q)))


def rotate_to_navigation(q_nd: ArrayLike, vectors: ArrayLike) -> FloatArray:
    """Project device-frame vectors (N, 3) into ENU with the attitudes ``q_nd`` (N, 4)."""
    return quat_rotate(as_quat_array(q_nd), np.asarray(vectors, dtype=np.float64))


@dataclass(frozen=True, kw_only=True)
class DeviceParams:
    """Parameters of the device-orientation pass-through.

    Attributes
    ----------
    reference_frame:
        Frame the input quaternions refer to (``"enu"`` when the reader already converted).
    mounting_q_bd:
        Device -> body rotation ``[w, x, y, z]``; when given the result is ``q_nb``.
    """

    reference_frame: ReferenceFrame = "enu"
    mounting_q_bd: tuple[float, float, float, float] | None = None

    def __post_init__(self) -> None:
        if self.reference_frame not in _TO_ENU:
            raise InputError(f"reference_frame = {self.reference_frame!r}",
                             where="DeviceParams", expected="'enu', 'ned' or 'nwu'")
        if self.mounting_q_bd is not None:
            q = np.asarray(self.mounting_q_bd, dtype=np.float64)
            if q.shape != (4,) or not np.all(np.isfinite(q)) or abs(np.linalg.norm(q) - 1) > 1e-6:
                raise InputError(f"mounting_q_bd = {self.mounting_q_bd}", where="DeviceParams",
                                 expected="a unit quaternion [w, x, y, z]")


class DeviceOrientation:
    """Use the device's own orientation as the attitude (method ``device``)."""

    name: ClassVar[str] = "device"
    params_type: ClassVar[type[DeviceParams]] = DeviceParams

    def __init__(self, params: DeviceParams | None = None) -> None:
        self.params = params if params is not None else DeviceParams()
        if not isinstance(self.params, DeviceParams):
            raise InputError(f"parameters of type {type(self.params).__name__}",
                             where=self.name, expected="DeviceParams")

    def _finish(self, t: FloatArray, q_nd: FloatArray, valid: np.ndarray) -> AttitudeResult:
        q = frame_to_enu(q_nd, self.params.reference_frame)
        frame = "nd"
        if self.params.mounting_q_bd is not None:
            q_bd = np.asarray(self.params.mounting_q_bd, dtype=np.float64)
            q = quat_normalize(quat_multiply(q, quat_conjugate(q_bd)))
            frame = "nb"
        flags = np.where(valid, K.FLAG_VALID, 0).astype(np.uint8)
        return AttitudeResult(t=t, q=q, frame=frame, var_rpy=None, flags=flags,
                              rejected={"acc": 0, "mag": 0, "gyro": 0, "bad": 0})

    def update(self, t: ArrayLike, q: ArrayLike) -> AttitudeResult:
        """Convert one chunk of device orientations (times in s, quaternions (N, 4))."""
        series = OrientationSeries(np.asarray(t, dtype=np.float64),
                                   np.asarray(q, dtype=np.float64), name="device orientation")
        return self._finish(series.t, series.q, np.ones(len(series.t), dtype=bool))

    def run(self, orientation: OrientationSeries, t: ArrayLike | None = None) -> AttitudeResult:
        """The orientation series, optionally resampled onto times ``t`` (e.g. the IMU's)."""
        if t is None:
            return self._finish(orientation.t, orientation.q,
                                np.ones(len(orientation.t), dtype=bool))
        tq = np.asarray(t, dtype=np.float64)
        if tq.ndim != 1 or not np.all(np.isfinite(tq)):
            raise InputError("times must be a finite 1-D array", where="device orientation t",
                             expected="(N,) finite times in s")
        if len(orientation.t) < 2:
            q = np.tile(orientation.q[0], (len(tq), 1))
            return self._finish(tq, q, np.abs(tq - orientation.t[0]) < 1e-9)
        valid = (tq >= orientation.t[0]) & (tq <= orientation.t[-1])
        clipped = np.clip(tq, orientation.t[0], orientation.t[-1])
        from scipy.spatial.transform import Slerp  # slow to import: only when used

        slerp = Slerp(orientation.t, quat_to_rotation(orientation.q))
        return self._finish(tq, quat_from_rotation(slerp(clipped)), valid)
