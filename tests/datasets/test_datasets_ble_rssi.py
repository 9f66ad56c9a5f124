from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest

from hrtls.datasets.ble_rssi import list_trajectories, load_devices, load_trajectory
from hrtls.errors import FormatError, InputError, RepairWarning

DEV = (
    'Dongles:{"aa0000000001": [[0.0, 0.0, 1.0], 1, "sensor1"], '
    '"AA0000000002": [[10.0, 0.0, 2.0], 2, "sensor2"]}\n'
    'Beacons:{"bb0000000001": [[], 3, "beacon1"] }\n'
)
ROT = ",1,0,0,0,1,0,0,0,1"


def _line(t: str, rx: str, rss: int, x: float) -> str:
    return f"{t},{rx},bb0000000001,{rss},{x},1.0,1.5{ROT}"


def _folder(tmp_path: Path, lines: list[str], name: str = "walk") -> Path:
    root = tmp_path / "ble_rssi"
    (root / "cnf").mkdir(parents=True)
    (root / "trk").mkdir()
    (root / "cnf" / "tetam.dev").write_text(DEV)
    (root / "trk" / f"{name}_all_sensors.mbd").write_text("\n".join(lines) + "\n")
    return tmp_path


def test_devices_parse(tmp_path: Path) -> None:
    _folder(tmp_path, [_line("100.0", "aa0000000001", -60, 1.0)])
    receivers, beacons = load_devices(tmp_path / "ble_rssi" / "cnf" / "tetam.dev")
    assert set(receivers) == {"sensor1", "sensor2"}
    assert receivers["sensor2"].mac == "aa0000000002"
    assert receivers["sensor2"].xyz == (10.0, 0.0, 2.0)
    assert beacons == {"bb0000000001": "beacon1"}


def test_synthetic_trajectory_sorting_and_truth(tmp_path: Path) -> None:
    lines = [
        _line("100.0", "aa0000000001", -60, 1.0),
        _line("100.0", "aa0000000002", -70, 1.0),      # same time as line 1
        _line("100.5004", "aa0000000001", -61, 2.0),
        _line("100.5", "aa0000000002", -71, 2.0),      # line 4 goes back by 0.4 ms
        _line("101.0", "aa0000000001", -62, 3.0),
    ]
    root = _folder(tmp_path, lines)
    assert list_trajectories(root) == ["walk"]
    with pytest.warns(RepairWarning, match=r"line\(s\) 4"):  # 0.4 ms: the merge order
        assert len(load_trajectory(root, "walk", repair=False).session.rss.t) == 5
    with pytest.warns(RepairWarning, match="line"):
        traj = load_trajectory(root, "walk")
    s = traj.session
    np.testing.assert_allclose(s.rss.t, [0.0, 0.0, 0.5, 0.5004, 1.0], atol=1e-6)
    np.testing.assert_array_equal(s.rss.anchor, ["sensor1", "sensor2", "sensor2", "sensor1",
                                                 "sensor1"])
    np.testing.assert_array_equal(s.rss.rss_dbm, [-60, -70, -71, -61, -62])
    assert s.meta.time_origin_unix_s == pytest.approx(100.0)
    # truth: one sample per distinct time
    assert len(s.truth) == 4
    np.testing.assert_allclose(s.truth.xyz[:, 0], [1.0, 2.0, 2.0, 3.0])
    assert set(s.landmarks) == {"sensor1", "sensor2"}
    assert s.landmarks["sensor1"].kind == "anchor"
    assert s.unknown_ids() == {}
    np.testing.assert_allclose(traj.distances_m()[0], np.linalg.norm([1.0, 1.0, 0.5]))
    assert traj.beacon_rotation.shape == (5, 3, 3)


