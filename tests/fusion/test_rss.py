from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from hrtls.data.landmarks import Landmark
from hrtls.data.observations import RssReadings
from hrtls.data.session import ChannelModel
from hrtls.errors import InputError
from hrtls.fusion.channel import ChannelEstimator, ChannelState
from hrtls.fusion.gating import is_spd
from hrtls.fusion.path_loss import PathLossModel
from hrtls.fusion.rss import (
    rss_update,
    update_rss_readings,
)
from hrtls.fusion.rss_scans import RssScan, group_scans, hyperbolic_wls, scan_table
from hrtls.fusion.state import FilterState

GRID = np.array([[x, y] for x in (0.0, 10.0, 20.0) for y in (0.0, 10.0, 20.0)])
LANDMARKS = {f"a{i}": Landmark(id=f"a{i}", kind="anchor", position=(a[0], a[1], 0.0))
             for i, a in enumerate(GRID)}
TRUE = PathLossModel(a_dbm=-60.0, eta=2.5, sigma_db=5.0)


def test_path_loss_roundtrip() -> None:
    d = np.array([0.5, 1.0, 3.0, 25.0])
    np.testing.assert_allclose(TRUE.distance(TRUE.expected_rss(d)), d)
    assert float(TRUE.expected_rss(1.0)) == -60.0
    assert TRUE.sigma_ln == pytest.approx(5.0 * np.log(10) / 25.0)
    np.testing.assert_allclose(TRUE.distance_sigma(-80.0), TRUE.distance(-80.0) * TRUE.sigma_ln)
    m = PathLossModel.from_channel(ChannelModel(a_dbm=-50, eta=3.0, sigma_db=2.0))
    assert m.eta == 3.0


@settings(max_examples=100, deadline=None)
@given(st.integers(3, 8), st.integers(0, 10_000))
def test_wls_exact_with_noiseless_distances(n: int, seed: int) -> None:
    rng = np.random.default_rng(seed)
    anchors = rng.uniform(-30, 30, (n, 2))
    centred = anchors - anchors.mean(axis=0)
    sv = np.linalg.svd(centred, compute_uv=False)
    assume(sv[-1] > 3.0)                                   # not (nearly) collinear
    p = rng.uniform(-25, 25, 2)
    d = np.linalg.norm(anchors - p, axis=1)
    assume(np.all(d > 0.1))
    fix = hyperbolic_wls(anchors, d)
    np.testing.assert_allclose(fix.xy, p, atol=1e-6 * max(1.0, float(np.max(d))))
    assert is_spd(fix.cov)


def test_wls_covariance_matches_monte_carlo() -> None:
    rng = np.random.default_rng(5)
    p = np.array([7.0, 12.0])
    d = np.linalg.norm(GRID - p, axis=1)
    sigma_ln = 0.02
    est = np.array([hyperbolic_wls(GRID, d * np.exp(rng.normal(0, sigma_ln, 9)),
                                   sigma_ln=sigma_ln).xy for _ in range(800)])
    fix = hyperbolic_wls(GRID, d, sigma_ln=sigma_ln)
    emp = np.cov(est.T)
    assert np.trace(emp) == pytest.approx(np.trace(fix.cov), rel=0.25)
    np.testing.assert_allclose(est.mean(axis=0), p, atol=0.05)


def test_wls_bad_geometry() -> None:
    with pytest.raises(InputError, match="at least 3"):
        hyperbolic_wls(GRID[:2], [1.0, 2.0])
    line = np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]])
    with pytest.raises(InputError, match="collinear"):
        hyperbolic_wls(line, [1.0, 1.0, 1.5])


def test_group_scans_average_and_unknown() -> None:
    rss = RssReadings(np.array([0.1, 0.2, 0.3, 0.4, 2.5]),
                      np.array(["a0", "a0", "zz", "a1", "a0"]),
                      np.array([-70.0, -72.0, -60.0, -99.0, -65.0]))
    scans = group_scans(rss, LANDMARKS, window_s=2.0, sensitivity_dbm=-95.0, t_origin=0.0)
    assert len(scans) == 2
    assert scans[0].anchor == ["a0"] and scans[0].rss_dbm[0] == pytest.approx(-71.0)
    assert scans[0].unknown == ["zz"] and scans[0].t == pytest.approx(0.3)
    assert scans[1].t == pytest.approx(2.5)


