"""A robot as a mission agent: wheel odometry plus ranges in one EKF (Inderst thesis Sec. 6.4).

A robot's session holds its odometry poses (``fixes``: positions integrated by the wheels, in a
frame aligned with the world at the start pose) and its ranges to nodes. The filter's state is
``[x, y, psi]``: the robot's position and the rotation ``psi`` of the odometry frame against the
world (the odometry's heading error; a random walk per metre driven). Each odometry displacement
``d`` (odometry frame) predicts (the discrete unicycle, eq. 6.2, with the heading from the wheels)

    p += R(psi) d,   P = F P F^T + Q,   F = I + [[0, 0, -(R d)_y], [0, 0, (R d)_x], [0, 0, 0]],
    Q = diag((f |d|)^2, (f |d|)^2, q_psi |d|)

and each range to a landmark with a position (the session's, or a node the mission gave with
:meth:`RobotTracker.set_landmarks`) corrects it as eq. 6.4 (scalar EKF update, Joseph form,
innovation gate); the mission smoother may set the state (:meth:`RobotTracker.set_smoothed`,
:mod:`hrtls.mission.feedback`).

With ``RobotTrackerParams.odometry_scale_sigma`` > 0 the state has a fourth component, the
wheels' scale error ``k`` (one for the run, prior ``N(0, sigma_k^2)``, no process noise):
``p += (1 + k) R(psi) d`` and ``F`` gains the column ``dp/dk = R(psi) d``. A scale error is
not white: over ``D`` metres driven straight it makes an along-track error ``k D`` (variance
``sigma_k^2 D^2``), which the per-displacement ``f |d|`` (variance ``f^2 |d| D``) does not cover.

A range to another agent (a peer, :meth:`RobotTracker.set_peers`, ``PeerRangeParams.rule``
"intersect") is taken by split covariance intersection (Julier & Uhlmann 1997; the split form:
Julier & Uhlmann 2001): the peer's position error (variance ``v`` along the line of sight) may
be correlated with the robot's whole state in any way, the range's own noise ``s^2`` is not::

    P_w = P / w,   R_w = s^2 + v / (1 - w),   K = P_w h / (h P_w h + R_w),
    P+ = (I - K h) P_w (I - K h)^T + K R_w K^T

which is consistent for every cross-covariance when ``P`` and ``v`` are; ``w`` minimizes
``det(P+)`` (:func:`intersect_weight`). The gate tests the innovation against ``h P h + s^2 +
v``. The per-event loop is a compiled kernel; :class:`RobotTracker`
has the part of :class:`hrtls.pipeline.Tracker`'s interface
:class:`~hrtls.mission.tracker.MissionTracker` uses.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hrtls.data import Session
from hrtls.data.landmarks import Landmark
from hrtls.data.results import StepEvents, Trajectory
from hrtls.errors import InputError
from hrtls.kernels import njit
from hrtls.pipeline.corrections import SMOOTHED, CorrectionLog, Corrections
from hrtls.pipeline.output import Estimates
from hrtls.pipeline.schedule import RANGE
from hrtls.pipeline.tracker import TrackResult

FloatArray = NDArray[np.float64]


@dataclass(frozen=True, kw_only=True)
class RobotTrackerParams:
    """Parameters of :class:`RobotTracker`.

    Attributes
    ----------
    odometry_fraction:
        1-sigma of a displacement's error per axis, as a fraction of its length.
    heading_var_per_m:
        Growth of the odometry-frame rotation variance per metre driven, rad^2 / m.
    gate_sigma:
        A range whose innovation exceeds this many sigmas is rejected (NLOS).
    odometry_scale_sigma:
        1-sigma of the wheels' scale error, one for the whole run (a state, module doc); 0
        (default): no such state.
    """

    odometry_fraction: float = 0.03
    heading_var_per_m: float = 1e-4
    gate_sigma: float = 4.0
    odometry_scale_sigma: float = 0.0

    def __post_init__(self) -> None:
        for name in ("odometry_fraction", "heading_var_per_m", "gate_sigma"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise InputError(f"{name} = {v}", where="RobotTrackerParams", expected="> 0")
        v = self.odometry_scale_sigma
        if not (math.isfinite(v) and v >= 0):
            raise InputError(f"odometry_scale_sigma = {v}", where="RobotTrackerParams",
                             expected=">= 0")


@njit(cache=True)
def robot_kernel(x: FloatArray, p: FloatArray, d_odo: FloatArray, t_odo: FloatArray,
                 t_rng: FloatArray, lm: FloatArray, r: FloatArray, s: FloatArray,
                 v: FloatArray, frac: float, q_psi: float, gate: float
                 ) -> tuple[FloatArray, FloatArray, NDArray[np.bool_], FloatArray]:
    """Odometry predictions and range updates in time order (module doc).

    The state is ``[x, y, psi]`` or, with the odometry scale, ``[x, y, psi, k]`` (module doc).
    Returns the state and covariance after each odometry event ``(n, d)``, ``(n, d, d)``,
    which ranges were accepted and, per range, ``[x, y, P00, P01, P11]`` before and after its
    update ``(m, 10)``; ``x``, ``p`` are updated in place. A range at the time of an odometry
    event is applied after it; ranges with a NaN landmark are skipped; a range whose landmark
    variance ``v`` is finite (a peer) is taken by covariance intersection.
    """
    n, m, nx = t_odo.shape[0], t_rng.shape[0], x.shape[0]
    xs = np.empty((n, nx))
    ps = np.empty((n, nx, nx))
    acc = np.zeros(m, dtype=np.bool_)
    around = np.empty((m, 10))
    j = 0
    for i in range(n):
        while j < m and t_rng[j] < t_odo[i]:
            acc[j] = _logged_update(x, p, lm[j], r[j], s[j], v[j], gate, around[j])
            j += 1
        c, sn = math.cos(x[2]), math.sin(x[2])
        g = 1.0 + x[3] if nx == 4 else 1.0
        rx = c * d_odo[i, 0] - sn * d_odo[i, 1]                  # R(psi) d
        ry = sn * d_odo[i, 0] + c * d_odo[i, 1]
        dx, dy = g * rx, g * ry
        x[0] += dx
        x[1] += dy
        f = np.eye(nx)
        f[0, 2] = -dy
        f[1, 2] = dx
        if nx == 4:
            f[0, 3] = rx
            f[1, 3] = ry
        pn = f @ p @ f.T
        dist = math.hypot(d_odo[i, 0], d_odo[i, 1])
        pn[0, 0] += (frac * dist) ** 2 + 1e-10
        pn[1, 1] += (frac * dist) ** 2 + 1e-10
        pn[2, 2] += q_psi * dist
        p[:, :] = 0.5 * (pn + pn.T)
        while j < m and t_rng[j] <= t_odo[i]:
            acc[j] = _logged_update(x, p, lm[j], r[j], s[j], v[j], gate, around[j])
            j += 1
        xs[i] = x
        ps[i] = p
    while j < m:
        acc[j] = _logged_update(x, p, lm[j], r[j], s[j], v[j], gate, around[j])
        j += 1
    return xs, ps, acc, around


@njit(cache=True)
def _logged_update(x: FloatArray, p: FloatArray, lm: FloatArray, r: float, s: float,
                   v: float, gate: float, around: FloatArray) -> bool:
    """:func:`_range_update` with the position and its covariance before and after."""
    for k, a in enumerate((x[0], x[1], p[0, 0], p[0, 1], p[1, 1])):
        around[k] = a
    ok = _range_update(x, p, lm, r, s, v, gate)
    for k, a in enumerate((x[0], x[1], p[0, 0], p[0, 1], p[1, 1])):
        around[5 + k] = a
    return ok


@njit(cache=True)
def intersect_weight(p: FloatArray, hrow: FloatArray, s2: float, v: float) -> float:
    """Covariance intersection's weight ``w`` in (0, 1] of a range to a peer (module doc).

    The state's ``P / w`` and the peer's variance ``v / (1 - w)`` along the line of sight, the
    range's own ``s2`` kept (split CI): the ``w`` of the grid ``k / 50`` whose posterior has the
    smallest determinant, ``det(P) w^-n R_w / S_w`` (matrix determinant lemma), ``R_w = s2 +
    v / (1 - w)``, ``S_w = h P h / w + R_w``, ``n`` the state's size; 1 (no update) when no
    ``w`` < 1 lowers it.
    """
    a = hrow @ p @ hrow
    n = p.shape[0]
    best_w, best = 1.0, 1.0
    for k in range(1, 50):
        w = k / 50.0
        r_w = s2 + v / (1.0 - w)
        f = r_w / (w ** n * (a / w + r_w))
        if f < best:
            best_w, best = w, f
    return best_w


@njit(cache=True)
def _range_update(x: FloatArray, p: FloatArray, lm: FloatArray, r: float, s: float,
                  v: float, gate: float) -> bool:
    if not (math.isfinite(lm[0]) and math.isfinite(lm[1])):
        return False
    ex, ey = x[0] - lm[0], x[1] - lm[1]
    h = math.hypot(ex, ey)
    if h < 1e-9:
        return False
    hrow = np.zeros(x.shape[0])
    hrow[0], hrow[1] = ex / h, ey / h
    innov = r - h
    ph = p @ hrow
    r2 = s * s + (v if math.isfinite(v) else 0.0)
    if innov * innov > gate * gate * (hrow @ ph + r2):
        return False
    pw = p
    if math.isfinite(v):
        w = intersect_weight(p, hrow, s * s, v)
        if w >= 1.0:
            return True
        pw = p / w                                               # P / w
        r2 = s * s + v / (1.0 - w)
        ph = pw @ hrow
    k = ph / (hrow @ ph + r2)
    x += k * innov
    ikh = np.eye(x.shape[0]) - np.outer(k, hrow)
    pn = ikh @ pw @ ikh.T + np.outer(k, k) * r2
    p[:, :] = 0.5 * (pn + pn.T)
    return True


_STATE_FIELDS = ("x", "p", "_last_odo", "_last_t", "_accepted", "_rejected", "_started")


class RobotTracker:
    """A robot's causal EKF, chunk by chunk (see module doc)."""

    def __init__(self, params: RobotTrackerParams | None = None) -> None:
        self.params = params or RobotTrackerParams()
        self.landmarks: dict[str, tuple[float, float]] = {}
        self.peers: dict[str, tuple[float, float, float]] = {}
        self._rows: list[tuple[FloatArray, FloatArray, FloatArray]] = []
        self._corr = CorrectionLog()
        self._accepted = 0
        self._rejected = 0
        self._started = False

    def start_session(self, session: Session) -> None:
        """Start at the session's start pose; its landmarks with a position are known."""
        sp = session.meta.start_pose
        if sp is None or session.fixes is None or len(session.fixes.t) < 2:
            raise InputError("a robot session needs a start pose and odometry poses",
                             where="robot session", expected="meta.start_pose and fixes.csv")
        var = [sp.sigma_xy_m ** 2, sp.sigma_xy_m ** 2, sp.sigma_heading_rad ** 2]
        k = self.params.odometry_scale_sigma
        self.x = np.zeros(4 if k > 0 else 3)
        self.x[:2] = sp.x, sp.y
        self.p = np.diag(var + ([k * k] if k > 0 else []))
        self._last_odo = np.asarray(session.fixes.xyz[0, :2], dtype=np.float64).copy()
        self._last_t = -math.inf
        self.set_landmarks({k: lm for k, lm in session.landmarks.items()
                            if lm.position is not None})
        self._started = True

    def set_landmarks(self, landmarks: dict[str, Landmark]) -> None:
        """Add or replace landmarks (their local position) from now on."""
        for k, lm in landmarks.items():
            if lm.position is not None:
                self.landmarks[k] = (float(lm.position[0]), float(lm.position[1]))

    def set_peers(self, peers: dict[str, tuple[float, float, float]]) -> None:
        """Peers as range anchors from now on, ``(x, y, variance)`` in m and m^2.

        A range to one is taken by covariance intersection (its error correlated with the
        robot's, module doc).
        """
        self.peers.update(peers)

    def update_landmarks(self, versions: Sequence[Landmark]) -> None:
        """New versions of landmarks from now on; a destroyed one is no range anchor any more."""
        for v in versions:
            if v.status == "destroyed":
                self.landmarks.pop(v.id, None)
        self.set_landmarks({v.id: v for v in versions if v.status != "destroyed"})

    def update(self, chunk: Session) -> None:
        """Feed one chunk: its odometry poses and ranges (times after the previous chunk's)."""
        if not self._started:
            raise InputError("update() before start_session()", where="RobotTracker",
                             expected="start_session() first")
        t_odo = np.zeros(0)
        d = np.zeros((0, 2))
        if chunk.fixes is not None:
            keep = chunk.fixes.t > self._last_t
            t_odo = np.asarray(chunk.fixes.t[keep], dtype=np.float64)
            xy = np.asarray(chunk.fixes.xyz[keep, :2], dtype=np.float64)
            if len(t_odo):
                d = np.diff(np.vstack([self._last_odo, xy]), axis=0)
                self._last_odo = xy[-1].copy()
                self._last_t = float(t_odo[-1])
        rg = chunk.ranges
        t_r = np.zeros(0) if rg is None else np.asarray(rg.t, dtype=np.float64)
        lm = np.full((len(t_r), 2), np.nan)
        r = np.zeros(len(t_r)) if rg is None else np.asarray(rg.range_m, dtype=np.float64)
        s = np.ones(len(t_r))
        v = np.full(len(t_r), np.nan)
        if rg is not None:
            s = np.where(np.isfinite(rg.sigma_m), rg.sigma_m, 0.1)
            for k, node in enumerate(rg.node.tolist()):
                if str(node) in self.peers:
                    lm[k, 0], lm[k, 1], v[k] = self.peers[str(node)]
                elif str(node) in self.landmarks:
                    lm[k] = self.landmarks[str(node)]
        prm = self.params
        xs, ps, acc, around = robot_kernel(self.x, self.p, d, t_odo, t_r, lm, r, s, v,
                                           prm.odometry_fraction, prm.heading_var_per_m,
                                           prm.gate_sigma)
        if acc.any():
            assert rg is not None
            self._corr.add_block(t_r[acc], np.full(int(acc.sum()), RANGE), rg.node[acc],
                                 around[acc, :5], around[acc, 5:])
        tried = int(np.count_nonzero(np.isfinite(lm[:, 0])))
        self._accepted += int(np.count_nonzero(acc))
        self._rejected += tried - int(np.count_nonzero(acc))
        if len(t_odo):
            self._rows.append((t_odo, xs, ps))

    def set_smoothed(self, x: FloatArray, p: FloatArray) -> bool:
        """The state and covariance now set from outside (the mission smoother's feedback).

        Recorded as a ``SMOOTHED`` correction at the latest row, which takes the new state
        (False before the first row).
        """
        if not self._rows:
            return False
        t, xs, ps = self._rows[-1]
        self._corr.add(float(t[-1]), SMOOTHED, "smoother", self.x, self.p, x, p)
        self.x = np.asarray(x, np.float64).copy()
        self.p = np.asarray(p, np.float64).copy()
        xs, ps = xs.copy(), ps.copy()
        xs[-1], ps[-1] = self.x, self.p
        self._rows[-1] = (t, xs, ps)
        return True

    def _all(self) -> tuple[FloatArray, FloatArray, FloatArray]:
        if len(self._rows) > 1:
            self._rows = [(np.concatenate([r[0] for r in self._rows]),
                           np.concatenate([r[1] for r in self._rows]),
                           np.concatenate([r[2] for r in self._rows]))]
        if not self._rows:
            return np.zeros(0), np.zeros((0, 3)), np.zeros((0, 3, 3))
        return self._rows[0]

    def state(self) -> dict[str, Any]:
        """A started tracker's state as plain values and arrays (:mod:`hrtls.mission.snapshot`)."""
        return {"robot": {k: getattr(self, k) for k in _STATE_FIELDS},
                "params": dataclasses.asdict(self.params), "landmarks": dict(self.landmarks),
                "peers": dict(self.peers),
                "rows": list(self._all()), "corr_count": self._corr.count()}

    @classmethod
    def from_state(cls, d: dict[str, Any]) -> RobotTracker:
        """The tracker of :meth:`state` values."""
        tr = cls(RobotTrackerParams(**d["params"]))
        tr.load_state(d)
        return tr

    def load_state(self, d: dict[str, Any]) -> None:
        """Take the EKF state, landmarks and rows of :meth:`state` values (same parameters)."""
        for k, v in d["robot"].items():
            setattr(self, k, v)
        self.landmarks = {k: (float(v[0]), float(v[1])) for k, v in d["landmarks"].items()}
        self.peers = {k: (float(v[0]), float(v[1]), float(v[2]))
                      for k, v in d.get("peers", {}).items()}
        self._rows = [tuple(d["rows"])] if len(d["rows"][0]) else []
        self._corr = CorrectionLog(int(d.get("corr_count", 0)))

    def corrections_since(self, index: int = 0) -> Corrections:
        """The accepted ranges' position changes from record ``index`` on (as the rescuers')."""
        return self._corr.since(index)

    def estimates_since(self, t_after_s: float = -math.inf) -> Estimates:
        """Rows with time > ``t_after_s`` (every row is final)."""
        t, xs, ps = self._all()
        i = int(np.searchsorted(t, t_after_s, side="right"))
        t, xs, ps = t[i:], xs[i:], ps[i:]
        n = len(t)
        xyz = np.column_stack([xs[:, :2], np.zeros(n)])
        return Estimates(t, xyz, xs[:, 2].copy(), ps[:, :2, :2].copy(), ps[:, 2, 2].copy(),
                         np.zeros(n, dtype=np.int64), np.full(n, np.inf),
                         np.zeros(n, dtype=np.int64))

    def finish(self) -> TrackResult:
        """The robot's track (rows at its odometry poses) and a short report."""
        est = self.estimates_since()
        traj = Trajectory(est.t, est.xyz, est.heading_rad, est.cov_xy, est.var_heading,
                          est.activity)
        z = np.zeros(0)
        steps = StepEvents(z, z, z, z, z, np.zeros(0, dtype=np.int64), z, z, z)
        dist = float(np.sum(np.hypot(*np.diff(est.xyz[:, :2], axis=0).T))) if len(est) > 1 \
            else 0.0
        report: dict[str, Any] = {
            "summary": {"steps": 0, "distance_walked_m": dist, "filter": "robot EKF"},
            "corrections": {"range": {"accepted": self._accepted, "rejected": self._rejected}}}
        return TrackResult(traj, steps, None, [], report)
