"""Offline forward-backward smoother of the grid density (``[offline] grid_smoother``)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

from hrtls.errors import InputError
from hrtls.fusion.path_loss import PathLossModel
from hrtls.fusion.rss_grid import GridGeometry, GridParams, GridScans, RssGridFilter, causal_scans
from hrtls.fusion.rss_grid_kernels import shift, shift_adjoint
from hrtls.fusion.rss_grid_smoother import FixedLag, GridRecord, check_smoothable, smooth_rows

ANCHORS = np.array([[0.0, 0.0], [12.0, 0.0], [0.0, 8.0], [12.0, 8.0], [6.0, 4.0]])
MODEL = PathLossModel(sigma_db=3.0)


def _shift_matrix(ny: int, nx: int, sx: float, sy: float) -> np.ndarray:
    """The bilinear shift as a matrix on flattened cells (mass leaving the grid dropped)."""
    m = np.zeros((ny * nx, ny * nx))
    ix, iy = math.floor(sx), math.floor(sy)
    fx, fy = sx - ix, sy - iy
    for i in range(ny):
        for j in range(nx):
            for di, wy in ((0, 1.0 - fy), (1, fy)):
                for dj, wx in ((0, 1.0 - fx), (1, fx)):
                    ii, jj = i + iy + di, j + ix + dj
                    if 0 <= ii < ny and 0 <= jj < nx:
                        m[ii * nx + jj, i * nx + j] += wy * wx
    return m


def _blur_matrix(ny: int, nx: int, sigma: float) -> np.ndarray:
    """The separable Gaussian (weights of the whole kernel, truncated at 3 sigma) as a matrix."""
    if sigma <= 1e-6:
        return np.eye(ny * nx)
    h = math.ceil(3.0 * sigma)
    w = np.exp(-0.5 * (np.arange(-h, h + 1) / sigma) ** 2)
    w /= w.sum()

    def axis(n: int) -> np.ndarray:
        return np.array([[w[k - i + h] if abs(k - i) <= h else 0.0 for k in range(n)]
                         for i in range(n)])

    return np.kron(axis(ny), axis(nx))


def _reference(kept: np.ndarray, moved: np.ndarray, sigma_cells: float) -> np.ndarray:
    """Smoothed densities by eq. 1-2 with explicit transition matrices (slow, readable)."""
    n, ny, nx = kept.shape
    f = kept.reshape(n, -1).astype(np.float64)
    s = np.empty_like(f)
    s[-1] = f[-1] / f[-1].sum()
    for k in range(n - 2, -1, -1):
        vx, vy, dt = moved[k + 1]
        t = _blur_matrix(ny, nx, sigma_cells * math.sqrt(dt)) @ _shift_matrix(ny, nx, vx * dt,
                                                                                vy * dt)
        pred = t @ f[k]
        pred /= pred.sum()
        ratio = np.divide(s[k + 1], pred, out=np.zeros_like(pred), where=pred > 0.0)
        s[k] = f[k] * (t.T @ ratio)
        s[k] /= s[k].sum()
    return s.reshape(n, ny, nx)


def _moments(d: np.ndarray, g: GridGeometry) -> tuple[np.ndarray, np.ndarray]:
    x, y = g.centres()
    xx, yy = np.meshgrid(x, y)
    m = np.array([(d * xx).sum(), (d * yy).sum()])
    dx, dy = xx - m[0], yy - m[1]
    return m, np.array([[(d * dx * dx).sum(), (d * dx * dy).sum()],
                        [(d * dx * dy).sum(), (d * dy * dy).sum()]])


@settings(max_examples=30, deadline=None)
@given(st.integers(2, 6), st.integers(2, 7), st.integers(1, 5), st.integers(0, 2 ** 31 - 1),
       st.floats(0.0, 2.0))
def test_backward_kernel_matches_the_matrix_reference(ny: int, nx: int, n: int, seed: int,
                                                      sigma_cells: float) -> None:
    rng = np.random.default_rng(seed)
    kept = rng.random((n, ny, nx)) ** 3
    kept /= kept.sum(axis=(1, 2), keepdims=True)
    kept = kept.astype(np.float32)
    # shifts below a cell: some mass stays on the grid (else the forward shift is the identity)
    moved = np.column_stack([rng.uniform(-1.9, 1.9, (n, 2)), rng.uniform(0.05, 0.5, n)])
    g = GridGeometry(1.0, -2.0, 1.0, nx, ny)            # 1 m cells: velocities in cells/s
    want = _reference(kept, moved, sigma_cells)
    params = GridParams(sigma_speed_m_per_sqrt_s=sigma_cells)
    got = kept.copy()
    rows = smooth_rows(np.arange(n, dtype=np.float64), got, moved, geometry=g, params=params)
    np.testing.assert_allclose(got, want, atol=2e-6)     # kept overwritten by the smoothed
    np.testing.assert_allclose(got.sum(axis=(1, 2)), 1.0, atol=1e-5)
    for k in range(n):
        m, c = _moments(want[k], g)
        np.testing.assert_allclose(rows.mean_xy[k], m, atol=1e-5)
        np.testing.assert_allclose(rows.cov_xy[k], c, atol=1e-5)


@settings(max_examples=30, deadline=None)
@given(st.integers(2, 8), st.integers(2, 8), st.floats(-4.0, 4.0), st.floats(-4.0, 4.0),
       st.integers(0, 2 ** 31 - 1))
def test_shift_adjoint_is_the_transpose_of_the_shift(ny: int, nx: int, sx: float, sy: float,
                                                     seed: int) -> None:
    q = np.random.default_rng(seed).random((ny, nx))
    want = (_shift_matrix(ny, nx, sx, sy).T @ q.ravel()).reshape(ny, nx)
    shift_adjoint(q, sx, sy, np.empty_like(q))
    np.testing.assert_allclose(q, want, atol=1e-12)
    p = np.zeros((ny, nx))
    p[ny // 2, nx // 2] = 1.0                          # the forward shift: same weights
    moved = (_shift_matrix(ny, nx, sx, sy) @ p.ravel()).reshape(ny, nx)
    shift(p, sx, sy, np.empty_like(p))
    if moved.sum() > 0.0:
        np.testing.assert_allclose(p, moved / moved.sum(), atol=1e-12)


def _walk(seed: int, *, burst_db: float) -> tuple[np.ndarray, ...]:
    """Readings at 2 Hz per anchor of a walker along +x at 0.5 m/s for 20 s; the centre anchor
    reads ``burst_db`` strong from 8 to 11 s."""
    t = np.arange(0.0, 20.0, 0.1)
    a = np.arange(t.size) % len(ANCHORS)
    xy = np.column_stack([1.0 + 0.5 * t, np.full(t.size, 3.0)])
    d = np.maximum(np.linalg.norm(xy - ANCHORS[a], axis=1), 1.0)
    rss = MODEL.expected_rss(d) + np.random.default_rng(seed).normal(0.0, 2.0, t.size)
    rss[(t > 8.0) & (t < 11.0) & (a == 4)] += burst_db
    return t, a, rss


def _filtered_and_smoothed(scans: GridScans, params: GridParams, split: int
                           ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray,
                                      np.ndarray]:
    """Filtered rows (two calls, split at scan ``split``), smoothed rows and covariances, the
    filtered and the smoothed densities."""
    f = RssGridFilter(ANCHORS, model=MODEL, params=params)
    state, rec, means = f.start(), GridRecord(), []
    for sl in (slice(0, split), slice(split, None)):
        first, count = scans.first[sl], scans.count[sl]
        r0, r1 = first[0], first[-1] + count[-1]
        part = GridScans(scans.t[sl], first - r0, count, scans.anchor[r0:r1],
                         scans.rss_dbm[r0:r1], scans.weight[r0:r1])
        rows, state = f.update(state, part, record=rec.new(len(part.t), f.geometry))
        means.append(rows.mean_xy)
    filtered = np.concatenate(rec.kept)
    smoothed = filtered.copy()
    sm = smooth_rows(scans.t, smoothed, np.concatenate(rec.moved), geometry=f.geometry,
                     params=params)
    assert np.array_equal(sm.mean_xy, rec.smooth(scans.t, geometry=f.geometry,
                                                 params=params).mean_xy)
    return np.concatenate(means), sm.mean_xy, sm.cov_xy, filtered, smoothed


def test_an_uninformative_last_scan_leaves_the_last_densities_filtered() -> None:
    t, a, rss = _walk(0, burst_db=0.0)
    sc = causal_scans(t, a, rss, n_anchors=len(ANCHORS), scan_s=0.5, average_s=2.0,
                      t_origin=0.0)
    last = slice(sc.first[-1], sc.first[-1] + sc.count[-1])
    weight = sc.weight.copy()
    weight[last] = 0.0                                # the last scan says nothing
    sc = GridScans(sc.t, sc.first, sc.count, sc.anchor, sc.rss_dbm, weight)
    filt, smooth, _, f_dens, s_dens = _filtered_and_smoothed(sc, GridParams(), len(sc.t) // 2)
    np.testing.assert_allclose(smooth[-1], filt[-1], atol=1e-5)
    np.testing.assert_allclose(s_dens.sum(axis=(1, 2)), 1.0, atol=1e-5)
    # s_N = f_N = p_N, so s_{N-1} = f_{N-1} S^T B 1, and S^T B 1 = 1 farther than the blur's
    # 3 sigma plus the shift from the grid's edge: s_{N-1} proportional to f_{N-1} there
    edge = math.ceil(3.0 * 1.5 * math.sqrt(0.5) / 0.25) + 2    # cells: 3 sigma + a shift
    inner = (slice(edge, -edge), slice(edge, -edge))
    ratio = s_dens[-2][inner] / f_dens[-2][inner]
    np.testing.assert_allclose(ratio, ratio.mean(), rtol=1e-4)
    assert np.abs(smooth[:-8] - filt[:-8]).max() > 0.05     # earlier rows do move


def test_the_smoother_undoes_an_outlier_burst_on_a_straight_walk() -> None:
    for seed in range(4):
        t, a, rss = _walk(seed, burst_db=12.0)
        sc = causal_scans(t, a, rss, n_anchors=len(ANCHORS), scan_s=0.5, average_s=2.0,
                          t_origin=0.0)
        filt, smooth, cov, _, _ = _filtered_and_smoothed(sc, GridParams(), 17)
        truth = np.column_stack([1.0 + 0.5 * sc.t, np.full(len(sc.t), 3.0)])
        ef = np.linalg.norm(filt - truth, axis=1)
        es = np.linalg.norm(smooth - truth, axis=1)
        burst = (sc.t > 8.0) & (sc.t < 13.0)
        assert es.mean() < ef.mean() - 0.03, seed
        assert es[burst].mean() < ef[burst].mean(), seed
        assert np.all(np.linalg.eigvalsh(cov) > 0.0)


def test_velocity_modes_and_too_many_densities_are_refused() -> None:
    with pytest.raises(InputError, match=r"grid_smoother.*velocity mode"):
        check_smoothable(GridParams(mode_turn_deg=90.0))
    with pytest.raises(InputError, match=r"grid_smoother.*velocity mode"):
        check_smoothable(GridParams(stopped_mode=True))
    check_smoothable(GridParams(velocity_time_s=0.0))
    g = GridGeometry(0.0, 0.0, 0.5, 10, 10)
    rec = GridRecord(max_bytes=4 * 100 * 5)
    rec.new(3, g)
    rec.new(2, g)
    with pytest.raises(InputError, match=r"grid_smoother.*cell_m"):
        rec.new(1, g)


@pytest.mark.realdata
def test_hrtls_track_with_the_smoother_on_a_ble_track(shared_data: Path, tmp_path: Path
                                                      ) -> None:
    from hrtls.cli.app import app

    rec = shared_data / "ble_rssi" / "trk" / "straight_01_all_sensors.mbd"
    if not rec.is_file():
        pytest.skip("BLE RSSI dataset not available")
    cfg = tmp_path / "smooth.toml"
    cfg.write_text("[offline]\ngrid_smoother = true\n", encoding="utf-8")
    runner = CliRunner()
    out = {}
    for name, extra in (("filtered", []), ("smoothed", ["--config", str(cfg)])):
        res = runner.invoke(app, ["track", str(rec), "-o", str(tmp_path / name), *extra])
        assert res.exit_code == 0, res.output
        out[name] = json.loads((tmp_path / name / "report.json").read_text(encoding="utf-8"))
    assert out["smoothed"]["offline"]["grid_smoother"] is True
    assert out["filtered"]["offline"]["grid_smoother"] is False
    assert any("grid_smoother" in n for n in out["smoothed"]["notes"])
    modes = tmp_path / "modes.toml"
    modes.write_text("[offline]\ngrid_smoother = true\n[prediction.grid]\nstopped_mode = true\n",
                     encoding="utf-8")
    res = runner.invoke(app, ["track", str(rec), "-o", str(tmp_path / "m"), "-c", str(modes)])
    assert res.exit_code == 2 and "velocity mode" in res.output, res.output


@pytest.mark.realdata
def test_the_live_path_ignores_the_smoother(shared_data: Path) -> None:
    import warnings

    from hrtls.datasets.ble_rssi import load_trajectory
    from hrtls.pipeline import Tracker, TrackerConfig
    from hrtls.pipeline.chunks import split_session

    root = shared_data / "ble_rssi"
    if not root.is_dir():
        pytest.skip("BLE RSSI dataset not available")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        s = load_trajectory(root, "straight_03").session
    cfg = TrackerConfig.model_validate({"offline": {"grid_smoother": True}})
    tr = Tracker(cfg)                                  # start / update / finish: the live path
    tr.start_session(s)
    for chunk in split_session(s, 7.0):
        tr.update(chunk)
    live = tr.finish()
    filtered = Tracker().run(s).trajectory
    smoothed = Tracker(cfg).run(s)
    assert live.report["offline"]["grid_smoother"] is False
    assert smoothed.report["offline"]["grid_smoother"] is True
    np.testing.assert_allclose(live.trajectory.xyz, filtered.xyz, atol=1e-9)
    assert np.abs(smoothed.trajectory.xyz - filtered.xyz).max() > 0.1


@pytest.mark.parametrize("lag_s", [0.0, 1.0, 2.5])
def test_fixed_lag_rows_are_the_smoother_over_the_scans_up_to_the_lag(lag_s: float) -> None:
    t, a, rss = _walk(1, burst_db=12.0)
    sc = causal_scans(t, a, rss, n_anchors=len(ANCHORS), scan_s=0.5, average_s=2.0,
                      t_origin=0.0)
    params = GridParams()
    f = RssGridFilter(ANCHORS, model=MODEL, params=params)
    rec = GridRecord()
    filtered, _ = f.update(f.start(), sc, record=rec.new(len(sc.t), f.geometry))
    kept, moved = rec.kept[0], rec.moved[0]
    lag = FixedLag.empty(f.geometry, lag_s=lag_s)
    parts = [lag.push(sc.t[i:i + 7], kept[i:i + 7], moved[i:i + 7], geometry=f.geometry,
                      params=params) for i in range(0, len(sc.t), 7)]
    out = np.concatenate([p.mean_xy for p in parts])
    # out as soon as a scan more than lag_s later is filtered
    assert len(out) == int(np.sum(sc.t < sc.t[-1] - lag_s))
    assert len(lag.t) == len(sc.t) - len(out)
    tail = lag.flush(geometry=f.geometry, params=params)
    rows = np.concatenate([out, tail.mean_xy])
    assert len(rows) == len(sc.t) and len(lag.t) == 0
    for j in range(0, len(sc.t), 5):
        m = int(np.searchsorted(sc.t, sc.t[j] + lag_s, side="right"))
        want = smooth_rows(sc.t[:m], kept[:m].copy(), moved[:m], geometry=f.geometry,
                           params=params)
        np.testing.assert_allclose(rows[j], want.mean_xy[j], atol=1e-9)
    if lag_s == 0.0:
        np.testing.assert_allclose(rows, filtered.mean_xy, atol=1e-5)
