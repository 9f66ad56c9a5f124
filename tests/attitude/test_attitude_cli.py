"""`hrtls attitude` and `hrtls calibrate imu|mag` (pure functions and typer wiring)."""

from __future__ import annotations

import numpy as np
import pytest
import typer
from scipy.spatial.transform import Rotation
from typer.testing import CliRunner

from hrtls.cli import attitude as cli
from hrtls.data import ImuStream, OrientationSeries, SensorSeries, Session, SessionMeta
from hrtls.errors import InputError
from hrtls.frames import GRAVITY_M_S2, quat_angle_between, quat_from_euler

from .conftest import make_motion


def _session(with_orientation=True, meta=None):
    m = make_motion(400, seed=9)
    imu = ImuStream(SensorSeries(m.t, m.acc, "accelerometer"), SensorSeries(m.t, m.gyr, "gyro"),
                    SensorSeries(m.t, m.mag, "mag"))
    ori = OrientationSeries(m.t[::4], m.q[::4]) if with_orientation else None
    return Session(meta=meta or SessionMeta(), imu=imu, orientation=ori), m


@pytest.mark.parametrize("method", ["euler-ekf", "quat-ekf", "complementary", "device"])
def test_compute_attitude_all_methods(method):
    session, m = _session()
    r = cli.compute_attitude(session, method)
    assert len(r) == len(m.t)
    ang = np.rad2deg(quat_angle_between(r.q, m.q))
    assert np.sqrt(np.mean(ang[100:] ** 2)) < 3.0


def test_compute_attitude_uses_mounting():
    q_bd = quat_from_euler(0.0, 0.0, 0.5)
    session, _ = _session(meta=SessionMeta(mounting_q_bd=tuple(q_bd)))
    assert cli.compute_attitude(session, "quat-ekf").frame == "nb"
    assert cli.compute_attitude(session, "device").frame == "nb"


def test_compute_attitude_errors():
    session, _ = _session(with_orientation=False)
    with pytest.raises(InputError, match="orientation"):
        cli.compute_attitude(session, "device")
    with pytest.raises(InputError, match="unknown method"):
        cli.compute_attitude(session, "kalman")


def test_attitude_command_writes_csv(tmp_path):
    from hrtls.io.session import write_session

    session, m = _session()
    folder = write_session(session, tmp_path / "s")
    out = tmp_path / "attitude.csv"
    result = cli.attitude_command(folder, out, "quat-ekf")
    text = out.read_text().splitlines()
    assert text[0] == "t,qw,qx,qy,qz,roll,pitch,yaw"
    table = np.loadtxt(out, delimiter=",", skiprows=1)
    assert table.shape == (len(m.t), 8)
    np.testing.assert_allclose(table[:, 1:5], result.q, atol=1e-8)
    np.testing.assert_allclose(table[:, 7], result.yaw, atol=1e-8)

    app = typer.Typer()
    app.command()(cli.attitude)
    app.command("other")(lambda: None)
    res = CliRunner().invoke(app, ["attitude", str(folder), "-o", str(tmp_path / "b.csv"),
                                   "--method", "complementary"])
    assert res.exit_code == 0, res.output
    assert (tmp_path / "b.csv").exists()
    bad = CliRunner().invoke(app, ["attitude", str(tmp_path / "nope"), "-o", str(out)])
    assert bad.exit_code != 0


def _static_session(tmp_path):
    """Six static positions of 2 s each, then a figure of eight for the magnetometer."""
    from hrtls.io.session import write_session

    rate = 50.0
    bias = np.array([0.2, -0.1, 0.05])
    scale = np.array([0.01, -0.02, 0.0])
    gbias = np.array([0.01, 0.0, -0.02])
    rows, gyr, mags, lines = [], [], [], ["t_start,t_end,position"]
    t0 = 0.0
    field = np.array([0.0, 20.0, -40.0])
    hard = np.array([5.0, -3.0, 8.0])
    for i, axis in enumerate("xyz"):
        for sign in (1, -1):
            true = np.zeros(3)
            true[i] = sign * GRAVITY_M_S2
            n = int(2 * rate)
            rows.append(np.tile(true * (1 + scale) + bias, (n, 1)))
            gyr.append(np.tile(gbias, (n, 1)))
            # any rotation with the axis up works for the field
            mags.append(np.tile(field + hard, (n, 1)))
            lines.append(f"{t0 + 0.2},{t0 + 1.8},{'+' if sign > 0 else '-'}{axis}")
            t0 += 2.0
    rots = Rotation.random(600, random_state=1)
    rows.append(rots.inv().apply([0, 0, GRAVITY_M_S2]) * (1 + scale) + bias)
    gyr.append(np.tile(gbias, (600, 1)))
    mags.append(rots.inv().apply(field) + hard)
    acc = np.vstack(rows)
    t = np.arange(len(acc)) / rate
    imu = ImuStream(SensorSeries(t, acc), SensorSeries(t, np.vstack(gyr)),
                    SensorSeries(t, np.vstack(mags)))
    folder = write_session(Session(imu=imu), tmp_path / "calib")
    pos = tmp_path / "positions.csv"
    pos.write_text("\n".join(lines) + "\n")
    return folder, pos, bias, scale, gbias, hard


def test_calibrate_commands(tmp_path):
    folder, pos, bias, scale, gbias, hard = _static_session(tmp_path)
    out = tmp_path / "cal.json"
    runner = CliRunner()
    res = runner.invoke(cli.calibrate_app, ["imu", str(folder), "--positions", str(pos),
                                            "-o", str(out)])
    assert res.exit_code == 0, res.output
    res = runner.invoke(cli.calibrate_app, ["mag", str(folder), "-o", str(out),
                                            "--model", "sphere"])
    assert res.exit_code == 0, res.output
    cal = cli.Calibration.load(out)
    np.testing.assert_allclose(cal.accel_bias_m_s2, bias, atol=1e-9)
    np.testing.assert_allclose(cal.accel_scale, scale, atol=1e-9)
    np.testing.assert_allclose(cal.gyro_bias_rad_s, gbias, atol=1e-9)
    # the static part has one field direction only; the sphere still finds the offset
    np.testing.assert_allclose(cal.mag_hard_iron_uT, hard, atol=0.5)
    # calibration used by the attitude command
    r = cli.attitude_command(folder, tmp_path / "a.csv", "quat-ekf", calibration=out)
    assert np.all(np.isfinite(r.q))
    bad = tmp_path / "badpos.csv"
    bad.write_text("t_start,t_end,position\n0,1,+w\n")
    res = runner.invoke(cli.calibrate_app, ["imu", str(folder), "--positions", str(bad),
                                            "-o", str(tmp_path / "x.json")])
    assert res.exit_code != 0
