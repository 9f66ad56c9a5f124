"""The range-SLAM smoother's estimate of each rescuer's latest pose, given back to its tracker.

After a solve (:mod:`hrtls.mission.smoothing`, ``SmootherParams.feedback``, with cooperation:
it carries the nodes' and the other agents' information) the smoother holds,
for every agent, a marginal ``N(m_s, P_s)`` of its position at its latest row ``t_a`` (the
last pose of its chain; ``P_s`` the 2x2 block of the inverse information times
``feedback_cov_scale``). The tracker's row there is ``N(m_f, P_f)``; its state ``x`` (position
first, then e.g. height and heading) has covariance ``P``. The smoother's information holds the
tracker's (its dead reckoning as the chain, its corrections as factors) plus the ranges to the
nodes and the other agents' paths through them, so two ways are consistent:

* ``"implied"``: the measurement ``(z, R)`` that turns ``(m_f, P_f)`` into ``(m_s, P_s)``,
  ``R^-1 = P_s^-1 - P_f^-1``, ``R^-1 (z - m_f) = P_s^-1 (m_s - m_f)``
  (:func:`hrtls.mission.correction_factors.implied_factors`; negative eigenvalues of ``R^-1``,
  directions where the smoother is less sure than the tracker, set to zero), applied to the
  whole state as a position measurement (:func:`position_update`): the heading moves through
  the tracker's cross-covariance and the covariance never grows; not applied when its NIS
  (:func:`nis`) exceeds ``feedback_gate``. For a tracker that holds the
  same linear-Gaussian information the position marginal becomes exactly ``N(m_s, P_s)``. It
  gives nothing where the smoother's chain (looser than the tracker's motion model) claims less
  than the tracker.
* ``"replace"``: the position set to ``m_s`` and the state's covariance to ``T P T^T`` with
  ``T = diag(A, I)``, ``A = L_s L_f^-1`` (``L`` the Cholesky factors of ``P_s`` and of the
  tracker's position block): the position block becomes ``P_s``, the position-heading
  cross-covariance ``A P_ph`` (``P`` stays positive semi-definite), the heading is unchanged
  (:func:`replacement`). The covariance may grow.

Applied to the tracker's state now; if it moved since ``t_a`` (its motion since is its own),
the target moves with it (``z + x_now - m_f``; replace: ``m_s + x_now - m_f`` and ``P_s + P_now
- P_f`` when positive definite). The superset argument is approximate (the chain is not the
tracker's motion model, a heading update's factor repeats some earlier information,
:mod:`hrtls.mission.correction_factors`); the covariance scale and the gate are chosen on dev
seeds (docs/mission.md). A robot (``SmootherParams.robots`` "feedback") takes it the same
way, on its state ``[x, y, psi]`` (:meth:`hrtls.mission.robot.RobotTracker.set_smoothed`).

No information counted twice: the jump is recorded as a correction of kind
:data:`~hrtls.pipeline.corrections.SMOOTHED`, which the smoother removes from the dead
reckoning like any correction but takes as no factor (it is its own output).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from hrtls.mission.correction_factors import implied_factors
from hrtls.mission.graph import SmootherResult
from hrtls.mission.robot import RobotTracker
from hrtls.pipeline.tracker import Tracker

if TYPE_CHECKING:
    from hrtls.mission.tracker import MissionTracker

FloatArray = NDArray[np.float64]


def implied_update(mean_f_m: FloatArray, cov_f_m2: FloatArray, mean_s_m: FloatArray,
                   cov_s_m2: FloatArray) -> tuple[FloatArray, FloatArray]:
    """The position measurement ``z`` (2,), m, and whitening ``W`` (2, 2), 1/m (module doc)."""
    z, w = implied_factors(np.asarray(mean_f_m, np.float64)[None],
                           np.asarray(cov_f_m2, np.float64)[None],
                           np.asarray(mean_s_m, np.float64)[None],
                           np.asarray(cov_s_m2, np.float64)[None])
    return z[0], w[0]


def position_update(x: FloatArray, p: FloatArray, z_m: FloatArray, w_per_m: FloatArray
                    ) -> tuple[FloatArray, FloatArray]:
    """Kalman update of a state whose first two components are the position.

    The measurement is ``W x[:2] = W z + e``, ``e ~ N(0, I)`` (``W^T W`` its information on the
    position; a row of zeros: none). Joseph form; the new state and covariance.
    """
    n = len(x)
    h = np.zeros((2, n))
    h[:, :2] = w_per_m
    s = h @ p @ h.T + np.eye(2)
    k = np.linalg.solve(s, h @ p).T
    xn = x + k @ (w_per_m @ (np.asarray(z_m, np.float64) - x[:2]))
    ikh = np.eye(n) - k @ h
    pn = ikh @ p @ ikh.T + k @ k.T
    return xn, 0.5 * (pn + pn.T)


def replacement(x: FloatArray, p: FloatArray, mean_m: FloatArray, cov_m2: FloatArray
                ) -> tuple[FloatArray, FloatArray]:
    """The state with position ``mean_m`` and covariance ``T P T^T`` (module doc)."""
    n = len(x)
    a = np.linalg.cholesky(cov_m2) @ np.linalg.inv(np.linalg.cholesky(p[:2, :2]))
    t = np.eye(n)
    t[:2, :2] = a
    xn = np.asarray(x, np.float64).copy()
    xn[:2] = mean_m
    pn = t @ p @ t.T
    return xn, 0.5 * (pn + pn.T)


def nis(mean_f_m: FloatArray, cov_f_m2: FloatArray, z_m: FloatArray, w_per_m: FloatArray
        ) -> float:
    """NIS of the implied measurement, ``nu^T S^-1 nu``.

    ``nu = W (z - m_f)``, ``S = W P_f W^T + I``.
    """
    nu = w_per_m @ (np.asarray(z_m) - np.asarray(mean_f_m))
    return float(nu @ np.linalg.solve(w_per_m @ cov_f_m2 @ w_per_m.T + np.eye(2), nu))


def _target(m_f: FloatArray, p_f: FloatArray, m_s: FloatArray, p_s: FloatArray, x: FloatArray,
            p: FloatArray, mode: str, gate: float) -> tuple[FloatArray, FloatArray] | None:
    """The tracker's new state and covariance, or None when the smoother adds nothing."""
    if mode == "implied":
        z, w = implied_update(m_f, p_f, m_s, p_s)
        if not np.any(w) or nis(m_f, p_f, z, w) > gate:
            return None
        return position_update(x, p, z + x[:2] - m_f, w)
    moved = p_s + p[:2, :2] - p_f
    target = moved if np.all(np.linalg.eigvalsh(moved) > 0) else p_s
    return replacement(x, p, m_s + x[:2] - m_f, target)


