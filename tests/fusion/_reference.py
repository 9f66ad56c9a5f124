"""Readable numpy versions of the compiled fusion functions, used as test oracles only.

Each mirrors an equation as written (matrices, no in-place expansion); the compiled functions
of ``hrtls.fusion`` must agree with them to rounding.
"""

from __future__ import annotations

import math

import numpy as np

from hrtls.data import Activity
from hrtls.frames import wrap_angle
from hrtls.fusion.step_prediction import FIRST_STRIDE_MAX_TURN_RAD, StepPredictionParams

LN10 = math.log(10.0)


def wrap(a: float) -> float:
    return float(wrap_angle(a))


def step_reference(prm: StepPredictionParams, x: np.ndarray, p: np.ndarray,
                   input_heading: float, has_input: bool, pending: bool, length: float,
                   heading: float, dz: float, act: int, var_h: float | None
                   ) -> tuple[np.ndarray, np.ndarray, float, bool, bool]:
    """Inderst eq. 4.23-4.25: ``P+ = F P F^T + R Qf R^T`` with matrices."""
    x = x.copy()
    p = p.copy()
    var = prm.sigma_heading_rad**2 if var_h is None else var_h
    if math.isfinite(heading):
        h_in = wrap(heading)
        if prm.heading_mode == "input":
            x[3] = h_in
            p[3, :] = 0.0
            p[:, 3] = 0.0
            p[3, 3] = var
        elif has_input:
            inc = wrap(h_in - input_heading)
            if pending and abs(inc) < FIRST_STRIDE_MAX_TURN_RAD:
                inc *= 0.5
            x[3] = wrap(x[3] + inc)
            p[3, 3] += prm.sigma_heading_increment_rad**2
        elif p[3, 3] > var:
            x[3] = h_in
            p[3, :] = 0.0
            p[:, 3] = 0.0
            p[3, 3] = var
        pending = not has_input
        input_heading, has_input = h_in, True
    x[3] = wrap(x[3])
    if act == int(Activity.STANDING):
        return x, p, input_heading, has_input, pending
    stairs = act in (int(Activity.UPSTAIRS), int(Activity.DOWNSTAIRS))
    if stairs and prm.stairs_from_model:
        horiz = prm.stair_depth_m
        vert = prm.stair_height_m if act == int(Activity.UPSTAIRS) else -prm.stair_height_m
    else:
        horiz, vert = length, dz
    c, s = math.cos(x[3]), math.sin(x[3])
    q_frame = (horiz**2 + vert**2) * np.diag([prm.q_along, prm.q_across, prm.q_vertical])
    f = np.eye(4)
    f[0, 3] = -horiz * s
    f[1, 3] = horiz * c
    rot = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    q = np.zeros((4, 4))
    q[:3, :3] = rot @ q_frame @ rot.T
    x[:3] += [horiz * c, horiz * s, vert]
    p = f @ p @ f.T + q
    return x, 0.5 * (p + p.T), input_heading, has_input, pending


def hyperbolic_wls_reference(a: np.ndarray, d: np.ndarray, sigma_ln: float, ref: int
                             ) -> tuple[np.ndarray, np.ndarray, float]:
    """Tarrio eq. 2 with explicit matrices (``S`` formed and solved).

    Returns the position, its covariance and the condition number of ``H^T S^-1 H`` (the
    position is NaN when the anchors are collinear: singular or condition above 1e12).
    """
    others = [i for i in range(len(d)) if i != ref]
    rel = a[others] - a[ref]
    h = 2.0 * rel
    b = np.sum(rel * rel, axis=1) - d[others] ** 2 + d[ref] ** 2
    s = np.diag(d[others] ** 4) + d[ref] ** 4
    info = h.T @ np.linalg.solve(s, h)
    w = np.linalg.eigvalsh(0.5 * (info + info.T))
    cond = float(w[1] / w[0]) if w[0] > 0.0 else math.inf
    if not cond <= 1e12:
        return np.full(2, np.nan), np.full((2, 2), np.nan), cond
    inv = np.linalg.inv(info)
    xy = inv @ (h.T @ np.linalg.solve(s, b)) + a[ref]
    cov = 4.0 * sigma_ln**2 * inv
    return xy, 0.5 * (cov + cov.T), cond


def channel_reference(theta: np.ndarray, cov: np.ndarray, res_var: float, rss: float, d: float,
                      dvar: float, *, forgetting: float, sigma_a: float, sigma_eta: float,
                      eta_bounds: tuple[float, float], d0: float = 1.0
                      ) -> tuple[np.ndarray, np.ndarray, float]:
    """One RLS reading with forgetting, vector form (skips are the caller's)."""
    phi = np.array([1.0, -10.0 * math.log10(d / d0)])
    e = float(rss - phi @ theta)
    slope = 10.0 * theta[1] / LN10
    s2 = res_var + slope**2 * dvar / d**2
    pphi = cov @ phi
    lim = 2.5 * math.sqrt(s2 + float(phi @ pphi))
    e = min(max(e, -lim), lim)
    k = pphi / (forgetting * s2 / res_var + float(phi @ pphi))
    theta = theta + k * e
    cov = (cov - np.outer(k, pphi)) / forgetting
    cov = 0.5 * (cov + cov.T)
    cap = sigma_a**2 + sigma_eta**2
    if np.trace(cov) > cap:
        cov = cov * (cap / np.trace(cov))
    eta_c = float(np.clip(theta[1], *eta_bounds))
    if eta_c != theta[1]:
        theta[0] += cov[0, 1] / cov[1, 1] * (eta_c - theta[1])
        theta[1] = eta_c
    return theta, cov, max(forgetting * res_var + (1.0 - forgetting) * e * e, 1e-6)