def test_rss_update_db_jacobian_and_convergence() -> None:
    rng = np.random.default_rng(2)
    p_true = np.array([6.0, 13.0])
    s = FilterState.initial(xyz=(10.0, 10.0, 0.0), sigma_xy_m=5.0)
    # Jacobian vs finite differences
    a = np.array([0.0, 0.0, 0.0])
    eps = 1e-6
    h0 = float(TRUE.expected_rss(np.hypot(10.0, 10.0)))
    hx = float(TRUE.expected_rss(np.hypot(10.0 + eps, 10.0)))
    upd = rss_update(s, a, h0 + 1.0, TRUE, gate_probability=None)
    s_cov = float(upd.diagnostics.innovation_cov[0, 0])
    num = (hx - h0) / eps
    assert s_cov == pytest.approx(num**2 * 25.0 + num**2 * 25.0 + 25.0, rel=1e-4)
    diags = []
    for _ in range(300):
        i = int(rng.integers(9))
        z = float(TRUE.expected_rss(np.linalg.norm(p_true - GRID[i]))) + rng.normal(0, 5.0)
        upd = rss_update(s, LANDMARKS[f"a{i}"].xyz(), z, TRUE)
        s = upd.state
        diags.append(upd.diagnostics)
    assert np.linalg.norm(s.x[:2] - p_true) < 1.5
    assert is_spd(s.P)
    rng_upd = rss_update(s, LANDMARKS["a0"].xyz(), -80.0, TRUE, domain="range")
    assert rng_upd.diagnostics.kind == "rss"


def test_channel_estimator_converges() -> None:
    rng = np.random.default_rng(3)
    est = ChannelEstimator()
    cs = est.start(PathLossModel(a_dbm=-50.0, eta=2.0, sigma_db=4.0))
    pts = rng.uniform(0, 20, (3000, 2))
    idx = rng.integers(0, 9, 3000)
    d = np.linalg.norm(pts - GRID[idx], axis=1)
    z = TRUE.expected_rss(d) + rng.normal(0, 5.0, d.size)
    cs, used = est.update(cs, rss_dbm=z, distance_m=d)
    assert used == int(np.sum(d >= 1.0))
    assert cs.theta[0] == pytest.approx(-60.0, abs=1.0)
    assert cs.theta[1] == pytest.approx(2.5, abs=0.1)
    assert np.sqrt(cs.residual_var_db2) == pytest.approx(5.0, abs=0.6)
    again = ChannelState.from_dict(json.loads(json.dumps(cs.to_dict())))
    np.testing.assert_array_equal(again.theta, cs.theta)
    # with the distance taken to a noisy position estimate the estimate stays close
    cs2 = est.start(PathLossModel(a_dbm=-50.0, eta=2.0, sigma_db=4.0))
    noisy = pts + rng.normal(0, 0.5, pts.shape)
    d2 = np.linalg.norm(noisy - GRID[idx], axis=1)
    cs2, _ = est.update(cs2, rss_dbm=z, distance_m=d2, distance_var_m2=0.25)
    assert cs2.theta[0] == pytest.approx(-60.0, abs=2.0)
    assert cs2.theta[1] == pytest.approx(2.5, abs=0.25)


def test_channel_estimator_robust_to_outliers_and_far_readings() -> None:
    """Far readings with outliers and poor distances must not drive A/eta away (IPIN Trial23)."""
    rng = np.random.default_rng(11)
    n = 300
    d = rng.uniform(13.0, 24.0, n)
    z = -75.0 - 12.5 * np.log10(d) + rng.normal(0.0, 5.0, n)
    z[::25] = -40.0
    d_est = d * rng.uniform(0.7, 1.3, n)
    est = ChannelEstimator()
    cs = est.start(PathLossModel(a_dbm=-59.0, eta=2.0, sigma_db=4.0))
    cs, used = est.update(cs, rss_dbm=z, distance_m=d_est, distance_var_m2=4.0)
    assert used == n
    assert -85.0 < cs.theta[0] < -65.0
    assert 1.0 <= cs.theta[1] < 2.0
    assert np.sqrt(cs.residual_var_db2) < 20.0


