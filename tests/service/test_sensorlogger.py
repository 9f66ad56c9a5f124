"""Sensor Logger's HTTP push: a recorded export replayed as push messages is tracked live
exactly as the offline reader + tracker track the export."""

from __future__ import annotations

import csv
import time
from pathlib import Path
from typing import Any

import httpx
import numpy as np
from tests.service.conftest import Live
from tests.service.streams import API, mission_for, office, stored
from tests.service.test_ingest import wait_idle

from hrtls.io.readers.sensorlogger import read_sensorlogger
from hrtls.pipeline import Tracker, preset
from hrtls.pipeline.chunks import aligned_imu


def write_export(folder: Path, t0_ns: int) -> None:
    """An Android Sensor Logger export (TotalAcceleration, Gyroscope, Magnetometer) of a walk."""
    s = office()
    assert s.imu is not None
    imu = aligned_imu(s.imu)   # a phone reporting its sensors on common times
    assert imu.gyro is not None and imu.mag is not None
    folder.mkdir()
    t_ns = t0_ns + np.round(s.imu.accel.t * 1e9).astype(np.int64)
    for name, series in (("TotalAcceleration", imu.accel), ("Gyroscope", imu.gyro),
                         ("Magnetometer", imu.mag)):
        with open(folder / f"{name}.csv", "w", newline="") as f:
            w = csv.writer(f)
            w.writerow(["time", "seconds_elapsed", "z", "y", "x"])
            for tn, v in zip(t_ns, series.values, strict=True):
                w.writerow([int(tn), (tn - t0_ns) * 1e-9, *(repr(float(v[k])) for k in (2, 1, 0))])


def push_messages(folder: Path, chunk_s: float) -> list[dict]:
    """The export as the app's HTTP push messages, one per ``chunk_s`` of samples."""
    items = []
    for name in ("TotalAcceleration", "Gyroscope", "Magnetometer"):
        with open(folder / f"{name}.csv") as f:
            for row in csv.DictReader(f):
                items.append({"name": name.lower(), "time": int(row["time"]),
                              "values": {"x": float(row["x"]), "y": float(row["y"]),
                                         "z": float(row["z"])}})
    items.sort(key=lambda i: (i["time"], i["name"]))
    t_first = items[0]["time"]
    messages: dict[int, list] = {}
    for it in items:
        messages.setdefault(int((it["time"] - t_first) * 1e-9 // chunk_s), []).append(it)
    return [{"messageId": k, "sessionId": "s1", "deviceId": "phone", "payload": v}
            for k, v in enumerate(messages[i] for i in sorted(messages))]


def _push(phone: httpx.Client, token: str, message: dict[str, Any]) -> httpx.Response:
    """POST one message; a phone resends after a 429, when told (bounded)."""
    for _ in range(300):
        r = phone.post(f"{API}/ingest/sensorlogger", params={"token": token}, json=message)
        if r.status_code != 429:
            break
        time.sleep(float(r.headers["retry-after"]))
    return r


def test_sensorlogger_push_tracked_like_offline(live: Live, commander: httpx.Client,
                                                tmp_path: Path) -> None:
    session = office()
    mid, aid, token = mission_for(commander, session)
    t0_unix = commander.get(f"{API}/missions/{mid}").json()["t0_unix"]
    origin_ns = round((t0_unix + 1.0) * 1e9)
    write_export(tmp_path / "export", origin_ns)
    offline_session = read_sensorlogger(tmp_path / "export")
    assert session.meta.start_pose is not None
    pose = {**session.meta.start_pose.model_dump(), "t": 1.0}
    assert commander.post(f"{API}/missions/{mid}/agents/{aid}/checkin",
                          json=pose).status_code == 200
    messages = push_messages(tmp_path / "export", 0.5)
    with httpx.Client(base_url=live.url, timeout=60) as phone:
        assert phone.post(f"{API}/ingest/sensorlogger", json=messages[0]).status_code == 401
        for m in messages:
            r = _push(phone, token, m)
            assert r.status_code == 200, r.text
        bad = _push(phone, token, {"messageId": 999, "payload": [{"name": "accelerometer"}]})
        assert bad.status_code == 422
        viewer = commander.post(f"{API}/tokens", json={"role": "viewer", "label": "v"}).json()
        assert phone.post(f"{API}/ingest/sensorlogger", params={"token": viewer["token"]},
                          json=messages[0]).status_code == 403
    wait_idle(live)
    time.sleep(0.2)
    got = stored(commander, mid, aid)
    meta = offline_session.meta.model_copy(update={
        "start_pose": session.meta.start_pose.model_copy(update={"t": 0.0}),
        "placement": session.meta.placement, "mounting_q_bd": session.meta.mounting_q_bd,
        "user": session.meta.user, "channel": session.meta.channel})
    ref = Tracker(preset("default")).run(
        offline_session.with_parts(meta=meta, landmarks=session.landmarks)).trajectory
    n = len(got["t"])
    assert n > 100 and got["t"][-1] >= ref.t[-1] + 1.0 - 8.0
    np.testing.assert_allclose(got["t"], ref.t[:n] + 1.0, atol=1e-6)
    np.testing.assert_allclose(got["xy"], ref.xyz[:n, :2], atol=1e-6)
