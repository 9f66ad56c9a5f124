"""Synthetic recordings written in each user format, with the truth they encode."""

from __future__ import annotations

import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from hrtls.frames import GRAVITY_M_S2, quat_conjugate, quat_multiply, quat_rotate
from hrtls.io.readers._orientation import FRAME_TO_ENU, quat_axis

FIELD_UT = np.array([0.0, 20.0, -40.0])  # ENU: north and down


@dataclass
class Motion:
    t: np.ndarray  # s
    q_nd: np.ndarray  # device -> ENU
    acc: np.ndarray  # specific force, device frame, m/s^2
    gyr: np.ndarray  # rad/s
    mag: np.ndarray  # uT
    angles: np.ndarray  # (A, B, C): q_nd = qz(A) qx(B) qy(C), rad
    pressure_pa: np.ndarray


def motion(n: int = 400, rate_hz: float = 50.0, seed: int = 0) -> Motion:
    rng = np.random.default_rng(seed)
    t = np.arange(n) / rate_hz
    a = 1.0 + 0.8 * np.sin(0.4 * t)
    b = 0.5 + 0.3 * np.sin(1.1 * t)
    c = 0.2 * np.cos(0.7 * t)
    q = quat_multiply(quat_multiply(quat_axis("z", a), quat_axis("x", b)), quat_axis("y", c))
    acc = quat_rotate(quat_conjugate(q), np.array([0.0, 0.0, GRAVITY_M_S2]))
    acc = acc + 0.3 * rng.standard_normal((n, 3))
    mag = quat_rotate(quat_conjugate(q), FIELD_UT) + 0.2 * rng.standard_normal((n, 3))
    gyr = 0.5 * rng.standard_normal((n, 3))
    p = 97000.0 + 5.0 * rng.standard_normal(n)
    return Motion(t, q, acc, gyr, mag, np.column_stack([a, b, c]), p)


def zip_folder(folder: Path, target: Path, *, prefix: str = "") -> Path:
    with zipfile.ZipFile(target, "w") as zf:
        for p in sorted(folder.rglob("*")):
            if p.is_file():
                zf.write(p, prefix + p.relative_to(folder).as_posix())
    return target


# ------------------------------------------------------------------------------------------
# Android TIMESTAMP X Y Z
# ------------------------------------------------------------------------------------------


def write_android(folder: Path, m: Motion, *, unit: str = "ns", t0: float = 1.2e13,
                  header: bool = False, orientation: bool = True) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    scale = {"ns": 1e9, "ms": 1e3, "s": 1.0}[unit]
    stamps = t0 + m.t * scale
    fmt = "%d" if unit in ("ns", "ms") and float(scale * (m.t[1] - m.t[0])).is_integer() \
        else "%.6f"

    def write(name: str, values: np.ndarray) -> None:
        lines = ["TIMESTAMP X Y Z"] if header else []
        lines += [(fmt % s) + " " + " ".join(f"{v:.6f}" for v in row)
                  for s, row in zip(stamps, values, strict=True)]
        (folder / name).write_text("\n".join(lines) + "\n")

    write("accelerometer.txt", m.acc)
    write("gyroscope.txt", m.gyr)
    write("MagneticField.txt", m.mag)
    if orientation:
        # documented reading: q_nd = qz(-azimuth) qx(-pitch) qy(-roll)
        az = -np.degrees(m.angles[:, 0])
        pitch = -np.degrees(m.angles[:, 1])
        roll = -np.degrees(m.angles[:, 2])
        write("orientation.txt", np.column_stack([az, pitch, roll]))
    return folder


# ------------------------------------------------------------------------------------------
# Sensor Logger
# ------------------------------------------------------------------------------------------


