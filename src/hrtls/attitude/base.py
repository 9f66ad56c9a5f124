"""The common interface of the attitude filters: parameters, state, chunk update, result.

Frames. The sensors measure in the *device* frame ``d``. Every filter estimates ``q_nd``
(device -> ENU, see :mod:`hrtls.frames`). When the parameters carry a mounting rotation
``mounting_q_bd`` (device -> body), the result is converted to ``q_nb = q_nd * conj(q_bd)`` and
``AttitudeResult.frame`` is ``"nb"``; otherwise the device frame is taken as the body frame and
``frame`` is ``"nd"``.

Streaming. A filter object holds its state. :meth:`AttitudeFilter.update` consumes one chunk of
samples (any length) and returns the result for that chunk; :meth:`AttitudeFilter.run` resets and
processes a whole :class:`~hrtls.data.ImuStream` as one chunk, through the same compiled kernel.
Processing a recording in chunks gives the same numbers as processing it at once.

Bad samples. Sensor values may be NaN, inf or saturated: such a sample is rejected by the gates of
the sensor concerned and counted (``AttitudeResult.rejected``); no NaN ever leaves a filter.
Before the first usable accelerometer sample the filter is uninitialised: those outputs are the
identity quaternion with ``valid == False``.
"""

from __future__ import annotations

import warnings
from abc import ABC, abstractmethod
from dataclasses import dataclass, field, fields
from typing import Any, ClassVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hrtls.attitude import _kernels as K
from hrtls.data import ImuStream
from hrtls.errors import DegradedInputWarning, InputError
from hrtls.frames import (
    GRAVITY_M_S2,
    FloatArray,
    euler_from_quat,
    heading_from_quat,
    quat_conjugate,
    quat_multiply,
    quat_normalize,
)

__all__ = [
    "AttitudeFilter",
    "AttitudeResult",
    "AttitudeState",
    "CommonParams",
]


