from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest

from hrtls.datasets.oxford import list_recordings, load_recording
from hrtls.errors import FormatError, InputError, RepairWarning

TRUE_STEPS = {"armband": 335, "backpocket": 343, "bag": 346, "frontpocket": 327, "hand": 326,
              "neckpouch": 346}


def _row(ns: int, acc: tuple[float, float, float], app: int, truth: int) -> str:
    return f"{ns},{acc[0]},{acc[1]},{acc[2]},{app},{truth},0"


def _write(tmp_path: Path, rows: list[str], name: str = "user9_frontpocket_1500000000000.csv"
           ) -> Path:
    path = tmp_path / name
    path.write_text("\n".join(rows) + "\n")
    return path


def _clean_rows(n: int = 30) -> list[str]:
    return [_row(1_000_000_000 + 10_000_000 * i, (0.1, 0.2, 9.8), i // 10, i // 5)
            for i in range(n)]


def test_clean_file_step_times_and_time_origin(tmp_path: Path) -> None:
    rec = load_recording(_write(tmp_path, _clean_rows()))
    assert rec.placement == "frontpocket"
    assert rec.total_steps == 5  # 29 // 5 - 0
    assert rec.app_steps == 2
    np.testing.assert_allclose(rec.step_times_s, [0.05, 0.10, 0.15, 0.20, 0.25])
    t = rec.session.imu.accel.t
    assert t[0] == 0.0 and t[1] == pytest.approx(0.01)
    assert rec.session.meta.time_origin_unix_s == pytest.approx(1.5e9)
    assert rec.session.imu.gyro is None and rec.session.imu.mag is None


def test_counter_jump_of_two_gives_two_step_times(tmp_path: Path) -> None:
    rows = [*_clean_rows(3), _row(1_030_000_000, (0, 0, 9.8), 0, 2)]
    rec = load_recording(_write(tmp_path, rows))
    assert rec.total_steps == 2
    np.testing.assert_allclose(rec.step_times_s, [0.03, 0.03])


def test_leading_zero_row_dropped_inner_one_rejected_then_repaired(tmp_path: Path) -> None:
    rows = _clean_rows()
    rows[0] = _row(1_000_000_000, (0.0, 0.0, 0.0), 0, 0)
    path = _write(tmp_path, rows)
    with pytest.warns(RepairWarning, match="all-zero"):  # before the sensor's first sample
        rec = load_recording(path)
    assert len(rec.session.imu.accel) == 29
    assert any("all-zero" in n for n in rec.session.meta.notes)
    rows[5] = _row(1_050_000_000, (0.0, 0.0, 0.0), 0, 1)
    path = _write(tmp_path, rows, "user9_hand_2.csv")
    with pytest.raises(InputError, match=r"line 6\b"):
        load_recording(path)
    with pytest.warns(RepairWarning, match="dropped 2 all-zero"):
        rec = load_recording(path, repair=True)
    assert len(rec.session.imu.accel) == 28


def test_backward_and_duplicate_rows(tmp_path: Path) -> None:
    rows = _clean_rows(10)
    rows.insert(5, rows[4])  # exact copy -> line 6: no information, dropped by default
    path = _write(tmp_path, rows)
    with pytest.warns(RepairWarning, match="dropped 1 exact duplicate"):
        rec = load_recording(path)
    assert len(rec.session.imu.accel) == 10
    rows.insert(8, _row(1_060_000_000, (1.0, 1.0, 9.0), 0, 1))  # equal time, other values
    path = _write(tmp_path, rows, "user9_bag_2.csv")
    with pytest.raises(InputError, match="line 9"):
        load_recording(path)
    with pytest.warns(RepairWarning, match="merged 1"):
        assert len(load_recording(path, repair=True).session.imu.accel) == 10
    # a backward step and a differing row with equal time
    rows = _clean_rows(10)
    rows[3], rows[4] = rows[4], rows[3]
    rows.append(_row(1_090_000_000, (1.0, 1.0, 9.0), 1, 1))
    with pytest.warns(RepairWarning) as record:
        rec = load_recording(_write(tmp_path, rows, "user9_bag_1.csv"), repair=True)
    message = str(record[0].message)
    assert "sorted 1 backward" in message and "merged 1" in message
    acc = rec.session.imu.accel
    assert np.all(np.diff(acc.t) > 0)
    np.testing.assert_allclose(acc.values[-1], [0.55, 0.6, 9.4])


def test_malformed_line_is_named(tmp_path: Path) -> None:
    rows = _clean_rows()
    rows[7] = "1070000000,0.1,0.2,9.8,0,1"
    with pytest.raises(FormatError, match="line 8"):
        load_recording(_write(tmp_path, rows))
    rows[7] = "1070000000,0.1,abc,9.8,0,1,0"
    with pytest.raises(FormatError, match="line 8"):
        load_recording(_write(tmp_path, rows, "user9_hand_2.csv"))


def test_cut_last_line_and_non_finite_field_need_repair(tmp_path: Path) -> None:
    rows = _clean_rows()
    rows[10] = "1100000000,0.1,nan,9.8,1,2,0"
    path = tmp_path / "user9_bag_3.csv"
    path.write_text("\n".join(rows) + "\n" + "1300000000,0.1")  # cut: no newline at the end
    with pytest.raises(FormatError, match=r"line 11.*field 3 is nan.*repair"):
        load_recording(path)
    path.write_text("\n".join(rows[:10] + rows[11:]) + "\n" + "1300000000,0.1")
    with pytest.raises(FormatError, match=r"line 30.*last line cut short \(2 of 7"):
        load_recording(path)
    path.write_text("\n".join(rows) + "\n" + "1300000000,0.1")
    with pytest.warns(RepairWarning, match=r"dropped 2 malformed line\(s\): line 11.*line 31"):
        rec = load_recording(path, repair=True)
    assert len(rec.session.imu.accel) == 29
    assert any("malformed" in n for n in rec.session.meta.notes)


def test_clock_jumping_back_is_named_even_after_repair(tmp_path: Path) -> None:
    rows = [_row(1_000_000_000 + 10_000_000 * i - (60_000_000_000 if i >= 15 else 0),
                 (0.1, 0.2, 9.8), 0, i // 5) for i in range(30)]
    path = _write(tmp_path, rows)
    with pytest.raises(InputError, match="line 16: timestamp is before"):
        load_recording(path)
    with pytest.warns(RepairWarning), pytest.raises(
            FormatError, match=r"once the times were sorted .*largest 60 s.*jump back"):
        load_recording(path, repair=True)


def test_file_of_another_format_is_not_offered_repair(tmp_path: Path) -> None:
    path = tmp_path / "user9_bag_4.csv"
    path.write_text("ACCE;0.1;5.0;0.1;9.8;0.2;3\nGYRO;0.1;5.0;0.0;0.0;0.0;3\n")
    with pytest.raises(FormatError, match=r"no line of 7 numbers \(line 1: 1 fields\)") as info:
        load_recording(path)
    assert "repair" not in str(info.value) and "--format" in str(info.value)


def test_decreasing_counter_is_rejected(tmp_path: Path) -> None:
    rows = _clean_rows()
    rows[-1] = _row(1_000_000_000 + 10_000_000 * 29, (0.1, 0.2, 9.8), 2, 0)
    with pytest.raises(FormatError, match="column 6"):
        load_recording(_write(tmp_path, rows))


@pytest.mark.realdata
def test_real_step_counts(shared_data: Path) -> None:
    paths = list_recordings(shared_data)
    assert len(paths) == 6
    for path in paths:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RepairWarning)
            rec = load_recording(path, repair=True)
        assert rec.total_steps == TRUE_STEPS[rec.placement]
        assert len(rec.step_times_s) == rec.total_steps
        assert np.all(np.diff(rec.step_times_s) >= 0)
        acc = rec.session.imu.accel
        assert 9.7 < np.median(np.linalg.norm(acc.values, axis=1)) < 10.7
        assert acc.rate_hz == pytest.approx(100.0, rel=0.01)
        assert 190.0 < acc.duration_s < 210.0


@pytest.mark.realdata
def test_real_known_defects(shared_data: Path) -> None:
    folder = shared_data / "oxford_step"
    by_place = {p.name.split("_")[1]: p for p in list_recordings(folder)}
    # exact copies and a leading all-zero row: dropped by default, with a warning
    with pytest.warns(RepairWarning, match="13345: dropped 1 exact duplicate"):
        load_recording(by_place["armband"])
    with pytest.warns(RepairWarning, match="715, 6715: dropped 2 exact duplicate"):
        load_recording(by_place["neckpouch"])
    with pytest.warns(RepairWarning, match=r"dropped 1 all-zero row\(s\) \(line\(s\) 1\)"):
        load_recording(by_place["hand"])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        clean = load_recording(by_place["backpocket"])
    assert clean.total_steps == 343
    with pytest.warns(RepairWarning, match="715, 6715"):
        neck = load_recording(by_place["neckpouch"], repair=True)
    assert sum("gap of" in n for n in neck.session.meta.notes) == 2
