"""Attitude commands: ``hrtls attitude`` and ``hrtls calibrate imu|mag``.

Register in :mod:`hrtls.cli.app` with::

    from hrtls.cli import attitude as attitude_cli
    app.command("attitude")(attitude_cli.attitude)
    app.add_typer(attitude_cli.calibrate_app, name="calibrate")   # or add its commands to an
    # existing calibrate_app: calibrate_app.command("imu")(attitude_cli.calibrate_imu) and
    # calibrate_app.command("mag")(attitude_cli.calibrate_mag)

``attitude`` writes ``t,qw,qx,qy,qz,roll,pitch,yaw`` (ENU, rad; body frame when the session
gives ``mounting_q_bd``, else device frame). When the recording carries a reference orientation
(a BROAD trial, ``orientation_reference.csv`` in a session folder, or ``--reference``) it also
prints the inclination and heading RMS against it, per segment and overall
(:func:`hrtls.evaluate.orientation.score_orientation`); ``hrtls evaluate ATTITUDE.csv --truth
REFERENCE`` scores a written CSV the same way (:func:`evaluate_orientation`).

``calibrate imu`` needs a positions file ``t_start,t_end,position`` (position one of
``+x,-x,+y,-y,+z,-z``: the device axis pointing up in that static interval) and optionally a
rate-test file ``t_start,t_end,axis,rate_rad_s`` (turntable runs, rate signed: positive is
counter-clockwise about the axis). Without a rate test the gyro bias is the mean rate over the
static intervals.
"""

from __future__ import annotations

import warnings
from pathlib import Path
from typing import Annotated

import numpy as np
import typer
from rich.console import Console
from rich.table import Table

from hrtls.attitude.base import AttitudeResult
from hrtls.attitude.device import DeviceOrientation, DeviceParams
from hrtls.attitude.registry import DEFAULT_FILTER, FILTERS, METHODS, make_filter
from hrtls.calibration.imu import (
    AXIS_POSITIONS,
    Calibration,
    accelerometer_six_position,
    fit_magnetometer,
    gyroscope_rate_test,
)
from hrtls.data import Session
from hrtls.datasets.reference_orientation import (
    find_reference_orientation,
    read_reference_orientation,
)
from hrtls.errors import DegradedInputWarning, FormatError, InputError
from hrtls.evaluate.orientation import OrientationScore, score_orientation
from hrtls.io.intervals import read_intervals
from hrtls.io.orientation import OrientationTable, read_orientation_csv

__all__ = [
    "attitude",
    "attitude_command",
    "calibrate_app",
    "calibrate_imu",
    "calibrate_mag",
    "compute_attitude",
    "evaluate_orientation",
    "orientation_table",
    "read_any_session",
    "write_attitude_csv",
]

calibrate_app = typer.Typer(no_args_is_help=True, help="Sensor calibration files.")


def read_any_session(path: Path, *, repair: bool = False) -> Session:
    """Read a session folder/zip, or any format the readers detect."""
    from hrtls.io.session import is_session, read_session

    path = Path(path)
    if not path.exists():
        raise InputError("no such file or folder", where=str(path),
                         expected="a session folder, zip or recording")
    if is_session(path):
        return read_session(path, repair=repair)
    try:
        from hrtls.recordings import read_any
    except ImportError:  # pragma: no cover - readers not installed
        return read_session(path, repair=repair)
    return read_any(path, repair=repair)


