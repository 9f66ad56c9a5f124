"""Passive (range-free) tags: the four correction strategies and the bearing heading correction.

Inderst thesis Sec. 4.3.2 (eq. 4.26-4.33) and Sec. 4.2.3 (eq. 4.21-4.22).

A tag ``i`` gives its position, the orientation of its antenna lobe and an accuracy ``w_i``.
The lobe centre is ``T^i = position_xy + r_c [cos, sin](lobe_orientation)`` (the tag position
itself when the orientation is unknown). Readings:

* ``w_i`` (``Landmark.accuracy_m``, m) is the radius of the lobe around its centre: the rescuer is
  "inside the lobe" when ``|p_xy - T^i| <= w_i``. The lobe as a measurement has the per-axis
  1-sigma ``kappa w_i`` (``R_i = (kappa w_i)^2 I``; ``kappa = 0.5`` is the spread of a uniform disc
  of radius ``w``). The thesis writes ``P = w_i I`` with ``w_i`` a length; we read it as ``R_i``.
* Defaults from the thesis' RFID calibration (App. B: range r = 2.5 m, lobe +-60 deg): the centroid
  of that sector lies ``2 r sin(a) / (3 a) = 1.4 m`` in front of the tag and a disc of about 2 m
  around it covers the sector, so ``r_c = 1.4 m`` and ``w = 2.0 m`` when the landmark says nothing.
* Several reads within ``group_window_s`` are one multi-tag detection (``r`` tags). The weights
  ``omega_i`` of eq. 4.28-4.33 are the normalized precisions ``(1/w_i^2) / sum(1/w_j^2)``.

Strategies (``strategy="paper"``), chosen automatically:

1. one tag, prediction outside its lobe (eq. 4.26): reset ``p_xy = T^i``, ``P_xy = R_i``;
2. one tag, prediction inside (eq. 4.27): position kept, ``P_xy`` bounded: replaced by ``R_i``
   when ``tr(P_xy) >= tr(R_i)``;
3. several tags, prediction outside all lobes (eq. 4.28): ``p_xy = T_bar = sum omega_i T^i`` and
   ``P_xy = sum omega_i (T^i - T_bar)(T^i - T_bar)^T + (sum R_i^-1)^-1`` (the added lobe term keeps
   it positive definite when the centres are aligned);
4. several tags, prediction inside some lobes (eq. 4.29-4.33): with ``delta = T_bar - p`` and the
   tags' combined uncertainty ``C = sum omega_i (T^i - T_bar)(T^i - T_bar)^T + (sum R_i^-1)^-1``,
   ``S = sum omega_i (T^i - p)(T^i - p)^T + (sum R_i^-1)^-1 = C + delta delta^T`` (eq. 4.33),
   ``P_pz = C`` (eq. 4.32 simplifies to it), ``L = P_pz S^-1`` (eq. 4.31),
   ``p+ = p + L delta`` (eq. 4.29 with the stacked innovation averaged by the weights; it moves the
   estimate toward ``T_bar`` by the fraction ``1 / (1 + delta^T C^-1 delta)``), and
   ``P+ = P`` when ``tr(P_xy) < tr(S)``, else ``P - L S L^T`` (eq. 4.30) -- if that is not positive
   definite, the information fusion ``(P^-1 + C^-1)^-1`` is used instead.

The paper strategies re-initialize the position, so after them the position is uncorrelated
with z and the heading (cross-covariances cleared). ``strategy="kalman"`` instead applies each
perceived lobe as a gated position measurement ``z = T^i``, ``R = R_i`` (Joseph form), keeping the
cross-covariances (a position jump then also corrects the heading in ``heading_mode="state"``).

Bearing correction (eq. 4.21-4.22, :func:`bearing_heading_correction`): the bearing nearest to the
heading is associated (eq. 4.21); the heading is kept when within ``deadband_rad`` of it (eq. 4.22,
``epsilon_phi``), replaced by it otherwise -- unless farther than ``gate_rad``, which we add
because a read while turning should not snap the heading. ``mode="kalman"`` instead fuses the
bearing as a heading measurement with variance ``sigma_rad^2`` (gated).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike

from hrtls.data.landmarks import Landmark
from hrtls.data.observations import TagDetections
from hrtls.errors import InputError
from hrtls.frames import wrap_angle
from hrtls.fusion._checks import FloatArray, finite_scalar, probability
from hrtls.fusion.gating import (
    UpdateDiagnostics,
    is_spd,
    kalman_update,
    rejected,
    skipped,
    symmetrize,
)
from hrtls.fusion.state import IH, N_STATE, FilterState, heading_update, independent_block

XY = [0, 1]


@dataclass(frozen=True, kw_only=True)
class TagParams:
    """Parameters of the passive-tag correction.

    Attributes
    ----------
    lobe_offset_m: ``r_c``, distance from the tag to its lobe centre, m.
    default_accuracy_m: ``w_i`` for tags without ``accuracy_m``, m.
    sigma_per_accuracy: ``kappa``: per-axis 1-sigma of a lobe as a fraction of ``w_i``.
    strategy: ``"paper"`` (strategies 1-4) or ``"kalman"``.
    group_window_s: reads closer in time than this form one detection.
    gate_probability: NIS gate of the ``"kalman"`` strategy (None: off).
    max_correction_m: reject detections whose lobe centre is farther than this from the
        prediction (a misread tag id); ``inf`` accepts all, as the thesis does.
    repeat_interval_s: a tag that corrected the state is ignored for this long (a reader
        queries a tag several times while passing; re-applying strategy 1 at every read would
        pin the estimate to the lobe centre). Our addition; 0 applies every read.
    """

    lobe_offset_m: float = 1.4
    default_accuracy_m: float = 2.0
    sigma_per_accuracy: float = 0.5
    strategy: Literal["paper", "kalman"] = "paper"
    group_window_s: float = 0.5
    gate_probability: float | None = 0.999
    max_correction_m: float = math.inf
    repeat_interval_s: float = 2.0

    def __post_init__(self) -> None:
        finite_scalar(self.lobe_offset_m, where="TagParams.lobe_offset_m", non_negative=True)
        finite_scalar(self.default_accuracy_m, where="TagParams.default_accuracy_m",
                      positive=True)
        finite_scalar(self.sigma_per_accuracy, where="TagParams.sigma_per_accuracy",
                      positive=True)
        finite_scalar(self.group_window_s, where="TagParams.group_window_s", non_negative=True)
        finite_scalar(self.repeat_interval_s, where="TagParams.repeat_interval_s",
                      non_negative=True)
        if not self.max_correction_m > 0:
            raise InputError(f"{self.max_correction_m}", where="TagParams.max_correction_m",
                             expected="a distance > 0 m (inf to disable)")
        if self.strategy not in ("paper", "kalman"):
            raise InputError(f"strategy {self.strategy!r}", where="TagParams.strategy",
                             expected="'paper' or 'kalman'")
        if self.gate_probability is not None:
            probability(self.gate_probability, where="TagParams.gate_probability")


def lobe_centre(landmark: Landmark, lobe_offset_m: float) -> FloatArray:
    """``T^i``: tag position plus ``r_c`` along the lobe orientation (xy, m)."""
    xy = landmark.xyz()[:2]
    if landmark.lobe_orientation_rad is None:
        return xy
    a = landmark.lobe_orientation_rad
    return xy + lobe_offset_m * np.array([math.cos(a), math.sin(a)])


@dataclass(frozen=True, slots=True)
class TagMemory:
    """Causal state of :class:`TagCorrector`: when each tag last corrected the filter (s)."""

    last_used: dict[str, float] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        """JSON-able form."""
        return {"last_used": dict(self.last_used)}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> TagMemory:
        """Inverse of :meth:`to_dict`."""
        return cls({str(k): float(v) for k, v in data.get("last_used", {}).items()})


@dataclass(frozen=True, slots=True, eq=False)
class TagUpdate:
    """Result of one detection: state, diagnostics, strategy (1-4, 0 = kalman, -1 = none).

    ``memory`` is the updated :class:`TagMemory` to pass to the next call.
    """

    state: FilterState
    diagnostics: list[UpdateDiagnostics]
    strategy: int
    correction_m: float
    memory: TagMemory = field(default_factory=TagMemory)


@dataclass(frozen=True, slots=True, eq=False)
class HeadingCorrection:
    """Result of a bearing correction: state, diagnostics, applied heading change (rad)."""

    state: FilterState
    diagnostics: UpdateDiagnostics
    correction_rad: float


class TagCorrector:
    """Inderst eq. 4.26-4.33 (and a Kalman alternative) for passive tag reads."""

    def __init__(self, params: TagParams | None = None) -> None:
        self.params = params or TagParams()

    def _lobes(self, landmarks: list[Landmark]) -> tuple[FloatArray, FloatArray]:
        prm = self.params
        centres = np.array([lobe_centre(lm, prm.lobe_offset_m) for lm in landmarks])
        w = np.array([lm.accuracy_m if lm.accuracy_m is not None else prm.default_accuracy_m
                      for lm in landmarks], dtype=np.float64)
        return centres, w

    def update(self, state: FilterState, *, t: float, tags: list[Landmark],
               memory: TagMemory | None = None) -> TagUpdate:
        """Correct ``state`` with the tags read together at ``t``.

        ``tags`` are landmarks with local positions (resolve WGS-84 ones first); ``memory``
        is the previous call's :attr:`TagUpdate.memory` (repeated reads are skipped).
        """
        mem = memory or TagMemory()
        res = self._update(state, t, tags, mem)
        used = {sid for d in res.diagnostics if d.accepted for sid in d.source.split(",") if sid}
        last = dict(mem.last_used)
        last.update(dict.fromkeys(used, float(t)))
        return TagUpdate(res.state, res.diagnostics, res.strategy, res.correction_m,
                         TagMemory(last))

    def update_ids(self, state: FilterState, *, t: float, ids: list[str],
                   landmarks: dict[str, Landmark], memory: TagMemory | None = None
                   ) -> TagUpdate:
        """:meth:`update` from tag ids; ids without a positioned landmark are skipped."""
        known = [landmarks[i] for i in ids
                 if i in landmarks and landmarks[i].position is not None]
        missing = [skipped("tag", t, "tag without a known position", i) for i in ids
                   if i not in landmarks or landmarks[i].position is None]
        if not known:
            return TagUpdate(state, missing, -1, 0.0, memory or TagMemory())
        res = self.update(state, t=t, tags=known, memory=memory)
        return TagUpdate(res.state, missing + res.diagnostics, res.strategy, res.correction_m,
                         res.memory)

    def _update(self, state: FilterState, t: float, tags: list[Landmark],
                mem: TagMemory) -> TagUpdate:
        prm = self.params
        fresh = [lm for lm in tags
                 if lm.id not in mem.last_used
                 or t - mem.last_used[lm.id] >= prm.repeat_interval_s]
        if not fresh:
            source = ",".join(lm.id for lm in tags)
            why = "repeated read" if tags else "no tag"
            return TagUpdate(state, [skipped("tag", t, why, source)], -1, 0.0)
        tags = fresh
        source = ",".join(lm.id for lm in tags)
        centres, w = self._lobes(tags)
        p_xy = state.x[:2]
        dist = np.linalg.norm(centres - p_xy, axis=1)
        if float(np.min(dist)) > prm.max_correction_m:
            return TagUpdate(state, [rejected("tag", t, f"lobe {np.min(dist):.1f} m away from "
                                              "the estimate", source)], -1, 0.0)
        sig2 = (prm.sigma_per_accuracy * w) ** 2          # per-axis variance of each lobe
        if prm.strategy == "kalman":
            return self._kalman(state, t, tags, centres, sig2)
        omega = (1.0 / w**2) / np.sum(1.0 / w**2)
        inside = dist <= w
        p = state.P
        x = state.x.copy()
        lobe_info = np.eye(2) * float(np.sum(1.0 / sig2))
        r_floor = np.linalg.inv(lobe_info)                # (sum R_i^-1)^-1
        if len(tags) == 1:
            r_i = np.eye(2) * sig2[0]
            if not inside[0]:                             # strategy 1, eq. 4.26
                x[:2] = centres[0]
                new_p = independent_block(p, XY, r_i)
                strategy = 1
            else:                                         # strategy 2, eq. 4.27
                strategy = 2
                keep = np.trace(p[:2, :2]) < np.trace(r_i)
                new_p = p if keep else independent_block(p, XY, r_i)
        else:
            t_bar = omega @ centres
            dev = centres - t_bar
            spread = (dev * omega[:, None]).T @ dev
            c_tags = symmetrize(spread + r_floor)
            if not np.any(inside):                        # strategy 3, eq. 4.28
                strategy = 3
                x[:2] = t_bar
                new_p = independent_block(p, XY, c_tags)
            else:                                         # strategy 4, eq. 4.29-4.33
                strategy = 4
                delta = t_bar - p_xy
                s = symmetrize(c_tags + np.outer(delta, delta))          # eq. 4.33
                gain = c_tags @ np.linalg.inv(s)                          # eq. 4.31-4.32
                x[:2] = p_xy + gain @ delta                               # eq. 4.29
                p_xy_cov = p[:2, :2]
                if np.trace(p_xy_cov) < np.trace(s):                      # eq. 4.30
                    block = p_xy_cov
                else:
                    block = symmetrize(p_xy_cov - gain @ s @ gain.T)
                    if not is_spd(block):
                        block = symmetrize(np.linalg.inv(np.linalg.inv(p_xy_cov)
                                                         + np.linalg.inv(c_tags)))
                new_p = independent_block(p, XY, block)
        moved = float(np.linalg.norm(x[:2] - p_xy))
        diag = UpdateDiagnostics("tag", t, "accepted", dof=2, innovation=x[:2] - p_xy,
                                 source=source, reason=f"strategy {strategy}")
        # the blocks above are symmetric PSD by construction (and checked in strategy 4), the
        # heading is untouched: only finiteness is checked (FilterState.from_kernel)
        new_state = FilterState.from_kernel(state.t, x, symmetrize(new_p),
                                            state.input_heading_rad, state.has_input_heading,
                                            state.reference_pending)
        return TagUpdate(new_state, [diag], strategy, moved)

    def _kalman(self, state: FilterState, t: float, tags: list[Landmark], centres: FloatArray,
                sig2: FloatArray) -> TagUpdate:
        h = np.zeros((2, N_STATE))
        h[0, 0] = h[1, 1] = 1.0
        diags: list[UpdateDiagnostics] = []
        start = state.x[:2].copy()
        for lm, c, v in zip(tags, centres, sig2, strict=True):
            res = kalman_update(state.x, state.P, h, np.eye(2) * v, c - state.x[:2],
                                gate_probability=self.params.gate_probability, kind="tag", t=t,
                                source=lm.id, angle_index=IH)
            # Joseph form, symmetrized, heading wrapped: only finiteness needs checking
            state = FilterState.from_kernel(state.t, res.x, res.P, state.input_heading_rad,
                                            state.has_input_heading, state.reference_pending)
            diags.append(res.diagnostics)
        return TagUpdate(state, diags, 0, float(np.linalg.norm(state.x[:2] - start)))


def group_detections(tags: TagDetections, window_s: float) -> list[tuple[float, list[str]]]:
    """Group reads closer than ``window_s`` to the first read of the group.

    Returns ``(time of the last read, unique tag ids in order of first read)`` per group.
    """
    w = finite_scalar(window_s, where="group_detections window_s", non_negative=True)
    groups: list[tuple[float, list[str]]] = []
    i = 0
    n = len(tags)
    while i < n:
        t0 = float(tags.t[i])
        j = int(np.searchsorted(tags.t, t0 + w, side="right"))
        j = max(j, i + 1)
        ids = list(dict.fromkeys(str(s) for s in tags.tag[i:j]))
        groups.append((float(tags.t[j - 1]), ids))
        i = j
    return groups


def bearing_heading_correction(state: FilterState, bearings_rad: ArrayLike, *,
                               deadband_rad: float = math.radians(5.0),
                               gate_rad: float = math.radians(45.0),
                               sigma_rad: float = math.radians(5.0),
                               mode: Literal["replace", "kalman"] = "replace",
                               gate_probability: float | None = 0.999,
                               t: float | None = None, source: str = "") -> HeadingCorrection:
    """Heading correction from a landmark's bearings (Inderst eq. 4.21-4.22).

    Parameters
    ----------
    state:
        Filter state (its heading is corrected).
    bearings_rad:
        Directions of travel through the landmark, rad (ENU, CCW from east).
    deadband_rad:
        ``epsilon_phi`` of eq. 4.22: smaller differences are left alone.
    gate_rad:
        Larger differences are rejected (not associated).
    sigma_rad:
        1-sigma of a bearing: the heading variance after ``"replace"``, the measurement noise
        in ``"kalman"``.
    mode:
        ``"replace"`` (eq. 4.22) or ``"kalman"``.
    gate_probability:
        NIS gate in ``"kalman"`` mode.
    t, source:
        For the diagnostics.
    """
    tt = state.t if t is None else float(t)
    b = np.atleast_1d(np.asarray(bearings_rad, dtype=np.float64))
    if b.size == 0:
        return HeadingCorrection(state, skipped("bearing", tt, "landmark has no bearing", source),
                                 0.0)
    if not np.all(np.isfinite(b)):
        raise InputError("non-finite bearing", where=f"bearings of {source or 'landmark'}",
                         expected="finite angles in rad")
    heading = state.heading
    diffs = wrap_angle(b - heading)
    k = int(np.argmin(np.abs(diffs)))                    # eq. 4.21
    err = float(diffs[k])
    if abs(err) < deadband_rad:                          # eq. 4.22, first branch
        return HeadingCorrection(state, skipped("bearing", tt, "heading within the deadband",
                                                source), 0.0)
    if abs(err) > gate_rad:
        return HeadingCorrection(state, rejected("bearing", tt, "no bearing near the heading",
                                                 source), 0.0)
    if mode == "replace":                                # eq. 4.22, second branch
        x = state.x.copy()
        x[IH] = float(wrap_angle(b[k]))
        p = independent_block(state.P, [IH], np.array([[sigma_rad**2]]))
        diag = UpdateDiagnostics("bearing", tt, "accepted", dof=1, innovation=np.array([err]),
                                 source=source, reason="replaced by the nearest bearing")
        return HeadingCorrection(state.evolve(x=x, P=p), diag, err)
    if mode != "kalman":
        raise InputError(f"mode {mode!r}", where="bearing_heading_correction",
                         expected="'replace' or 'kalman'")
    new, diag = heading_update(state, err, sigma_rad**2, kind="bearing", t=tt,
                               gate_probability=gate_probability, source=source)
    return HeadingCorrection(new, diag, float(wrap_angle(new.heading - heading)))