@dataclass(frozen=True, kw_only=True)
class CommonParams:
    """Parameters shared by the sensor-fusion filters (gates, ranges, gyro bias, mounting).

    Attributes
    ----------
    gravity_m_s2:
        Local gravity, m/s^2.
    acc_gate_m_s2:
        Accelerometer gate ``eps_a``: the accelerometer corrects only when
        ``| |a| - g | < eps_a`` (Inderst Sec. 4.2.1). ``inf`` disables the gate.
    mag_norm_gate_uT:
        Magnetometer norm gate ``eps_m``: ``| |m| - |d_m| | < eps_m`` (Inderst Sec. 4.2.1), uT.
    mag_dip_gate_rad:
        Dip-angle gate (our addition): the angle of the field below the horizon must stay within
        this of the reference dip, rad.
    mag_jump_gate_uT:
        Jump gate ``eps_dm``: ``|m_k - m_{k-1}| < eps_dm`` (Inderst Sec. 4.2.1), uT per sample.
    mag_new_field_s:
        A different field that stays stable this long becomes the new reference, s (``inf``:
        never).
    mag_ref_norm_uT, mag_ref_dip_rad:
        Reference field norm (uT) and dip (rad, positive below the horizon); ``None`` learns them
        from the first magnetometer sample.
    gyro_range_rad_s:
        Gyro samples with any axis at or above this rate are treated as saturated, rad/s.
    acc_range_m_s2:
        Accelerometer samples with a norm at or above this are treated as saturated, m/s^2.
    max_dt_s:
        Sample gaps longer than this are not integrated (the attitude is held), s.
    estimate_bias:
        Estimate the gyro bias whenever the device rests (see :mod:`hrtls.attitude.bias`).
    rest_gyro_rad_s, rest_acc_m_s2, rest_s:
        Rest detection thresholds: deviation of the gyro rate from its low-pass and of the
        low-pass from the bias (twice this) in rad/s, deviation of the specific force from its
        low-pass and of its norm from g in m/s^2, and the minimum rest duration in s. A gyro
        whose bias exceeds ``2 rest_gyro_rad_s`` is never seen at rest: pass
        ``gyro_bias_rad_s`` or calibrate.
    bias_tau_s:
        Time constant of the bias update at rest, s.
    gyro_bias_rad_s:
        Initial gyro bias (e.g. from :func:`hrtls.attitude.bias.estimate_gyro_bias`), rad/s.
    init_heading_from_mag:
        Initialise the heading from the magnetometer (else heading 0 = device x east).
    mounting_q_bd:
        Device -> body rotation ``[w, x, y, z]``; when given the result is ``q_nb``.
    """

    gravity_m_s2: float = GRAVITY_M_S2
    acc_gate_m_s2: float = 1.0
    mag_norm_gate_uT: float = 3.0
    mag_dip_gate_rad: float = float(np.deg2rad(5.0))
    mag_jump_gate_uT: float = 5.0
    mag_new_field_s: float = 20.0
    mag_ref_norm_uT: float | None = None
    mag_ref_dip_rad: float | None = None
    gyro_range_rad_s: float = 35.0
    acc_range_m_s2: float = 16.0 * GRAVITY_M_S2
    max_dt_s: float = 0.5
    estimate_bias: bool = True
    rest_gyro_rad_s: float = float(np.deg2rad(2.0))
    rest_acc_m_s2: float = 0.5
    rest_s: float = 1.0
    bias_tau_s: float = 1.0
    gyro_bias_rad_s: tuple[float, float, float] = (0.0, 0.0, 0.0)
    init_heading_from_mag: bool = True
    mounting_q_bd: tuple[float, float, float, float] | None = None

    def __post_init__(self) -> None:
        positive = ("gravity_m_s2", "acc_gate_m_s2", "mag_norm_gate_uT", "mag_dip_gate_rad",
                    "mag_jump_gate_uT", "mag_new_field_s", "gyro_range_rad_s", "acc_range_m_s2",
                    "max_dt_s", "rest_gyro_rad_s", "rest_acc_m_s2", "bias_tau_s")
        self._require_positive(positive, inf_ok=positive,
                               expected="a positive number (inf allowed for gates)")
        if not (np.isfinite(self.rest_s) and self.rest_s >= 0.0):
            raise InputError(f"rest_s = {self.rest_s}", where=type(self).__name__,
                             expected="a finite number >= 0")
        b = np.asarray(self.gyro_bias_rad_s, dtype=np.float64)
        if b.shape != (3,) or not np.all(np.isfinite(b)):
            raise InputError(f"gyro_bias_rad_s = {self.gyro_bias_rad_s}",
                             where=type(self).__name__, expected="three finite rates, rad/s")
        if self.mounting_q_bd is not None:
            q = np.asarray(self.mounting_q_bd, dtype=np.float64)
            if q.shape != (4,) or not np.all(np.isfinite(q)) or abs(np.linalg.norm(q) - 1) > 1e-6:
                raise InputError(f"mounting_q_bd = {self.mounting_q_bd}",
                                 where=type(self).__name__, expected="a unit quaternion [w,x,y,z]")
        for name in ("mag_ref_norm_uT", "mag_ref_dip_rad"):
            value = getattr(self, name)
            if value is not None and not np.isfinite(value):
                raise InputError(f"{name} = {value}", where=type(self).__name__,
                                 expected="a finite number or None")

    def _require_positive(self, names: tuple[str, ...], *, inf_ok: tuple[str, ...] = (),
                          expected: str = "a finite positive number") -> None:
        """Raise :class:`InputError` unless each named field is > 0 (inf only if in ``inf_ok``)."""
        for name in names:
            value = float(getattr(self, name))
            if not (value > 0.0 and (np.isfinite(value) or name in inf_ok)):
                raise InputError(f"{name} = {value}", where=type(self).__name__,
                                 expected=expected)

    def common_array(self) -> FloatArray:
        """The shared part of the kernel parameter array (layout: ``_kernels.PRM_*``)."""
        p = np.zeros(K.PRM_SPECIFIC)
        p[K.PRM_GRAVITY] = self.gravity_m_s2
        p[K.PRM_ACC_GATE] = self.acc_gate_m_s2
        p[K.PRM_MAG_NORM_GATE] = self.mag_norm_gate_uT
        p[K.PRM_MAG_DIP_GATE] = self.mag_dip_gate_rad
        p[K.PRM_MAG_JUMP_GATE] = self.mag_jump_gate_uT
        p[K.PRM_MAG_NEW_S] = self.mag_new_field_s
        p[K.PRM_MAG_REF_N] = np.nan if self.mag_ref_norm_uT is None else self.mag_ref_norm_uT
        p[K.PRM_MAG_REF_DIP] = np.nan if self.mag_ref_dip_rad is None else self.mag_ref_dip_rad
        p[K.PRM_GYR_RANGE] = self.gyro_range_rad_s
        p[K.PRM_ACC_RANGE] = self.acc_range_m_s2
        p[K.PRM_MAX_DT] = self.max_dt_s
        p[K.PRM_BIAS_EST] = 1.0 if self.estimate_bias else 0.0
        p[K.PRM_REST_GYR] = self.rest_gyro_rad_s
        p[K.PRM_REST_ACC] = self.rest_acc_m_s2
        p[K.PRM_REST_S] = self.rest_s
        p[K.PRM_BIAS_TAU_S] = self.bias_tau_s
        p[K.PRM_BIAS0 : K.PRM_BIAS0 + 3] = self.gyro_bias_rad_s
        p[K.PRM_INIT_MAG] = 1.0 if self.init_heading_from_mag else 0.0
        return p

    def specific_values(self) -> tuple[float, ...]:
        """The filter's own kernel parameters, in the order of its indices from ``PRM_SPECIFIC``."""
        return ()

    def kernel_array(self) -> FloatArray:
        """The whole kernel parameter array: :meth:`common_array`, then :meth:`specific_values`."""
        return np.concatenate([self.common_array(),
                               np.asarray(self.specific_values(), dtype=np.float64)])