def compute_attitude(session: Session, method: str, *,
                     calibration: Calibration | None = None) -> AttitudeResult:
    """Run an attitude method on a session (mounting from ``session.meta.mounting_q_bd``)."""
    if method not in METHODS:
        raise InputError(f"unknown method {method!r}", where="--method",
                         expected=" | ".join(sorted(METHODS)))
    mounting = session.meta.mounting_q_bd
    if method == DeviceOrientation.name:
        if session.orientation is None:
            raise InputError("the session has no device orientation", where="--method device",
                             expected="orientation.csv (t,qw,qx,qy,qz) in the session",
                             hint="use --method quat-ekf to compute one from the IMU")
        dev = DeviceOrientation(DeviceParams(mounting_q_bd=mounting))
        t = None if session.imu is None else session.imu.accel.t
        return dev.run(session.orientation, t)
    if session.imu is None:
        raise InputError("the session has no IMU stream", where=f"--method {method}",
                         expected="imu.csv with accelerometer (and gyroscope) columns")
    imu = session.imu if calibration is None else calibration.apply(session.imu)
    params_type = FILTERS[method].params_type
    params = params_type(mounting_q_bd=mounting) if mounting is not None else params_type()
    flt = make_filter(method, params)
    with warnings.catch_warnings():
        warnings.simplefilter("always", DegradedInputWarning)
        return flt.run(imu)


def write_attitude_csv(result: AttitudeResult, output: Path) -> Path:
    """Write ``t,qw,qx,qy,qz,roll,pitch,yaw`` (ENU, rad)."""
    roll, pitch, yaw = result.euler
    table = np.column_stack([result.t, result.q, roll, pitch, yaw])
    output = Path(output)
    if output.parent and not output.parent.exists():
        raise InputError("folder does not exist", where=str(output.parent),
                         expected="an existing output folder")
    np.savetxt(output, table, delimiter=",", header="t,qw,qx,qy,qz,roll,pitch,yaw",
               comments="", fmt="%.9g")
    return output


def attitude_command(session: Path, output: Path, method: str = DEFAULT_FILTER, *,
                     calibration: Path | None = None, repair: bool = False) -> AttitudeResult:
    """Read a session, estimate its attitude and write the CSV (the body of ``hrtls attitude``)."""
    data = read_any_session(Path(session), repair=repair)
    cal = None if calibration is None else Calibration.load(calibration)
    result = compute_attitude(data, method, calibration=cal)
    write_attitude_csv(result, output)
    return result


def _score(t: np.ndarray, q: np.ndarray, ref: OrientationTable) -> OrientationScore:
    return score_orientation(t, q, ref.t, ref.q, mask=ref.mask)


def orientation_table(score: OrientationScore, title: str = "") -> Table:
    """Inclination and heading RMS (deg) per segment and overall as a rich table."""
    table = Table("segment", "t start (s)", "t end (s)", "samples", "inclination RMS (deg)",
                  "heading RMS (deg)", title=title or None)
    rows = [(str(i + 1), s) for i, s in enumerate(score.segments)] + [("all", score.overall)]
    for label, seg in rows:
        table.add_row(label, f"{seg.t_start_s:.1f}", f"{seg.t_end_s:.1f}", str(seg.n),
                      f"{np.rad2deg(seg.inclination_rms_rad):.2f}",
                      f"{np.rad2deg(seg.heading_rms_rad):.2f}")
    table.caption = (f"heading offset removed: {np.rad2deg(score.heading_offset_rad):.2f} deg; "
                     f"{score.overall.n} of {score.n_reference} reference samples scored")
    return table


def evaluate_orientation(estimate_csv: Path, reference: Path,
                         output: Path | None = None) -> OrientationScore:
    """Score an attitude CSV against a reference; write ``<stem>_orientation.json``.

    The body of ``hrtls evaluate ATTITUDE.csv --truth REFERENCE``.
    """
    import json

    est = read_orientation_csv(estimate_csv)
    score = _score(est.t, est.q, read_reference_orientation(reference))
    out = output if output is not None else estimate_csv.parent
    out.mkdir(parents=True, exist_ok=True)
    (out / f"{estimate_csv.stem}_orientation.json").write_text(
        json.dumps(score.to_dict(), indent=2) + "\n")
    return score


def _report(result: AttitudeResult) -> str:
    n = len(result)
    if n == 0:
        return "no samples"
    return (f"{n} samples, accelerometer used {result.acc_used.mean():.0%}, magnetometer used "
            f"{result.mag_used.mean():.0%}, rejected {result.rejected}")