def feed_back(mt: MissionTracker, res: SmootherResult) -> list[str]:
    """Give each rescuer (robot: ``robots`` "feedback") the smoother's latest row; those updated."""
    prm, st = mt.params.smoother, mt.smoother
    assert prm is not None and st is not None
    done: list[str] = []
    for name, (t_a, m_s, p_s) in sorted(res.last_pose.items()):
        tail = st.tail.get(name)
        tr = mt.trackers[name]
        robot = isinstance(tr, RobotTracker) and prm.robots == "feedback"
        if tail is None or tail[0] != t_a or not (isinstance(tr, Tracker) or robot) or \
                not np.all(np.isfinite(p_s)) or np.linalg.eigvalsh(p_s)[0] <= 0:
            continue
        m_f = np.asarray(tail[1:3], np.float64)
        x, p = (tr.x, tr.p) if isinstance(tr, RobotTracker) else \
            (tr.engine.state.x, tr.engine.state.P)
        new = _target(m_f, np.asarray(tail[3:7], np.float64).reshape(2, 2), m_s,
                      prm.feedback_cov_scale * p_s, x, p, prm.feedback, prm.feedback_gate)
        if new is not None and (tr.set_smoothed(*new) if isinstance(tr, RobotTracker)
                                else tr.engine.set_smoothed(*new)):
            done.append(name)
    return done
