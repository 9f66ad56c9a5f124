"""Scoring an orientation against a reference: hand-computed cases, segments, CLI wiring."""

from __future__ import annotations

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from hrtls.cli import attitude as cli
from hrtls.datasets.reference_orientation import read_reference_orientation
from hrtls.errors import FormatError, InputError
from hrtls.evaluate.orientation import orientation_errors, score_orientation
from hrtls.frames import quat_from_euler, quat_multiply
from hrtls.io.orientation import REFERENCE_FILE

from .conftest import make_motion


def _tilted(q_ref, tilt_rad, yaw_rad):
    """``R_x(tilt) R_z(yaw) q_ref``: inclination error ``tilt``, heading error ``yaw``."""
    n = len(q_ref)
    e = quat_multiply(quat_from_euler(np.full(n, tilt_rad), np.zeros(n), np.zeros(n)),
                      quat_from_euler(np.zeros(n), np.zeros(n), np.full(n, yaw_rad)))
    return quat_multiply(e, q_ref)


def test_tilt_and_heading_offset_are_separated():
    m = make_motion(300, seed=1, noise=False)
    q = _tilted(m.q, np.deg2rad(2.0), np.deg2rad(10.0))
    e = orientation_errors(q, m.q, remove_heading_offset=False)
    np.testing.assert_allclose(np.rad2deg(e.inclination_rad), 2.0, atol=1e-9)
    np.testing.assert_allclose(np.rad2deg(e.heading_rad), 10.0, atol=1e-9)
    s = score_orientation(m.t, q, m.t, m.q)
    assert np.rad2deg(s.overall.inclination_rms_rad) == pytest.approx(2.0, abs=1e-9)
    assert s.overall.heading_rms_rad == pytest.approx(0.0, abs=1e-9)
    assert np.rad2deg(s.heading_offset_rad) == pytest.approx(10.0, abs=1e-9)
    assert len(s.segments) == 1 and s.overall.n == 300


def test_estimate_on_another_clock_is_interpolated():
    m = make_motion(400, seed=2, noise=False)
    s = score_orientation(m.t[::3], m.q[::3], m.t, m.q)
    # slerp between samples 30 ms apart of a smooth motion: tiny errors
    assert np.rad2deg(s.overall.inclination_rms_rad) < 0.05
    assert np.rad2deg(s.overall.heading_rms_rad) < 0.05
    # reference samples after the estimate's last time are not scored
    assert s.overall.n == int(np.sum(m.t <= m.t[::3][-1]))


def test_segments_split_at_gaps_with_one_offset():
    m = make_motion(600, seed=3, noise=False)
    q_ref = m.q.copy()
    q_ref[250:400] = np.nan  # reference lost for 1.5 s
    q = m.q.copy()
    q[400:] = _tilted(m.q[400:], np.deg2rad(3.0), 0.0)
    mask = np.ones(600, dtype=bool)
    mask[:20] = False
    s = score_orientation(m.t, q, m.t, q_ref, mask=mask)
    assert [seg.n for seg in s.segments] == [230, 200]
    assert s.segments[0].inclination_rms_rad == pytest.approx(0.0, abs=1e-9)
    assert np.rad2deg(s.segments[1].inclination_rms_rad) == pytest.approx(3.0, abs=1e-9)
    expected = np.sqrt(200 * 3.0 ** 2 / 430)
    assert np.rad2deg(s.overall.inclination_rms_rad) == pytest.approx(expected, abs=1e-9)
    d = json.loads(json.dumps(s.to_dict()))
    assert d["segments"][1]["inclination_rms_deg"] == pytest.approx(3.0, abs=1e-9)