@dataclass(frozen=True, eq=False)
class AttitudeState:
    """Saved state of a filter (restore it to continue exactly where it stopped).

    Attributes
    ----------
    method:
        Registry name of the filter that produced it.
    x:
        The filter's own state vector (a quaternion; for the Euler EKF roll, pitch, yaw in rad
        followed by their quaternion).
    P:
        Its covariance (empty for filters without one).
    aux:
        Bookkeeping shared by all filters (time of the last sample, gyro bias, rest timer,
        magnetometer reference, rejection counters); layout in :mod:`hrtls.attitude._kernels`.
    """

    method: str
    x: FloatArray
    P: FloatArray
    aux: FloatArray

    @property
    def initialized(self) -> bool:
        """True once the attitude was initialised from the accelerometer."""
        return bool(self.aux[K.AUX_INIT] > 0.5)

    @property
    def gyro_bias_rad_s(self) -> FloatArray:
        """Current gyro bias estimate, rad/s."""
        return np.array(self.aux[K.AUX_BIAS : K.AUX_BIAS + 3])

    @property
    def t_last_s(self) -> float:
        """Time of the last processed sample, s (NaN before the first sample)."""
        return float(self.aux[K.AUX_T_PREV])

    def copy(self) -> AttitudeState:
        """Deep copy."""
        return AttitudeState(self.method, self.x.copy(), self.P.copy(), self.aux.copy())

    def to_dict(self) -> dict[str, Any]:
        """JSON-able dictionary (NaN stored as None)."""
        def enc(a: FloatArray) -> list[Any]:
            return [None if np.isnan(v) else float(v) for v in np.ravel(a)]

        return {"method": self.method, "x": enc(self.x), "P": enc(self.P),
                "P_shape": list(self.P.shape), "aux": enc(self.aux)}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> AttitudeState:
        """Inverse of :meth:`to_dict`."""
        try:
            def dec(v: Any) -> FloatArray:
                return np.array([np.nan if e is None else e for e in np.ravel(
                    np.array(v, dtype=object))], dtype=np.float64)

            P = dec(data["P"]).reshape(tuple(data.get("P_shape", [0])))
            state = cls(str(data["method"]), dec(data["x"]), P, dec(data["aux"]))
        except (KeyError, TypeError, ValueError) as exc:
            raise InputError(f"cannot read attitude state: {exc}", where="attitude state",
                             expected="a dictionary written by AttitudeState.to_dict") from exc
        if state.aux.shape == (K.AUX_DYN_MEAN,):
            # written before the body-acceleration variance existed: it restarts
            aux = np.concatenate([state.aux, [np.nan, np.nan, np.nan, 0.0]])
            state = cls(state.method, state.x, state.P, aux)
        if state.aux.shape != (K.AUX_SIZE,):
            raise InputError(f"aux has {state.aux.size} values", where="attitude state",
                             expected=f"{K.AUX_SIZE} values")
        return state