def attitude(
    session: Annotated[Path, typer.Argument(help="Session folder/zip or recording.")],
    output: Annotated[Path, typer.Option("--output", "-o", help="CSV to write.")] = Path(
        "attitude.csv"),
    method: Annotated[str, typer.Option(
        "--method", "-m",
        help="euler-ekf | quat-ekf | complementary | inertial-lp | device")] = DEFAULT_FILTER,
    calibration: Annotated[Path | None, typer.Option(
        "--calibration", "-c", help="IMU calibration JSON (from `hrtls calibrate`).")] = None,
    repair: Annotated[bool, typer.Option("--repair", help="Repair bad rows (warns).")] = False,
    reference: Annotated[Path | None, typer.Option(
        "--reference", help="Reference orientation (CSV t,qw,qx,qy,qz[,movement] or BROAD "
        "trial) to score against; found in the recording when it carries one.")] = None,
) -> None:
    """Estimate the orientation (ENU) and write t,qw,qx,qy,qz,roll,pitch,yaw."""
    from hrtls.cli.errors import reports_errors

    @reports_errors
    def _go() -> None:
        result = attitude_command(session, output, method, calibration=calibration,
                                  repair=repair)
        typer.echo(f"{output}: {_report(result)}")
        ref = (read_reference_orientation(reference) if reference is not None
               else find_reference_orientation(session))
        if ref is not None:
            Console().print(orientation_table(_score(result.t, result.q, ref),
                                              title=f"{method} against {ref.source}"))

    _go()


# ---------------------------------------------------------------------------------------------
# calibration
# ---------------------------------------------------------------------------------------------



def imu_calibration_from_session(session: Session, positions: Path,
                                 rate_test: Path | None = None) -> Calibration:
    """Six-position (and optional rate-test) calibration of a session's IMU."""
    if session.imu is None:
        raise InputError("the session has no IMU stream", where="calibrate imu",
                         expected="imu.csv")
    t, acc, gyr, _ = session.imu.aligned()
    segments: dict[str, list[np.ndarray]] = {p: [] for p in AXIS_POSITIONS}
    static_gyro: list[np.ndarray] = []
    iv = read_intervals(positions, columns={"position": "str"})
    for t0, t1, pos, i in zip(iv.t_start, iv.t_end, iv.table.str("position"), iv.line,
                              strict=True):
        if pos not in segments:
            raise FormatError(f"position {pos!r}", where=f"{positions} line {i}",
                              expected=" | ".join(AXIS_POSITIONS))
        sel = (t >= t0) & (t < t1)
        if not sel.any():
            raise InputError("no samples in the interval", where=f"{positions} line {i}",
                             expected="intervals on the session clock")
        segments[pos].append(acc[sel])
        if gyr is not None:
            static_gyro.append(gyr[sel])
    merged = {k: np.vstack(v) for k, v in segments.items() if v}
    bias, scale = accelerometer_six_position(merged)
    notes = [f"six-position test from {positions.name}"]
    gbias = np.zeros(3)
    gscale = np.zeros(3)
    if rate_test is not None:
        if gyr is None:
            raise InputError("the session has no gyroscope", where="--rate-test",
                             expected="gyroscope columns in imu.csv")
        ccw = np.full(3, np.nan)
        cw = np.full(3, np.nan)
        rate = np.nan
        rates = read_intervals(rate_test, columns={"axis": "str", "rate_rad_s": "float"})
        for t0, t1, axis_name, r, i in zip(rates.t_start, rates.t_end,
                                           rates.table.str("axis"),
                                           rates.table.float("rate_rad_s"), rates.line,
                                           strict=True):
            axis = "xyz".find(axis_name.lower()) if len(axis_name) == 1 else -1
            if axis < 0 or r == 0:
                raise FormatError(f"axis {axis_name!r}, rate {r}",
                                  where=f"{rate_test} line {i}",
                                  expected="axis x|y|z and a non-zero rate")
            sel = (t >= t0) & (t < t1)
            if not sel.any():
                raise InputError("no samples in the interval", where=f"{rate_test} line {i}",
                                 expected="intervals on the session clock")
            (ccw if r > 0 else cw)[axis] = float(np.mean(gyr[sel, axis]))
            rate = abs(r)
        if np.any(np.isnan(ccw)) or np.any(np.isnan(cw)):
            raise InputError("runs missing", where=str(rate_test),
                             expected="a positive and a negative run about each axis x, y, z")
        gbias, gscale = gyroscope_rate_test(rate, ccw, cw)
        notes.append(f"gyroscope rate test from {rate_test.name}")
    elif static_gyro:
        gbias = np.vstack(static_gyro).mean(axis=0)
        notes.append("gyroscope bias from the static intervals")
    return Calibration.model_validate({
        "accel_bias_m_s2": bias.tolist(), "accel_scale": scale.tolist(),
        "gyro_bias_rad_s": np.asarray(gbias).tolist(), "gyro_scale": np.asarray(gscale).tolist(),
        "notes": notes})