def write_sensorlogger(folder: Path, m: Motion, *, platform: str = "android",
                       standardisation: bool = False, accel_in_g: bool = False,
                       total: bool = True, metadata: bool = True, frame: str | None = None
                       ) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    t_ns = (1_700_000_000.0 + m.t) * 1e9

    def write(name: str, cols: dict[str, np.ndarray]) -> None:
        header = "time,seconds_elapsed," + ",".join(cols)
        rows = [header]
        for i in range(len(m.t)):
            rows.append(f"{int(t_ns[i])},{m.t[i]:.6f}," + ",".join(
                f"{c[i]:.9g}" for c in cols.values()))
        (folder / name).write_text("\n".join(rows) + "\n")

    def zyx(v: np.ndarray) -> dict[str, np.ndarray]:
        return {"z": v[:, 2], "y": v[:, 1], "x": v[:, 0]}

    ios = platform == "ios" and not standardisation
    sign = -1.0 if ios else 1.0
    g_unit = GRAVITY_M_S2 if accel_in_g else 1.0
    gravity = quat_rotate(quat_conjugate(m.q_nd), np.array([0.0, 0.0, GRAVITY_M_S2]))
    if total:
        write("TotalAcceleration.csv", zyx(m.acc / g_unit))
        write("Accelerometer.csv", zyx((m.acc - gravity) / g_unit))
    else:
        write("Accelerometer.csv", zyx(sign * (m.acc - gravity) / g_unit))
        write("Gravity.csv", zyx(sign * gravity / g_unit))
    write("Gyroscope.csv", zyx(m.gyr))
    write("Magnetometer.csv", zyx(m.mag))
    write("Barometer.csv", {"relativeAltitude": np.zeros(len(m.t)),
                            "pressure": m.pressure_pa / 100.0})
    if frame is None:
        frame = "nwu" if platform == "ios" else "enu"
    q_ref = quat_multiply(quat_conjugate(FRAME_TO_ENU[frame])[None, :], m.q_nd)
    write("Orientation.csv", {"qz": q_ref[:, 3], "qy": q_ref[:, 2], "qx": q_ref[:, 1],
                              "qw": q_ref[:, 0], "roll": np.zeros(len(m.t)),
                              "pitch": np.zeros(len(m.t)), "yaw": np.zeros(len(m.t))})
    if metadata:
        (folder / "Metadata.csv").write_text(
            "version,device name,recording epoch time,recording time,recording timezone,"
            "platform,appVersion,device id,sensors,sampleRateMs,standardisation,"
            "platform version\n"
            f'3,Phone,1700000000000,2023-11-14_22-13-20,UTC,{platform},1.40,abc,'
            f'"Accelerometer|Gyroscope",10|10,{str(standardisation).lower()},14\n')
    return folder


# ------------------------------------------------------------------------------------------
# phyphox
# ------------------------------------------------------------------------------------------


def write_phyphox(folder: Path, m: Motion, *, sep: str = ",", gyro_unit: str = "rad/s",
                  mag_unit: str = "µT") -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    dec = "," if sep == ";" else "."

    def num(v: float) -> str:
        return f"{v:.9E}".replace(".", dec)

    def write(name: str, header: list[str], cols: list[np.ndarray]) -> None:
        lines = [sep.join(f'"{h}"' for h in header)]
        for i in range(len(m.t)):
            lines.append(sep.join(num(c[i]) for c in [m.t, *cols]))
        (folder / name).write_text("\n".join(lines) + "\n", encoding="utf-8")

    acc = ["Time (s)"] + [f"Acceleration {a} (m/s^2)" for a in "xyz"]
    write("Accelerometer.csv", [*acc, "Absolute acceleration (m/s^2)"],
          [*m.acc.T, np.linalg.norm(m.acc, axis=1)])
    gfac = 180.0 / np.pi if gyro_unit == "deg/s" else 1.0
    write("Gyroscope.csv", ["Time (s)"] + [f"Gyroscope {a} ({gyro_unit})" for a in "xyz"],
          list((m.gyr * gfac).T))
    mfac = 1e-3 if mag_unit == "mT" else 1.0
    write("Magnetometer.csv", ["Time (s)"] + [f"Magnetic field {a} ({mag_unit})" for a in "xyz"],
          list((m.mag * mfac).T))
    write("Pressure.csv", ["Time (s)", "Pressure (hPa)"], [m.pressure_pa / 100.0])
    meta = folder / "meta"
    meta.mkdir(exist_ok=True)
    (meta / "time.csv").write_text(
        '"event","experiment time","system time","system time text"\n'
        '"START",0.000000000E0,1.700000000000E9,"2023-11-14 22:13:20.000 UTC+00:00"\n')
    return folder