def _flag(flags: NDArray[np.uint8], bit: int) -> NDArray[np.bool_]:
    return (flags & bit) != 0


@dataclass(frozen=True, eq=False)
class AttitudeResult:
    """Attitude estimates of one chunk (or a whole recording).

    Attributes
    ----------
    t:
        Sample times, s, shape (N,).
    q:
        Unit quaternions ``[w, x, y, z]``, shape (N, 4): ``q_nd`` (``frame == "nd"``) or
        ``q_nb`` (``frame == "nb"``, when a mounting rotation was given).
    frame:
        ``"nd"`` (device -> ENU) or ``"nb"`` (body -> ENU).
    var_rpy:
        Variances of roll, pitch, yaw (rad^2), shape (N, 3), for methods with a covariance
        (for the quaternion EKF: of the small rotation about the ENU axes, which equals the yaw
        variance exactly and roll/pitch variances for small tilt); ``None`` otherwise.
    flags:
        Bit mask per sample (see ``_kernels.FLAG_*``); the boolean views below decode it.
    rejected:
        Counts in this chunk: ``acc`` / ``mag`` (samples not used by the gates, including
        invalid ones), ``gyro`` (samples not integrated) and ``bad`` (samples with a non-finite
        or saturated value).
    extra:
        Method-specific per-sample outputs (e.g. ``gain_acc``/``gain_mag`` of the
        complementary filter).
    """

    t: FloatArray
    q: FloatArray
    frame: str
    var_rpy: FloatArray | None
    flags: NDArray[np.uint8]
    rejected: dict[str, int]
    extra: dict[str, FloatArray] = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.t)

    @property
    def acc_used(self) -> NDArray[np.bool_]:
        """Samples where the accelerometer corrected the attitude."""
        return _flag(self.flags, K.FLAG_ACC)

    @property
    def mag_used(self) -> NDArray[np.bool_]:
        """Samples where the magnetometer corrected the attitude."""
        return _flag(self.flags, K.FLAG_MAG)

    @property
    def gyro_used(self) -> NDArray[np.bool_]:
        """Samples whose gyro rate was integrated."""
        return _flag(self.flags, K.FLAG_GYR)

    @property
    def valid(self) -> NDArray[np.bool_]:
        """Samples after initialisation (before it, ``q`` is the identity)."""
        return _flag(self.flags, K.FLAG_VALID)

    @property
    def at_rest(self) -> NDArray[np.bool_]:
        """Samples detected as rest (gyro bias updated there when enabled)."""
        return _flag(self.flags, K.FLAG_REST)

    @property
    def euler(self) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Roll, pitch, yaw in rad (z-y'-x'' sequence of :mod:`hrtls.frames`)."""
        return euler_from_quat(self.q)

    @property
    def roll(self) -> FloatArray:
        """Roll, rad."""
        return self.euler[0]

    @property
    def pitch(self) -> FloatArray:
        """Pitch, rad."""
        return self.euler[1]

    @property
    def yaw(self) -> FloatArray:
        """Yaw, rad, CCW from east, in (-pi, pi]."""
        return self.euler[2]

    @property
    def heading(self) -> FloatArray:
        """Heading of the forward (x) axis projected on the horizontal plane, rad."""
        return heading_from_quat(self.q)

    @classmethod
    def concatenate(cls, parts: list[AttitudeResult]) -> AttitudeResult:
        """Join consecutive chunk results into one."""
        if not parts:
            raise InputError("no results", where="AttitudeResult.concatenate",
                             expected="at least one chunk result")
        frames = {p.frame for p in parts}
        if len(frames) != 1:
            raise InputError(f"mixed frames {sorted(frames)}", where="AttitudeResult.concatenate",
                             expected="results of one filter")
        has_var = parts[0].var_rpy is not None
        rejected = {k: sum(p.rejected.get(k, 0) for p in parts) for k in parts[0].rejected}
        keys = set(parts[0].extra)
        return cls(
            t=np.concatenate([p.t for p in parts]),
            q=np.concatenate([p.q for p in parts]),
            frame=parts[0].frame,
            var_rpy=np.concatenate([p.var_rpy for p in parts if p.var_rpy is not None])
            if has_var else None,
            flags=np.concatenate([p.flags for p in parts]),
            rejected=rejected,
            extra={k: np.concatenate([p.extra[k] for p in parts]) for k in keys},
        )


def _as_samples(values: ArrayLike | None, n: int, name: str) -> FloatArray | None:
    if values is None:
        return None
    arr = np.ascontiguousarray(values, dtype=np.float64)
    if arr.shape != (n, 3):
        raise InputError(f"shape {arr.shape}", where=name, expected=f"({n}, 3) samples")
    return arr


class AttitudeFilter(ABC):
    """Base class: a causal attitude filter with a saveable state and a chunk update.

    Subclasses set ``name`` and ``params_type`` (and ``extra_inputs`` / ``extra_outputs`` when
    they take or give more per-sample arrays) and implement :meth:`_new_xp` and :meth:`_kernel`;
    their parameters extend :meth:`CommonParams.specific_values`.
    """

    name: ClassVar[str] = ""
    params_type: ClassVar[type[CommonParams]] = CommonParams
    has_covariance: ClassVar[bool] = True
    extra_outputs: ClassVar[tuple[str, ...]] = ()
    extra_inputs: ClassVar[tuple[str, ...]] = ()

    def __init__(self, params: CommonParams | None = None) -> None:
        if params is None:
            params = self.params_type()
        if not isinstance(params, self.params_type):
            raise InputError(f"parameters of type {type(params).__name__}", where=self.name,
                             expected=self.params_type.__name__)
        self.params = params
        self._prm = params.kernel_array()
        self._state = self._fresh_state()

    # -- state ---------------------------------------------------------------------------
    @abstractmethod
    def _new_xp(self) -> tuple[FloatArray, FloatArray]:
        """Initial state vector and covariance."""

    def _fresh_state(self) -> AttitudeState:
        x, P = self._new_xp()
        bias0 = np.asarray(self.params.gyro_bias_rad_s, dtype=np.float64)
        return AttitudeState(self.name, x, P, K.new_aux(bias0))

    @property
    def state(self) -> AttitudeState:
        """A copy of the current state (save it with ``state.to_dict()``)."""
        return self._state.copy()

    def restore(self, state: AttitudeState) -> None:
        """Continue from a saved state (of the same method)."""
        ref = self._fresh_state()
        if state.method != self.name:
            raise InputError(f"state of method {state.method!r}", where=self.name,
                             expected=f"a state saved by {self.name!r}")
        if state.x.shape != ref.x.shape or state.P.shape != ref.P.shape:
            raise InputError(f"state shapes {state.x.shape}, {state.P.shape}", where=self.name,
                             expected=f"{ref.x.shape}, {ref.P.shape}")
        self._state = state.copy()

    def reset(self) -> None:
        """Forget everything: the next sample initialises the filter again."""
        self._state = self._fresh_state()

    # -- processing ----------------------------------------------------------------------
    @abstractmethod
    def _kernel(self, t: FloatArray, acc: FloatArray, gyr: FloatArray, mag: FloatArray,
                has_gyr: bool, has_mag: bool, x: FloatArray, P: FloatArray, aux: FloatArray,
                out_q: FloatArray, out_var: FloatArray, out_flags: NDArray[np.uint8],
                out_extra: FloatArray, **inputs: FloatArray) -> None:
        """Run the compiled kernel over one chunk (mutates ``x``, ``P``, ``aux``)."""

    def _check_time(self, t: FloatArray) -> None:
        if not np.all(np.isfinite(t)):
            i = int(np.flatnonzero(~np.isfinite(t))[0])
            raise InputError("non-finite time", where=f"{self.name} time index {i}",
                             expected="finite times in s")
        if len(t) > 1 and not np.all(np.diff(t) > 0.0):
            i = int(np.flatnonzero(np.diff(t) <= 0.0)[0]) + 1
            raise InputError("time does not increase", where=f"{self.name} time index {i}",
                             expected="strictly increasing times")
        t_prev = self._state.t_last_s
        if len(t) and np.isfinite(t_prev) and not t[0] > t_prev:
            raise InputError(f"chunk starts at {t[0]} s, not after {t_prev} s",
                             where=f"{self.name} time index 0",
                             expected="chunks in time order (reset() to start over)")

    def update(self, t: ArrayLike, acc: ArrayLike, gyr: ArrayLike | None = None,
               mag: ArrayLike | None = None, **inputs: ArrayLike) -> AttitudeResult:
        """Process one chunk of device-frame samples and advance the state.

        Parameters
        ----------
        t:
            Times, s, shape (N,), strictly increasing and after the previous chunk.
        acc:
            Specific force, m/s^2, shape (N, 3).
        gyr:
            Angular rate, rad/s, shape (N, 3); ``None`` for an accelerometer-only device
            (warns: the attitude then follows the static sensors only).
        mag:
            Magnetic field, uT, shape (N, 3), or ``None``.
        **inputs:
            Method-specific inputs named in ``extra_inputs`` (the Euler EKF takes ``yaw_rad``).

        Returns
        -------
        AttitudeResult
            Estimates for the N samples of the chunk.
        """
        tt = np.ascontiguousarray(t, dtype=np.float64)
        if tt.ndim != 1:
            raise InputError(f"shape {tt.shape}", where=f"{self.name} time", expected="(N,)")
        n = len(tt)
        self._check_time(tt)
        a = _as_samples(acc, n, f"{self.name} accelerometer")
        assert a is not None
        g = _as_samples(gyr, n, f"{self.name} gyroscope")
        m = _as_samples(mag, n, f"{self.name} magnetometer")
        if g is None:
            warnings.warn(f"{self.name}: no gyroscope; the attitude follows the accelerometer "
                          "and magnetometer only", DegradedInputWarning, stacklevel=2)
        unknown = sorted(set(inputs) - set(self.extra_inputs))
        if unknown:
            raise InputError(f"unexpected inputs {unknown}", where=self.name,
                             expected=f"optional {', '.join(self.extra_inputs)} only"
                             if self.extra_inputs else "t, acc, gyr, mag only")
        extra_in = {k: np.ascontiguousarray(v, dtype=np.float64) for k, v in inputs.items()}
        for k, v in extra_in.items():
            if v.shape != (n,):
                raise InputError(f"shape {v.shape}", where=f"{self.name} {k}", expected=f"({n},)")
        zeros = np.zeros((n, 3))
        st = self._state.copy()
        before = st.aux.copy()
        out_q = np.empty((n, 4))
        out_var = np.empty((n, 3)) if self.has_covariance else np.empty((0, 3))
        out_flags = np.zeros(n, dtype=np.uint8)
        out_extra = np.empty((n, len(self.extra_outputs)))
        self._kernel(tt, a, zeros if g is None else g, zeros if m is None else m,
                     g is not None, m is not None, st.x, st.P, st.aux, out_q, out_var,
                     out_flags, out_extra, **extra_in)
        self._state = st
        diff = st.aux - before
        rejected = {"acc": int(diff[K.AUX_N_ACC_REJ]), "mag": int(diff[K.AUX_N_MAG_REJ]),
                    "gyro": int(diff[K.AUX_N_GYR_REJ]), "bad": int(diff[K.AUX_N_BAD])}
        frame = "nd"
        if self.params.mounting_q_bd is not None:
            q_bd = np.asarray(self.params.mounting_q_bd, dtype=np.float64)
            out_q = quat_normalize(quat_multiply(out_q, quat_conjugate(q_bd)))
            frame = "nb"
        return AttitudeResult(
            t=tt, q=out_q, frame=frame, var_rpy=out_var if self.has_covariance else None,
            flags=out_flags, rejected=rejected,
            extra={k: np.ascontiguousarray(out_extra[:, i])
                   for i, k in enumerate(self.extra_outputs)},
        )

    def run(self, imu: ImuStream, **inputs: ArrayLike) -> AttitudeResult:
        """Reset, then process a whole stream as one chunk (on the accelerometer's times)."""
        self.reset()
        t, acc, gyr, mag = imu.aligned()
        return self.update(t, acc, gyr, mag, **inputs)


def params_to_dict(params: CommonParams) -> dict[str, Any]:
    """Parameters as a JSON-able dictionary (for reports and saved configurations)."""
    return {f.name: getattr(params, f.name) for f in fields(params)}