def test_backward_step_beyond_the_merge_jitter_needs_repair(tmp_path: Path) -> None:
    lines = [_line("100.0", "aa0000000001", -60, 1.0),
             _line("100.0004", "aa0000000002", -70, 1.0),
             _line("100.0", "aa0000000001", -61, 1.0),      # line 3: back by 0.4 ms
             _line("101.5", "aa0000000002", -71, 2.0),
             _line("101.0", "aa0000000001", -62, 3.0)]      # line 5: back by 0.5 s
    root = _folder(tmp_path, lines)
    with pytest.raises(InputError, match=r"line 5.*0\.5 s"):
        load_trajectory(root, "walk", repair=False)
    with pytest.warns(RepairWarning, match="sorted 2 backward"):
        traj = load_trajectory(root, "walk", repair=True)
    np.testing.assert_allclose(traj.session.rss.t, [0.0, 0.0, 0.0004, 1.0, 1.5], atol=1e-6)


def test_synthetic_errors(tmp_path: Path) -> None:
    root = _folder(tmp_path, [_line("100.0", "cc0000000009", -60, 1.0)])
    with pytest.raises(FormatError, match="line 1"):
        load_trajectory(root, "walk")
    with pytest.raises(InputError, match="walk"):
        load_trajectory(root, "nope")
    (tmp_path / "ble_rssi" / "trk" / "bad_all_sensors.mbd").write_text("1,2,3\n")
    with pytest.raises(FormatError, match=r"line 1: 3 fields.*repair"):
        load_trajectory(root, "bad", repair=False)
    with pytest.raises(FormatError, match=r"no readings \(all 1 malformed, line 1: 3 fields"):
        load_trajectory(root, "bad")


def test_malformed_lines_need_repair_and_keep_their_numbers(tmp_path: Path) -> None:
    lines = [_line("100.0", "aa0000000001", -60, 1.0), "",
             _line("100.5", "aa0000000002", -70, 1.0).replace("-70", "nan"),
             _line("101.0", "aa0000000001", -61, 2.0),
             _line("100.9", "aa0000000002", -71, 2.0),   # line 5: back by 0.1 s
             _line("101.5", "aa0000000001", -62, 3.0)[:20]]  # cut short
    root = _folder(tmp_path, lines)
    with pytest.raises(FormatError, match="line 3: a non-finite number"):
        load_trajectory(root, "walk", repair=False)
    with pytest.warns(RepairWarning) as record:
        traj = load_trajectory(root, "walk", repair=True)
    text = " | ".join(str(w.message) for w in record)
    assert "dropped 2 malformed line(s): line 3" in text and "line 6" in text
    assert "line(s) 5" in text  # the backward step is named by its line in the file
    np.testing.assert_array_equal(traj.session.rss.rss_dbm, [-60, -71, -61])


@pytest.mark.realdata
def test_real_trajectories(shared_data: Path) -> None:
    names = list_trajectories(shared_data)
    assert names == ["rectangular_with_rotation", "rectangular_without_rotation", "straight_01",
                     "straight_02", "straight_03"]
    with pytest.warns(RepairWarning, match=r"line\(s\) 679"):  # 0.66 ms, sorted
        load_trajectory(shared_data, "rectangular_with_rotation", repair=False)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        load_trajectory(shared_data, "straight_01", repair=False)  # only equal times
    for name in names:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RepairWarning)
            traj = load_trajectory(shared_data, name)
        s = traj.session
        assert len(s.landmarks) == 12
        assert {lm.position[2] for lm in s.landmarks.values()} == {1.22, 2.30}  # type: ignore[index]
        assert s.unknown_ids() == {}
        assert s.rss.rss_dbm.min() >= -102 and s.rss.rss_dbm.max() <= -51
        assert 45.0 < s.rss.t[-1] < 85.0
        assert np.all(np.diff(s.truth.t) > 0)
        assert s.truth.xyz[:, 2].min() > 1.4 and s.truth.xyz[:, 2].max() < 2.1
        assert np.all((s.truth.xyz[:, :2] > -1.0) & (s.truth.xyz[:, :2] < 21.0))
        # RSS falls with distance: rank correlation clearly negative (-0.43 .. -0.56 measured)
        d = traj.distances_m()
        rank_d = np.argsort(np.argsort(d))
        rank_r = np.argsort(np.argsort(traj.rss_dbm))
        assert np.corrcoef(rank_d, rank_r)[0, 1] < -0.3
