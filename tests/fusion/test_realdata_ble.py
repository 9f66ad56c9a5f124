"""RSS positioning on the position-annotated BLE dataset (../shared/data/ble_rssi)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from hrtls.data.landmarks import Landmark
from hrtls.data.observations import RssReadings
from hrtls.fusion.channel import ChannelEstimator
from hrtls.fusion.path_loss import PathLossModel
from hrtls.fusion.random_walk import RandomWalkParams, predict_random_walk
from hrtls.fusion.rss import update_rss_readings
from hrtls.fusion.rss_scans import group_scans, scan_position
from hrtls.fusion.state import FilterState

pytestmark = pytest.mark.realdata


def load(root: Path, name: str) -> tuple[dict[str, Landmark], RssReadings, np.ndarray]:
    text = (root / "cnf" / "tetam.dev").read_text()
    dongles = json.loads(text.split("Dongles:")[1].split("Beacons:")[0])
    lms = {mac: Landmark(id=mac, kind="anchor", position=tuple(v[0]))
           for mac, v in dongles.items()}
    rows = [line.split(",") for line in
            (root / "trk" / f"{name}_all_sensors.mbd").read_text().splitlines() if line.strip()]
    t = np.array([float(r[0]) for r in rows])
    order = np.argsort(t, kind="stable")                 # the files have tiny backward steps
    t = t[order] - t[order[0]]
    mac = np.array([rows[i][1] for i in order])
    rss = np.array([float(rows[i][3]) for i in order])
    pos = np.array([[float(x) for x in rows[i][4:7]] for i in order])
    return lms, RssReadings(t, mac, rss), pos


@pytest.fixture(scope="module")
def ble(shared_data: Path) -> Path:
    root = shared_data / "ble_rssi"
    if not root.is_dir():
        pytest.skip("ble_rssi not present")
    return root


def test_channel_rls_equals_batch_fit(ble: Path) -> None:
    lms, rss, pos = load(ble, "rectangular_with_rotation")
    anchors = np.array([lms[m].xyz() for m in rss.anchor])
    d = np.linalg.norm(pos - anchors, axis=1)
    x = np.column_stack([np.ones_like(d), -10 * np.log10(d)])
    theta = np.linalg.lstsq(x, rss.rss_dbm, rcond=None)[0]
    est = ChannelEstimator()
    cs, _ = est.update(est.start(PathLossModel()), rss_dbm=rss.rss_dbm, distance_m=d)
    assert cs.theta[0] == pytest.approx(theta[0], abs=1.0)
    assert cs.theta[1] == pytest.approx(theta[1], abs=0.1)
    assert 1.0 < cs.theta[1] < 2.5                       # indoor BLE: flat path loss


@pytest.mark.parametrize("name", ["straight_01", "rectangular_without_rotation"])
def test_rss_positioning_room_level(ble: Path, name: str) -> None:
    lms, rss, pos = load(ble, name)
    model = PathLossModel()                              # uncalibrated defaults
    errs = []
    for scan in group_scans(rss, lms, window_s=1.0):
        if len(scan.anchor) >= 3:
            truth = pos[np.searchsorted(rss.t, scan.t, side="right") - 1, :2]
            errs.append(np.linalg.norm(scan_position(scan, model).xy - truth))
    assert np.median(errs) < 4.5
    s = FilterState.initial(xyz=(10.0, 9.0, 1.7), sigma_xy_m=8.0)
    ekf = []
    for i in range(len(rss)):
        s = predict_random_walk(s, float(rss.t[i]), RandomWalkParams(sigma_speed_m_per_sqrt_s=1.0))
        s, _, _ = update_rss_readings(s, rss, [i], lms, model, use_3d=True)
        if rss.t[i] > 5.0:
            ekf.append(np.linalg.norm(s.x[:2] - pos[i, :2]))
    assert np.median(ekf) < 3.0
    assert np.median(ekf) < np.median(errs)
