"""Walking direction found from the motion, mounting unknown (issue 19, item 2).

Each real recording is turned into other device frames (as recorded, and
``Rotation.random(random_state=seed)`` for the seeds given) and run through the gait stage
twice on the same attitude (``inertial-lp`` on the turned IMU, so both runs see the same steps
and the same yaw reference): once with the known mounting (turned with the frame), once with
the mounting unknown (the reference axis's yaw plus the estimated offset,
:mod:`hrtls.gait.walking_direction`). The table gives the step-heading difference between the
two (the absolute walking-direction error relative to the device), median and 90th
percentile of its size, for the first 10 steps with a heading and for the later ones (with
the mounting unknown the first steps get none, ``settle_steps``).

Known mountings: mobgap lower back (the reader's: x up, z forward); IPIN 2023 and the Oxford
``hand`` file (a phone held in front: the top edge made horizontal,
:func:`hrtls.pipeline.mounting.handheld_mounting_q_bd` over the whole file). The Oxford file
has no gyroscope: its attitude is the tilt alone (gravity from a causal 0.3 Hz low-pass, yaw
fixed to the device), which is all the gait stage needs here.

Development data (the lag rule, forgetting factor, ``max_step_s`` and ``settle_steps`` were
chosen on it): mobgap HA/001. Held out: HA/002, MS/001, IPIN, Oxford.

Needs ``../shared/data``. Run: ``python benchmarks/walking_direction.py [--seeds 1 2 3]``.
"""

from __future__ import annotations

import argparse
import warnings
from collections.abc import Iterator
from pathlib import Path

import numpy as np
from rich.console import Console
from rich.table import Table
from scipy.signal import butter, sosfilt, sosfilt_zi
from scipy.spatial.transform import Rotation

from hrtls.attitude.registry import make_filter
from hrtls.data import ImuStream
from hrtls.datasets.mobgap import list_trials, load_trial
from hrtls.datasets.oxford import load_recording
from hrtls.frames import quat_conjugate, quat_from_rotation, quat_multiply, wrap_angle
from hrtls.gait.analyzer import GaitAnalyzer
from hrtls.pipeline.mounting import handheld_mounting_q_bd
from hrtls.recordings import read_any

DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data"
DEV = ("mobgap HA/001",)


def recordings() -> Iterator[tuple[str, ImuStream, np.ndarray]]:
    """(name, IMU, known q_bd) of each recording with walking."""
    for tid in list_trials(DATA / "mobgap_lab"):
        s = load_trial(DATA / "mobgap_lab", tid.participant, tid.test, tid.trial).session
        assert s.imu is not None and s.meta.mounting_q_bd is not None
        yield (f"mobgap {tid.participant} {tid.test} {tid.trial}", s.imu,
               np.asarray(s.meta.mounting_q_bd))
    for f in sorted((DATA / "ipin2023").glob("IPIN2023_*.txt")):
        s = read_any(f, trim_to_start=True)
        assert s.imu is not None
        yield f"IPIN {f.name.split('_')[2]}", s.imu, handheld_mounting_q_bd(s.imu.accel.values)
    for f in sorted((DATA / "oxford_step").glob("user1_hand_*.csv")):
        imu = load_recording(f, repair=True).session.imu
        assert imu is not None
        yield "Oxford hand", imu, handheld_mounting_q_bd(imu.accel.values)


def tilt_attitude(t: np.ndarray, acc: np.ndarray) -> np.ndarray:
    """Tilt-only ``q_nd`` from causally low-passed gravity (device x kept at yaw 0)."""
    sos = butter(2, 0.3, fs=1.0 / float(np.median(np.diff(t))), output="sos")
    up = sosfilt(sos, acc, axis=0, zi=sosfilt_zi(sos)[:, :, None] * acc[0])[0]
    up /= np.linalg.norm(up, axis=1, keepdims=True)
    x = np.array([1.0, 0.0, 0.0]) - up[:, :1] * up   # device x made horizontal
    x /= np.linalg.norm(x, axis=1, keepdims=True)
    rows = np.stack([x, np.cross(up, x), up], axis=1)   # ENU axes in device coordinates
    return np.asarray(quat_from_rotation(Rotation.from_matrix(rows)), dtype=np.float64)


def errors_deg(imu: ImuStream, q_bd: np.ndarray, r: np.ndarray) -> np.ndarray:
    """|unknown - known mounting| step heading in device frame ``r``, deg (NaN: no heading)."""
    imu_r = imu.in_device_frame(r)
    t, acc = imu_r.accel.t, imu_r.accel.values
    if imu_r.gyro is None:
        q = tilt_attitude(t, acc)
    else:
        res = make_filter("inertial-lp").run(imu_r)
        acc = np.column_stack([np.interp(res.t, t, acc[:, k]) for k in range(3)])
        t, q = res.t, res.q
    rate = 1.0 / float(np.median(np.diff(t)))
    # q_bd' = q_bd * conj(q_r): body from the new device frame
    q_bd_r = quat_multiply(q_bd, quat_conjugate(quat_from_rotation(Rotation.from_matrix(r))))
    known = GaitAnalyzer(rate_hz=rate, heading="yaw", mounting_q_bd=q_bd_r).process(t, acc, q)
    unknown = GaitAnalyzer(rate_hz=rate, heading="yaw").process(t, acc, q)
    assert np.array_equal(known.steps.t_end, unknown.steps.t_end)
    return np.abs(np.degrees(wrap_angle(unknown.steps.heading_rad - known.steps.heading_rad)))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--seeds", type=int, nargs="*", default=[1, 2, 3])
    args = ap.parse_args()
    frames = [np.eye(3)] + [Rotation.random(random_state=k).as_matrix() for k in args.seeds]
    table = Table(title="walking direction, mounting unknown minus known (deg): median / p90 "
                        f"over the as-recorded frame and seeds {args.seeds}")
    for col in ("recording", "set", "steps", "without heading", "first 10 with one",
                "later ones"):
        table.add_column(col)
    pooled: dict[str, list[np.ndarray]] = {"dev": [], "held-out": []}
    for name, imu, q_bd in recordings():
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            errs = [errors_deg(imu, q_bd, r) for r in frames]
        n_none = int(np.sum(np.isnan(errs[0])))
        errs = [e[np.isfinite(e)] for e in errs]
        first = np.concatenate([e[:10] for e in errs])
        later = np.concatenate([e[10:] for e in errs])
        kind = "dev" if name.startswith(DEV) else "held-out"
        pooled[kind].append(later)

        def cell(e: np.ndarray) -> str:
            return f"{np.median(e):.1f} / {np.percentile(e, 90):.1f}" if e.size else "-"
        table.add_row(name, kind, str(len(errs[0]) + n_none), str(n_none), cell(first),
                      cell(later))
    for kind, parts in pooled.items():
        e = np.concatenate(parts)
        table.add_row(f"pooled {kind}", kind, "", "", "",
                      f"{np.median(e):.1f} / {np.percentile(e, 90):.1f}")
    Console(width=130).print(table)


if __name__ == "__main__":
    main()