@calibrate_app.command("imu")
def calibrate_imu(
    session: Annotated[Path, typer.Argument(help="Session with the static recordings.")],
    positions: Annotated[Path, typer.Option(
        "--positions", "-p", help="CSV t_start,t_end,position (+x,-x,+y,-y,+z,-z).")],
    output: Annotated[Path, typer.Option("--output", "-o", help="Calibration JSON.")] = Path(
        "calibration.json"),
    rate_test: Annotated[Path | None, typer.Option(
        "--rate-test", help="CSV t_start,t_end,axis,rate_rad_s of turntable runs.")] = None,
) -> None:
    """Accelerometer six-position test (+ gyroscope rate test) -> calibration JSON."""
    from hrtls.cli.errors import reports_errors

    @reports_errors
    def _go() -> None:
        cal = imu_calibration_from_session(read_any_session(session), positions, rate_test)
        if output.exists():
            old = Calibration.load(output)
            cal = cal.model_copy(update={
                "mag_hard_iron_uT": old.mag_hard_iron_uT, "mag_soft_iron": old.mag_soft_iron,
                "mag_field_uT": old.mag_field_uT, "notes": [*old.notes, *cal.notes]})
        cal.save(output)
        typer.echo(f"{output}: accel bias {np.round(cal.accel_bias_m_s2, 4).tolist()} m/s^2, "
                   f"scale {np.round(cal.accel_scale, 5).tolist()}")

    _go()


@calibrate_app.command("mag")
def calibrate_mag(
    session: Annotated[Path, typer.Argument(help="Session swung through a figure of eight.")],
    output: Annotated[Path, typer.Option("--output", "-o", help="Calibration JSON.")] = Path(
        "calibration.json"),
    model: Annotated[str, typer.Option(help="ellipsoid | sphere")] = "ellipsoid",
) -> None:
    """Magnetometer hard/soft-iron fit -> calibration JSON (updates an existing file)."""
    from hrtls.cli.errors import reports_errors

    @reports_errors
    def _go() -> None:
        data = read_any_session(session)
        if data.imu is None or data.imu.mag is None:
            raise InputError("the session has no magnetometer", where=str(session),
                             expected="mx,my,mz columns or mag.csv")
        if model not in ("ellipsoid", "sphere"):
            raise InputError(f"model {model!r}", where="--model",
                             expected="ellipsoid | sphere")
        fit = fit_magnetometer(data.imu.mag.values,
                               model="sphere" if model == "sphere" else "ellipsoid")
        base = Calibration.load(output) if output.exists() else Calibration()
        base.with_magnetometer(fit).save(output)
        typer.echo(f"{output}: hard iron {np.round(fit.hard_iron_uT, 2).tolist()} uT, field "
                   f"{fit.field_uT:.2f} uT, residual {fit.residual_uT:.3f} uT")

    _go()