def test_bad_inputs_raise():
    m = make_motion(50, seed=4, noise=False)
    with pytest.raises(InputError):
        score_orientation(m.t[::-1], m.q, m.t, m.q)
    with pytest.raises(InputError):
        score_orientation(m.t, m.q[:, :3], m.t, m.q)
    with pytest.raises(InputError):
        score_orientation(m.t, np.full((50, 4), np.nan), m.t, m.q)
    with pytest.raises(InputError):
        score_orientation(m.t, m.q, m.t, m.q, segment_gap_s=0.0)


def _write_reference(path, t, q, movement=None):
    lines = ["t,qw,qx,qy,qz" + (",movement" if movement is not None else "")]
    for i in range(len(t)):
        cells = [f"{t[i]:.6f}"] + ["" if np.isnan(v) else f"{v:.12g}" for v in q[i]]
        if movement is not None:
            cells.append(str(int(movement[i])))
        lines.append(",".join(cells))
    path.write_text("\n".join(lines) + "\n")


def test_reference_csv_is_read_and_errors_name_the_line(tmp_path):
    m = make_motion(30, seed=5, noise=False)
    q = m.q.copy()
    q[5] = np.nan
    p = tmp_path / "ref.csv"
    _write_reference(p, m.t, q, movement=np.arange(30) > 3)
    ref = read_reference_orientation(p)
    assert np.isnan(ref.q[5]).all() and ref.mask is not None and ref.mask.sum() == 26
    bad = tmp_path / "bad.csv"
    bad.write_text("t,qw,qx,qy,qz\n0,1,0,0,0\n0.1,one,0,0,0\n")
    with pytest.raises(FormatError, match="line 3"):
        read_reference_orientation(bad)
    with pytest.raises(InputError):
        read_reference_orientation(tmp_path / "missing.csv")


def test_attitude_prints_and_evaluate_scores_against_the_reference(tmp_path):
    from hrtls.cli.app import app
    from hrtls.data import ImuStream, SensorSeries, Session
    from hrtls.io.session import write_session

    m = make_motion(600, seed=6)
    imu = ImuStream(SensorSeries(m.t, m.acc), SensorSeries(m.t, m.gyr), SensorSeries(m.t, m.mag))
    folder = write_session(Session(imu=imu), tmp_path / "s")
    _write_reference(folder / REFERENCE_FILE, m.t, m.q)
    out = tmp_path / "att.csv"
    runner = CliRunner()
    res = runner.invoke(app, ["attitude", str(folder), "-o", str(out), "-m", "inertial-lp"])
    assert res.exit_code == 0, res.output
    assert "inclination" in res.output and "heading offset removed" in res.output
    res = runner.invoke(app, ["evaluate", str(out), "--truth", str(folder / REFERENCE_FILE),
                              "-o", str(tmp_path / "rep")])
    assert res.exit_code == 0, res.output
    report = json.loads((tmp_path / "rep" / "att_orientation.json").read_text())
    est = read_reference_orientation(out)
    direct = score_orientation(est.t, est.q, m.t, m.q)
    assert report["overall"]["inclination_rms_rad"] == pytest.approx(
        direct.overall.inclination_rms_rad, rel=1e-6)  # reference CSV rounded
    assert np.rad2deg(direct.overall.inclination_rms_rad) < 3.0
    # --reference given explicitly on a session without its own
    res = runner.invoke(app, ["attitude", str(folder), "-o", str(out), "--reference",
                              str(tmp_path / "nope.csv")])
    assert res.exit_code != 0


def test_attitude_scores_a_broad_trial(shared_data):
    path = shared_data / "broad" / "02_undisturbed_slow_rotation_B.hdf5"
    if not path.exists():
        pytest.skip(f"{path} not available")
    ref = cli.find_reference_orientation(path)
    assert ref is not None and ref.mask is not None
    result = cli.compute_attitude(cli.read_any_session(path), "inertial-lp")
    s = score_orientation(result.t, result.q, ref.t, ref.q, mask=ref.mask)
    assert np.rad2deg(s.overall.inclination_rms_rad) < 1.0
    assert np.rad2deg(s.overall.heading_rms_rad) < 1.5
