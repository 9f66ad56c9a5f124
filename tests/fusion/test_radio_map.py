"""The radio map: kernel regression by hand, shrinkage far from the survey, bad survey files."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hrtls.errors import InputError
from hrtls.fusion.path_loss import PATH_LOSS_DTYPE, PathLossModel
from hrtls.fusion.radio_map import RadioMapParams, RadioSurvey, residual_map
from hrtls.fusion.rss_grid import GridGeometry, GridParams, RssGridFilter, causal_scans
from hrtls.fusion.rss_grid_kernels import log_likelihood
from hrtls.io.survey import read_survey
from hrtls.pipeline.build import Notes
from hrtls.pipeline.grid_stage import GridStage

MODEL = PathLossModel(a_dbm=-59.0, eta=2.0, sigma_db=4.0, d0_m=1.0)
ANCHOR = np.array([[0.0, 0.0]])
ROW = GridGeometry(x0_m=10.0, y0_m=0.0, cell_m=1.0, nx=3, ny=1)
"""Three cells at x = 10, 11, 12 m (y = 0), 1 m apart."""
NO_MAP = np.zeros((0, 0, 0))


def _survey(x: list[float], y: list[float], rss: list[float], anchor: str = "a") -> RadioSurvey:
    return RadioSurvey(np.array(x), np.array(y), np.array([anchor] * len(x)), np.array(rss))


def _map(survey: RadioSurvey, **kw: float) -> tuple[np.ndarray, np.ndarray]:
    return residual_map(survey, anchor_ids=["a"], anchors_xy=ANCHOR, geometry=ROW, model=MODEL,
                        params=RadioMapParams(**kw))


def test_kernel_regression_by_hand() -> None:
    # two readings at x = 10 m, 10 m from the anchor: mean -59 - 20 log10(10) = -79 dBm, so
    # residuals 4 and 2 dB; l = 1 m (one cell): weights W = 2, 2 exp(-1/2), 2 exp(-2)
    mean, var = _map(_survey([10.0, 10.0], [0.0, 0.0], [-75.0, -77.0]), length_m=1.0,
                     prior_sigma_db=2.0, prior_readings=1.0)
    w = 2.0 * np.exp(-0.5 * np.arange(3.0) ** 2)
    np.testing.assert_allclose(mean[0, 0], 3.0 * w / (w + 1.0))
    np.testing.assert_allclose(mean[0, 0, 0], 2.0)                 # 6 / (2 + 1)
    np.testing.assert_allclose(var[0, 0], 4.0 / (w + 1.0))
    np.testing.assert_allclose(var[0, 0, 0], 4.0 / 3.0)


def test_readings_in_two_cells_by_hand() -> None:
    # residual 4 dB at x = 10 m; at x = 12 m the mean is -59 - 20 log10(12) dBm, residual -2 dB
    mu12 = -59.0 - 20.0 * math.log10(12.0)
    mean, _ = _map(_survey([10.0, 12.0], [0.0, 0.0], [-75.0, mu12 - 2.0]), length_m=1.0,
                   prior_sigma_db=2.0, prior_readings=1.0)
    k1, k2 = math.exp(-0.5), math.exp(-2.0)
    expect = [(4.0 - 2.0 * k2) / (1.0 + k2 + 1.0), (4.0 * k1 - 2.0 * k1) / (2.0 * k1 + 1.0),
              (4.0 * k2 - 2.0) / (k2 + 1.0 + 1.0)]
    np.testing.assert_allclose(mean[0, 0], expect)


@settings(max_examples=30, deadline=None)
@given(xs=st.lists(st.floats(0.0, 3.0), min_size=1, max_size=8),
       rss=st.floats(-100.0, -40.0), length=st.floats(0.3, 1.5), sigma=st.floats(0.5, 8.0))
def test_map_shrinks_to_zero_and_the_prior_far_from_the_survey(
        xs: list[float], rss: float, length: float, sigma: float) -> None:
    g = GridGeometry(x0_m=0.0, y0_m=0.0, cell_m=0.5, nx=40, ny=3)
    survey = RadioSurvey(np.array(xs), np.zeros(len(xs)), np.array(["a"] * len(xs)),
                         np.full(len(xs), rss))
    mean, var = residual_map(survey, anchor_ids=["a"], anchors_xy=np.array([[0.0, 5.0]]),
                             geometry=g, model=MODEL,
                             params=RadioMapParams(length_m=length, prior_sigma_db=sigma))
    x = g.centres()[0]
    far = x > 3.0 + 4.0 * length + g.cell_m        # beyond the kernel's 4 sigma of any reading
    assert np.all(mean[0][:, far] == 0.0)
    np.testing.assert_allclose(var[0][:, far], sigma ** 2)
    assert np.all((var >= 0.0) & (var <= sigma ** 2 * (1.0 + 1e-12)))
    d = np.maximum(np.hypot(np.array(xs), 5.0), 1.0)
    resid = rss - (-59.0 - 20.0 * np.log10(d))
    assert np.all(np.abs(mean) <= np.abs(resid).max() * (1.0 + 1e-9))


def test_a_zero_map_is_no_map() -> None:
    anchors = np.array([[0.0, 0.0], [8.0, 0.0], [0.0, 8.0]])
    g = GridGeometry.around(anchors, cell_m=0.5, margin_m=1.0, max_cells=10_000)
    dist = g.distances(anchors, 1.0)
    model = np.zeros(1, dtype=PATH_LOSS_DTYPE)
    model[0] = MODEL.record()[0]
    prm = GridParams(burst_sigma_db=10.0, attenuation_probability=0.2).record()[0]
    args = (np.array([0, 2]), np.array([-70.0, -66.0]), np.array([1.0, 0.5]),
            np.array([1.0, -2.0]), np.array([2.0, 0.0]), np.array([0.1, 0.0, 0.3]), model[0],
            prm)
    ref, out = np.empty((g.ny, g.nx)), np.empty((g.ny, g.nx))
    log_likelihood(dist, NO_MAP, NO_MAP, *args, ref)
    zeros = np.zeros_like(dist)
    log_likelihood(dist, zeros, zeros, *args, out)
    np.testing.assert_array_equal(out, ref)
    # the whole filter: rows with a zero map equal the rows without one
    rng = np.random.default_rng(3)
    t = np.sort(rng.uniform(0.0, 20.0, 120))
    a = rng.integers(0, 3, 120)
    scans = causal_scans(t, a, rng.uniform(-85.0, -55.0, 120), n_anchors=3, scan_s=0.5,
                         average_s=2.0, t_origin=0.0)
    params = GridParams(cell_m=0.5, burst_sigma_db=10.0)
    plain = RssGridFilter(anchors, model=MODEL, params=params)
    mapped = RssGridFilter(anchors, model=MODEL, params=params,
                           radio_map=(np.zeros_like(plain.dist), np.zeros_like(plain.dist)))
    r0 = plain.update(plain.start(), scans)[0]
    r1 = mapped.update(mapped.start(), scans)[0]
    np.testing.assert_array_equal(r1.mean_xy, r0.mean_xy)
    np.testing.assert_array_equal(r1.cov_xy, r0.cov_xy)


def test_a_map_moves_the_likelihood_peak_to_where_it_says() -> None:
    # one anchor heard at -79 dBm: the law puts it on the ring at 10 m; a map of -6.02 dB
    # (-20 log10 2) everywhere says the RSS is that much weaker, so the ring moves to 5 m
    anchors = np.array([[0.0, 0.0], [30.0, 0.0], [0.0, 30.0]])
    params = GridParams(cell_m=1.0, bias_sigma_db=0.0)
    f = RssGridFilter(anchors, model=MODEL, params=params)
    model = np.zeros(1, dtype=PATH_LOSS_DTYPE)
    model[0] = MODEL.record()[0]
    for shift_db, ring_m in ((0.0, 10.0), (-20.0 * math.log10(2.0), 5.0)):
        rmap = np.zeros_like(f.dist)
        rmap[0] = shift_db
        out = np.empty(f.dist.shape[1:])
        log_likelihood(f.dist, rmap, np.zeros_like(rmap), np.array([0]), np.array([-79.0]),
                       np.ones(1), np.zeros(3), np.zeros(3), np.zeros(3), model[0],
                       params.record()[0], out)
        assert abs(f.dist[0].flat[np.argmax(out)] - ring_m) < 0.75


def _write(tmp_path: Path, text: str) -> Path:
    p = tmp_path / "walk_survey.csv"
    p.write_text(text)
    return p


@pytest.mark.parametrize(("text", "words"), [
    ("x_m,y_m,anchor,rss_dbm\n1,2,a,nan\n", ("walk_survey.csv", "rss_dbm", "finite")),
    ("x_m,y_m,anchor,rss_dbm\n1,nan,a,-70\n", ("walk_survey.csv", "y_m", "finite")),
    ("x_m,y_m,anchor,rss_dbm\n1,2,a,1e-7\n", ("walk_survey.csv", "rss_dbm", "units")),
    ("x_m,y_m,anchor,rss_dbm\n1,2,a,-170\n", ("walk_survey.csv", "rss_dbm", "dBm")),
    ("x_m,y_m,anchor,rss_dbm\n1,2,a,strong\n", ("walk_survey.csv", "rss_dbm", "number")),
    ("x,y_m,anchor,rss_dbm\n1,2,a,-70\n", ("walk_survey.csv", "x_m", "header")),
    ("x_m,y_m,anchor,rss_dbm\n", ("walk_survey.csv", "no readings")),
])
def test_bad_survey_files_name_the_file_and_field(tmp_path: Path, text: str,
                                                  words: tuple[str, ...]) -> None:
    with pytest.raises(InputError) as exc:
        read_survey(_write(tmp_path, text))
    for w in words:
        assert w in str(exc.value)


def test_unknown_anchor_names_the_file_and_column(tmp_path: Path) -> None:
    survey = read_survey(_write(tmp_path, "x_m,y_m,anchor,rss_dbm\n1,2,a,-70\n3,4,zz,-71\n"))
    with pytest.raises(InputError, match=r"walk_survey\.csv column 'anchor'.*'zz'"):
        residual_map(survey, anchor_ids=["a"], anchors_xy=ANCHOR, geometry=ROW, model=MODEL,
                     params=RadioMapParams())
    with pytest.raises(InputError, match="cannot read"):
        read_survey(tmp_path / "missing.csv")


def test_the_stage_reads_the_survey_file(tmp_path: Path) -> None:
    from hrtls.data import Landmark
    from hrtls.pipeline import TrackerConfig

    anchors = {k: Landmark(id=k, kind="anchor", position=(x, y, 0.0))
               for k, x, y in (("a", 0.0, 0.0), ("b", 8.0, 0.0), ("c", 0.0, 8.0))}
    p = _write(tmp_path, "x_m,y_m,anchor,rss_dbm\n4,4,a,-60\n4,4,b,-80\n")
    cfg = TrackerConfig()
    cfg = cfg.model_copy(update={"prediction": cfg.prediction.model_copy(update={
        "radio_map": {**cfg.prediction.radio_map, "survey": str(p)}})})
    notes = Notes()
    stage = GridStage.build(cfg, anchors, MODEL, has_imu=False, t0=0.0, z_m=0.0, notes=notes)
    assert stage.filter is not None
    assert stage.filter.rmap.shape == stage.filter.dist.shape
    assert stage.filter.rmap[0].max() > 0.0 > stage.filter.rmap[1].min()
    assert np.all(stage.filter.rmap[2] == 0.0)
    assert any("radio map of 2 surveyed readings" in n for n in notes.items)
