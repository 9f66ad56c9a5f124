"""State of the rescuer position filter: ``x = [x, y, z, heading]`` and its covariance ``P``.

Position in the ENU navigation frame (m), heading in rad CCW from east wrapped to ``(-pi, pi]``
(see :mod:`hrtls.frames`). The state is immutable: predictions and corrections return a new
:class:`FilterState`. It is saved and restored with :meth:`FilterState.to_dict` /
:meth:`FilterState.from_dict` (JSON-able), which is how the live tracker resumes.

``input_heading_rad`` remembers the last heading *input* (from the attitude filter or the step
detector) so that, in ``heading_mode="state"``, predictions integrate heading *changes* of the
input into the state heading and heading corrections persist (see
:mod:`hrtls.fusion.step_prediction`). ``reference_pending`` is true between the first heading
input and the second: the reference is then completed over the first stride (see
:data:`hrtls.fusion.step_prediction.FIRST_STRIDE_MAX_TURN_RAD`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from hrtls.data.session import StartPose
from hrtls.errors import InputError
from hrtls.frames import wrap_angle
from hrtls.fusion._checks import FloatArray, finite_matrix, finite_scalar, finite_vector
from hrtls.fusion.gating import UpdateDiagnostics, kalman_update, symmetrize

STATE_LABELS = ("x", "y", "z", "heading")
"""Names of the state components, in order."""
IX, IY, IZ, IH = 0, 1, 2, 3
"""Indices of x, y, z and heading in the state vector."""
N_STATE = 4


@dataclass(frozen=True, slots=True, eq=False)
class FilterState:
    """Position/heading estimate with covariance.

    Attributes
    ----------
    t: time of the estimate, s.
    x: ``[x, y, z, heading]`` (m, m, m, rad).
    P: 4x4 covariance (m^2, m rad, rad^2), symmetric positive semi-definite.
    input_heading_rad: last heading input seen by a predictor (rad).
    has_input_heading: whether ``input_heading_rad`` is valid.
    reference_pending: whether only one heading input has been seen (the first step's).
    """

    t: float
    x: FloatArray
    P: FloatArray
    input_heading_rad: float = 0.0
    has_input_heading: bool = False
    reference_pending: bool = False

    def __post_init__(self) -> None:
        t = finite_scalar(self.t, where="filter state t")
        x = finite_vector(self.x, where="filter state x", length=N_STATE).copy()
        p = finite_matrix(self.P, where="filter state P", shape=(N_STATE, N_STATE))
        asym = np.abs(p - p.T)
        if np.any(asym > 1e-9 + 1e-6 * np.abs(p.T)):   # as np.allclose(p, p.T, 1e-6, 1e-9)
            raise InputError("covariance is not symmetric", where="filter state P",
                             expected="a symmetric positive semi-definite 4x4 matrix")
        p = symmetrize(p)
        scale = max(1.0, float(np.max(np.abs(np.diag(p)))))
        # PSD check: Cholesky of P + tol I (fast); the eigenvalues only when it fails
        try:
            np.linalg.cholesky(p + (1e-9 * scale) * np.eye(N_STATE))
            negative = False
        except np.linalg.LinAlgError:
            negative = float(np.min(np.linalg.eigvalsh(p))) < -1e-9 * scale
        if negative:
            raise InputError("covariance has a negative eigenvalue", where="filter state P",
                             expected="a symmetric positive semi-definite 4x4 matrix")
        x[IH] = float(wrap_angle(x[IH]))
        h_in = finite_scalar(self.input_heading_rad, where="filter state input_heading_rad")
        object.__setattr__(self, "t", t)
        object.__setattr__(self, "x", x)
        object.__setattr__(self, "P", p)
        object.__setattr__(self, "input_heading_rad", float(wrap_angle(h_in)))
        object.__setattr__(self, "has_input_heading", bool(self.has_input_heading))
        object.__setattr__(self, "reference_pending", bool(self.reference_pending))

    # ---------------------------------------------------------------- construction
    @classmethod
    def initial(cls, *, t: float = 0.0, xyz: tuple[float, float, float] = (0.0, 0.0, 0.0),
                heading_rad: float = 0.0, sigma_xy_m: float = 0.5, sigma_z_m: float = 0.1,
                sigma_heading_rad: float = 0.2) -> FilterState:
        """A start state with a diagonal covariance built from 1-sigma values."""
        for name, v in (("sigma_xy_m", sigma_xy_m), ("sigma_z_m", sigma_z_m),
                        ("sigma_heading_rad", sigma_heading_rad)):
            finite_scalar(v, where=name, non_negative=True)
        x = np.array([*xyz, heading_rad], dtype=np.float64)
        p = np.diag([sigma_xy_m**2, sigma_xy_m**2, sigma_z_m**2, sigma_heading_rad**2])
        return cls(t, x, p)

    @classmethod
    def from_start_pose(cls, pose: StartPose, *, t: float = 0.0, sigma_z_m: float = 0.1,
                        default_heading_rad: float = 0.0) -> FilterState:
        """Start state from a session's ``start_pose`` (unknown heading -> ``default``)."""
        heading = pose.heading if pose.heading is not None else default_heading_rad
        sigma_h = pose.sigma_heading_rad if pose.heading is not None else np.pi
        return cls.initial(t=t, xyz=(pose.x, pose.y, pose.z), heading_rad=heading,
                           sigma_xy_m=pose.sigma_xy_m, sigma_z_m=sigma_z_m,
                           sigma_heading_rad=float(sigma_h))

    @classmethod
    def from_kernel(cls, t: float, x: FloatArray, p: FloatArray, input_heading_rad: float,
                    has_input_heading: bool, reference_pending: bool = False) -> FilterState:
        """Wrap the output of a compiled filter loop without the full validation.

        The loops of :mod:`hrtls.pipeline._events` keep ``P`` exactly symmetric (Joseph form,
        symmetrized) and the heading wrapped; only finiteness is checked here (NaN never
        leaves a filter).
        """
        x = np.array(x, dtype=np.float64)
        p = np.array(p, dtype=np.float64)
        # a sum is finite only when every term is (20 numbers: summed as Python floats)
        if not math.isfinite(sum(x.tolist()) + sum(p.ravel().tolist()) + t
                             + input_heading_rad):
            raise InputError("non-finite state from the compiled loop", where="filter state",
                             expected="finite x, P and t")
        state = object.__new__(cls)
        object.__setattr__(state, "t", float(t))
        object.__setattr__(state, "x", x)
        object.__setattr__(state, "P", p)
        object.__setattr__(state, "input_heading_rad", float(input_heading_rad))
        object.__setattr__(state, "has_input_heading", bool(has_input_heading))
        object.__setattr__(state, "reference_pending", bool(reference_pending))
        return state

    def evolve(self, **changes: Any) -> FilterState:
        """A copy with some fields replaced (validated again)."""
        return replace(self, **changes)

    # ---------------------------------------------------------------- views
    @property
    def position(self) -> FloatArray:
        """``[x, y, z]``, m (a copy)."""
        return self.x[:3].copy()

    @property
    def heading(self) -> float:
        """Heading, rad."""
        return float(self.x[IH])

    @property
    def cov_xy(self) -> FloatArray:
        """Horizontal position covariance (2, 2), m^2."""
        return self.P[:2, :2].copy()

    @property
    def var_heading(self) -> float:
        """Heading variance, rad^2."""
        return float(self.P[IH, IH])

    # ---------------------------------------------------------------- save / restore
    def to_dict(self) -> dict[str, Any]:
        """JSON-able form."""
        return {"t": self.t, "x": self.x.tolist(), "P": self.P.tolist(),
                "input_heading_rad": self.input_heading_rad,
                "has_input_heading": self.has_input_heading,
                "reference_pending": self.reference_pending}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> FilterState:
        """Inverse of :meth:`to_dict`."""
        missing = [k for k in ("t", "x", "P") if k not in data]
        if missing:
            raise InputError(f"missing keys {missing}", where="filter state",
                             expected="a dict written by FilterState.to_dict()")
        return cls(float(data["t"]), np.asarray(data["x"], dtype=np.float64),
                   np.asarray(data["P"], dtype=np.float64),
                   float(data.get("input_heading_rad", 0.0)),
                   bool(data.get("has_input_heading", False)),
                   bool(data.get("reference_pending", False)))


def independent_block(p: FloatArray, idx: list[int], block: FloatArray) -> FloatArray:
    """Covariance with ``P[idx, idx] = block`` and the cross terms of ``idx`` set to zero.

    Used when a correction *resets* some components (e.g. a tag read re-initializes the
    position): the new values are independent of the rest of the state, so the result stays
    positive semi-definite.
    """
    out = p.copy()
    out[idx, :] = 0.0
    out[:, idx] = 0.0
    out[np.ix_(idx, idx)] = block
    return symmetrize(out)


def heading_update(state: FilterState, innovation_rad: float, r_rad2: float, *, kind: str,
                   t: float, gate_probability: float | None,
                   source: str = "") -> tuple[FilterState, UpdateDiagnostics]:
    """Scalar EKF update by a heading measurement (Joseph form, NIS gate).

    ``h(x) = x_h``, ``H = e_h``; ``innovation_rad`` is ``z - x_h``, wrapped to ``(-pi, pi]``.
    """
    h = np.zeros((1, N_STATE))
    h[0, IH] = 1.0
    res = kalman_update(state.x, state.P, h, np.array([[r_rad2]]), np.array([innovation_rad]),
                        gate_probability=gate_probability, kind=kind, t=t, source=source,
                        angle_index=IH)
    return state.evolve(x=res.x, P=res.P), res.diagnostics