def test_channel_eta_clip_moves_a_consistently() -> None:
    """Clipping eta at its bound shifts A along the estimate's correlation."""
    est = ChannelEstimator()
    cs = est.start(PathLossModel(a_dbm=-59.0, eta=1.05, sigma_db=4.0))
    # readings much stronger than the prior predicts (-69.5 dBm at 10 m) pull eta below 1
    cs2, _ = est.update(cs, rss_dbm=[-50.0] * 5, distance_m=[10.0] * 5)
    assert cs2.theta[1] == 1.0
    # A absorbs what eta could not: the model predicts stronger readings at 10 m than before
    assert cs2.model().expected_rss(np.array([10.0]))[0] > -69.5 + 2.0
    assert cs2.cov[0, 1] > 0.0


def test_update_rss_readings_with_channel_estimation() -> None:
    rng = np.random.default_rng(4)
    p_true = np.array([12.0, 7.0])
    d = np.linalg.norm(p_true - GRID, axis=1)
    n = 400
    idx = rng.integers(0, 9, n)
    rss = RssReadings(np.arange(n) * 0.05, np.array([f"a{i}" for i in idx]),
                      TRUE.expected_rss(d[idx]) + rng.normal(0, 5.0, n))
    s = FilterState.initial(xyz=(11.0, 8.0, 0.0), sigma_xy_m=1.0)
    est = ChannelEstimator()
    wrong = PathLossModel(a_dbm=-55.0, eta=2.2, sigma_db=5.0)
    s2, diags, ch = update_rss_readings(s, rss, np.arange(n), LANDMARKS, wrong, estimator=est,
                                        channel=est.start(wrong))
    assert ch is not None and ch.count > 0
    assert len(diags) == n
    assert np.linalg.norm(s2.x[:2] - p_true) < 2.0
    skipped = update_rss_readings(s, RssReadings([0.0], ["nope"], [-70.0]), [0], LANDMARKS,
                                  TRUE)[1]
    assert skipped[0].status == "skipped"


def test_tight_variant_with_channel_reestimation() -> None:
    from hrtls.fusion.velocity_prediction import VelocityPredictionParams, VelocityPredictor

    rng = np.random.default_rng(0)
    fs, duration, r, v = 50.0, 80.0, 8.0, 1.0
    t = np.arange(1, int(duration * fs) + 1) / fs
    w = v / r
    truth = np.column_stack([10 + r * np.cos(w * t), 10 + r * np.sin(w * t)])
    tr = np.arange(0.4, duration, 0.4)
    pos = np.column_stack([10 + r * np.cos(w * tr), 10 + r * np.sin(w * tr)])
    d = np.linalg.norm(pos[:, None, :] - GRID[None], axis=2)
    rss = RssReadings(np.repeat(tr, 9), np.tile([f"a{i}" for i in range(9)], tr.size),
                      (TRUE.expected_rss(d) + rng.normal(0, 5.0, d.shape)).ravel())
    speed = v + rng.normal(0, 0.05, t.size)
    heading = w * t + np.pi / 2 + rng.normal(0, 0.02, t.size)
    wrong = PathLossModel(a_dbm=-52.0, eta=2.0, sigma_db=5.0)

    def run(model: PathLossModel, estimate: bool) -> tuple[float, ChannelState | None]:
        pred = VelocityPredictor(VelocityPredictionParams(heading_mode="state"))
        s = FilterState.initial(xyz=(18.0, 10.0, 0.0), heading_rad=np.pi / 2, sigma_xy_m=2.0,
                                sigma_heading_rad=0.1)
        est = ChannelEstimator() if estimate else None
        ch = est.start(model) if est is not None else None
        out = np.empty((t.size, 2))
        start = 0
        for k, stop in enumerate(np.searchsorted(t, tr, side="right")):
            res = pred.run(s, t[start:stop], speed[start:stop], heading[start:stop])
            s, out[start:stop] = res.state, res.xyz[:, :2]
            start = int(stop)
            s, _, ch = update_rss_readings(s, rss, np.arange(9 * k, 9 * k + 9), LANDMARKS,
                                           model if ch is None else ch.model(), estimator=est,
                                           channel=ch)
        res = pred.run(s, t[start:], speed[start:], heading[start:])
        out[start:] = res.xyz[:, :2]
        return float(np.mean(np.linalg.norm(out - truth, axis=1)[t > 20])), ch

    err_true, _ = run(TRUE, False)
    err_wrong, _ = run(wrong, False)
    err_est, ch = run(wrong, True)
    assert err_true < 1.0
    assert err_est < 1.0 < err_wrong
    assert ch is not None
    assert ch.theta[0] == pytest.approx(-60.0, abs=1.5)
    assert ch.theta[1] == pytest.approx(2.5, abs=0.15)