# ------------------------------------------------------------------------------------------
# IPIN logfile
# ------------------------------------------------------------------------------------------

IPIN_HEADER = """% LogFile created by the 'GetSensorData' App for Android.
% Date of creation: Wed Jun 14 10:51:07 GMT+02:00 2023
% Manufacturer:            	testmaker
% Model:                   	TEST-1
%
"""

LAT0, LON0 = 49.4612, 11.1112


def write_ipin(path: Path, m: Motion, *, offset_s: float = -5000.0, gyro_every: int = 1,
               with_posi: bool = True, ble: bool = True, extra: str = "") -> Path:
    """Logfile with app time = sensor time + offset + 3 ms delivery delay."""
    lines = [IPIN_HEADER.rstrip("\n")]
    sensor_t = m.t - offset_s
    app = m.t + 0.003
    q = m.q_nd
    for i in range(len(m.t)):
        lines.append(f"ACCE;{app[i]:.4f};{sensor_t[i]:.4f};{m.acc[i, 0]:.5f};"
                     f"{m.acc[i, 1]:.5f};{m.acc[i, 2]:.5f};3")
        if i % gyro_every == 0:
            lines.append(f"GYRO;{app[i]:.4f};{sensor_t[i]:.4f};{m.gyr[i, 0]:.5f};"
                         f"{m.gyr[i, 1]:.5f};{m.gyr[i, 2]:.5f};3")
        lines.append(f"MAGN;{app[i]:.4f};{sensor_t[i]:.4f};{m.mag[i, 0]:.5f};"
                     f"{m.mag[i, 1]:.5f};{m.mag[i, 2]:.5f};3")
        lines.append(f"AHRS;{app[i]:.4f};{sensor_t[i]:.4f};1.0;2.0;3.0;{q[i, 1]:.8f};"
                     f"{q[i, 2]:.8f};{q[i, 3]:.8f};3")
        if i % 5 == 0:
            lines.append(f"PRES;{app[i]:.4f};{sensor_t[i]:.4f};{m.pressure_pa[i] / 100:.4f};3")
            lines.append(f"LIGH;{app[i]:.4f};{sensor_t[i]:.4f};44.0;3")
        if ble and i % 10 == 3:
            minor = 1 + (i // 10) % 3
            lines.append(f"BLE4;{app[i]:.4f};iBeacon;BE:AC:20:23:00:0{minor};-{70 + minor};0;1;"
                         f"{minor};11111111-1111-BEAC-2023-111111111111")
        if i % 50 == 7:
            lines.append(f"WIFI;{app[i]:.4f};{sensor_t[i]:.4f};SSID;my;net;20:23:00:00:00:12;"
                         "2417;-63")
    if with_posi:
        n = len(m.t)
        lines.append(f"POSI;{m.t[n // 40]:.4f};1;{LAT0:.9f};{LON0:.9f};0;100")
        lines.append(f"POSI;{m.t[n // 2]:.4f};2;{LAT0 + 1e-4:.9f};{LON0:.9f};1;100")
        lines.append(f"POSI;{m.t[3 * n // 4]:.4f};3;{LAT0:.9f};{LON0 + 1e-4:.9f};0;100")
    path.write_text("\n".join(lines) + "\n" + extra)
    return path


def write_beacons(path: Path) -> Path:
    path.write_text('bleID,Lat,Lon,floor\n"BLE1",49.4613,11.1112,00\n"BLE2",49.4612,11.1113,00\n'
                    '"BLE9",49.4611,11.1111,-2\n')
    return path