def test_wls_first_reference_as_in_the_paper() -> None:
    p = np.array([3.0, 14.0])
    d = np.linalg.norm(GRID - p, axis=1)
    fix = hyperbolic_wls(GRID, d, reference="first")
    assert fix.reference == 0
    np.testing.assert_allclose(fix.xy, p, atol=1e-9)
    with pytest.raises(InputError):
        hyperbolic_wls(GRID, d, reference="bogus")  # type: ignore[arg-type]


def reference_group_scans(rss: RssReadings, landmarks: dict[str, Landmark], *,
                          window_s: float, sensitivity_dbm: float = -95.0,
                          t_origin: float | None = None) -> list[RssScan]:
    """Per-window Python loop (the implementation before the vectorized scan table)."""
    t0 = float(rss.t[0]) if t_origin is None else float(t_origin)
    keep = rss.rss_dbm >= sensitivity_dbm
    tt, ids, vals = rss.t[keep], rss.anchor[keep], rss.rss_dbm[keep]
    if tt.size == 0:
        return []
    bins = np.floor((tt - t0) / window_s).astype(np.int64)
    scans: list[RssScan] = []
    for chunk in np.split(np.arange(tt.size), np.flatnonzero(np.diff(bins)) + 1):
        names, inv = np.unique(ids[chunk], return_inverse=True)
        sums = np.bincount(inv, weights=vals[chunk], minlength=len(names))
        counts = np.bincount(inv, minlength=len(names)).astype(np.float64)
        known, xyz, mean, cnt, unknown = [], [], [], [], []
        for k, name in enumerate(names):
            lm = landmarks.get(str(name))
            if lm is None or lm.position is None:
                unknown.append(str(name))
                continue
            known.append(str(name))
            xyz.append(lm.xyz())
            mean.append(sums[k] / counts[k])
            cnt.append(counts[k])
        scans.append(RssScan(float(tt[chunk[-1]]), known,
                             np.asarray(xyz, dtype=np.float64).reshape(-1, 3),
                             np.asarray(mean, dtype=np.float64), np.asarray(cnt), unknown))
    return scans


@settings(max_examples=60, deadline=None)
@given(reads=st.lists(st.tuples(st.floats(0.0, 3.0), st.sampled_from(
    ["a0", "a1", "a2", "a5", "zz", "yy"]), st.floats(-100.0, -40.0)), min_size=1, max_size=60),
       window=st.sampled_from([0.5, 1.0, 2.0]), origin=st.floats(-1.0, 0.0))
def test_scan_table_equals_reference(reads: list[tuple[float, str, float]], window: float,
                                     origin: float) -> None:
    reads = sorted(reads, key=lambda r: r[0])
    rss = RssReadings(np.array([r[0] for r in reads]), np.array([r[1] for r in reads]),
                      np.array([r[2] for r in reads]))
    ref = reference_group_scans(rss, LANDMARKS, window_s=window, t_origin=origin)
    got = group_scans(rss, LANDMARKS, window_s=window, t_origin=origin)
    table = scan_table(rss, LANDMARKS, window_s=window, t_origin=origin)
    assert len(table) == len(ref) == len(got)
    for a, b in zip(ref, got, strict=True):
        assert a.t == b.t and a.anchor == b.anchor and a.unknown == b.unknown
        np.testing.assert_array_equal(a.anchor_xyz, b.anchor_xyz)
        np.testing.assert_array_equal(a.rss_dbm, b.rss_dbm)      # same summation order
        np.testing.assert_array_equal(a.count, b.count)
