import zipfile

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from tests.io.test_session_io import assert_same, full_session

from hrtls.data import ImuStream, SensorSeries, Session, TagDetections
from hrtls.errors import FormatError, UnitError
from hrtls.io.schema import TABLE_KEY, UNIT_KEY
from hrtls.io.session import read_session, session_from_tables, session_tables, write_session
from hrtls.io.tables import from_arrow, read_steps, to_arrow, write_steps

finite = st.floats(min_value=-1e6, max_value=1e6, allow_nan=False, width=64)


@settings(max_examples=40, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.lists(st.tuples(finite, finite, finite), min_size=2, max_size=40),
       st.floats(min_value=1e-3, max_value=1.0))
def test_csv_parquet_round_trips_are_exact(tmp_path, rows, dt):
    acc = np.array(rows)
    t = 1.7e9 + np.arange(len(acc)) * dt
    series = SensorSeries(t, acc + np.array([0, 0, 9.81]), "acc")
    s = Session(imu=ImuStream(series, check_units=False))
    write_session(s, tmp_path / "c", overwrite=True)
    back_csv = read_session(tmp_path / "c", check_units=False)
    write_session(back_csv, tmp_path / "p", overwrite=True, table_format="parquet")
    back_pq = read_session(tmp_path / "p", check_units=False)
    write_session(back_pq, tmp_path / "c2", overwrite=True)
    for b in (back_csv, back_pq, read_session(tmp_path / "c2", check_units=False)):
        assert np.array_equal(b.imu.accel.t, s.imu.accel.t)
        assert np.array_equal(b.imu.accel.values, s.imu.accel.values)


@pytest.mark.parametrize("name", ["p", "p.zip"])
def test_parquet_session_round_trip_every_file(tmp_path, name):
    s = full_session()
    write_session(s, tmp_path / name, table_format="parquet")
    if name == "p":
        assert (tmp_path / "p" / "imu.parquet").exists()
        assert not (tmp_path / "p" / "imu.csv").exists()
    else:
        with zipfile.ZipFile(tmp_path / name) as zf:
            assert "rss.parquet" in zf.namelist()
    assert_same(s, read_session(tmp_path / name))


def test_units_are_in_the_schema_and_checked(tmp_path):
    write_session(full_session(), tmp_path / "p", table_format="parquet")
    table = pq.read_table(tmp_path / "p" / "imu.parquet")
    assert table.schema.metadata[TABLE_KEY] == b"imu"
    assert table.schema.field("ax").metadata[UNIT_KEY] == b"m/s^2"
    assert table.schema.field("mx").metadata[UNIT_KEY] == b"uT"
    assert pq.read_table(tmp_path / "p" / "rss.parquet").schema.field("rss_dbm").metadata[
        UNIT_KEY] == b"dBm"
    field = table.schema.field("ax").with_metadata({UNIT_KEY: b"g"})
    wrong = table.cast(table.schema.set(table.schema.get_field_index("ax"), field))
    pq.write_table(wrong, tmp_path / "p" / "imu.parquet")
    with pytest.raises(UnitError, match=r"imu\.parquet schema: column 'ax' is in 'g'"):
        read_session(tmp_path / "p")


def test_malformed_parquet_names_row_and_column(tmp_path):
    write_session(full_session(), tmp_path / "p", table_format="parquet")
    table = pq.read_table(tmp_path / "p" / "pressure.parquet")
    values = table.column("pressure_pa").to_numpy().copy()
    values[3] = np.inf
    pq.write_table(table.set_column(1, "pressure_pa", pa.array(values)),
                   tmp_path / "p" / "pressure.parquet")
    with pytest.raises(FormatError, match=r"pressure\.parquet row 4: 'pressure_pa' is inf; "
                                          r"expected a finite number"):
        read_session(tmp_path / "p")
    (tmp_path / "p" / "pressure.parquet").write_bytes(b"not parquet")
    with pytest.raises(FormatError, match="not a readable Parquet file"):
        read_session(tmp_path / "p")
    (tmp_path / "p" / "pressure.parquet").unlink()
    (tmp_path / "p" / "tags.csv").write_text("t,tag\n1.0,x\n")
    with pytest.raises(FormatError, match=r"both tags\.csv and tags\.parquet"):
        read_session(tmp_path / "p")


def test_arrow_api_round_trip_and_checks():
    s = full_session()
    tables = session_tables(s)
    assert set(tables) >= {"imu", "gyro", "rss", "truth"}
    back = session_from_tables(tables, meta=s.meta, landmarks=s.landmarks)
    assert_same(s, back)
    with pytest.raises(FormatError, match="tags row 2: empty 'tag'"):
        from_arrow(pa.table({"t": [0.0, 1.0], "tag": ["a", " "]}), table="tags")
    with pytest.raises(FormatError, match="unknown column"):
        to_arrow({"t": np.zeros(2), "pressure_pa": np.ones(2), "bogus": np.zeros(2)},
                 table="pressure")
    tags = TagDetections(np.array([0.0, 1.0]), np.array(["a", "b"]))
    assert from_arrow(to_arrow({"t": tags.t, "tag": tags.tag}, table="tags"),
                      table="tags").str("tag").tolist() == ["a", "b"]


def test_steps_parquet_output(tmp_path):
    from hrtls.data import StepEvents

    steps = StepEvents.build(t_start=[0, 0.5], t_end=[0.5, 1.0], length_m=[0.7, 0.72],
                             heading_rad=[0.1, np.nan], dz_m=[0, 0.17],
                             activity=["walking", "upstairs"])
    write_steps(steps, tmp_path / "steps.parquet")
    back = read_steps(tmp_path / "steps.parquet")
    assert np.allclose(back.heading_rad, steps.heading_rad, equal_nan=True)
    assert list(back.activity) == list(steps.activity)


@pytest.mark.filterwarnings("ignore::hrtls.errors.DegradedInputWarning")
def test_parquet_numbers_are_byte_stream_split_and_text_dictionary(tmp_path):
    rng = np.random.default_rng(3)
    n = 500
    t = np.arange(n) / 100.0
    session = Session(imu=ImuStream(SensorSeries(t, rng.normal([0, 0, 9.81], 1.0, (n, 3)))),
                      tags=TagDetections(np.array([1.0, 2.0]), np.array(["a", "b"])))
    write_session(session, tmp_path / "s", table_format="parquet")
    imu = pq.ParquetFile(tmp_path / "s" / "imu.parquet").metadata.row_group(0)
    encodings = {imu.column(i).path_in_schema: imu.column(i).encodings
                 for i in range(imu.num_columns)}
    assert all("BYTE_STREAM_SPLIT" in e for e in encodings.values())
    tags = pq.ParquetFile(tmp_path / "s" / "tags.parquet").metadata.row_group(0)
    assert any("DICTIONARY" in e for e in tags.column(1).encodings)
    back = read_session(tmp_path / "s")
    np.testing.assert_array_equal(back.imu.accel.values, session.imu.accel.values)
    np.testing.assert_array_equal(back.tags.tag, ["a", "b"])


def test_many_chunk_columns_are_joined_in_order(tmp_path):
    # 1 MiB Arrow blocks: a 40k-row file parses in several chunks, joined into one array
    n = 40_000
    rng = np.random.default_rng(5)
    t = np.arange(n) / 100.0
    acc = rng.normal([0, 0, 9.81], 1.0, (n, 3))
    write_session(Session(imu=ImuStream(SensorSeries(t, acc))), tmp_path / "s")
    assert (tmp_path / "s" / "imu.csv").stat().st_size > 2 << 20
    back = read_session(tmp_path / "s")
    np.testing.assert_array_equal(back.imu.accel.t, t)
    np.testing.assert_array_equal(back.imu.accel.values, acc)
    assert back.imu.accel.values.flags.c_contiguous and back.imu.accel.values.flags.writeable


def test_bad_value_deep_in_a_memory_mapped_file_names_its_line(tmp_path):
    n = 40_000
    t = np.arange(n) / 100.0
    acc = np.tile([0.0, 0.0, 9.81], (n, 1))
    write_session(Session(imu=ImuStream(SensorSeries(t, acc))), tmp_path / "s")
    path = tmp_path / "s" / "imu.csv"
    lines = path.read_text().splitlines()
    fields = lines[30_001].split(",")
    fields[2] = "oops"
    lines[30_001] = ",".join(fields)
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(FormatError, match=r"imu\.csv line 30002.*'ay' is 'oops'"):
        read_session(tmp_path / "s")


def test_integer_parquet_columns_with_nulls_read_as_nan(tmp_path):
    arrow = pa.table({"t": pa.array([0, 1, 2], pa.int64()), "x": [0.0, 1.0, 2.0],
                      "y": [0.0, 0.0, 0.0], "z": [0.0, 0.0, 0.0],
                      "heading": pa.array([1, None, 3], pa.int32())})
    table = from_arrow(arrow, table="trajectory")
    np.testing.assert_array_equal(table.float("t"), [0.0, 1.0, 2.0])
    np.testing.assert_array_equal(table.float("heading"), [1.0, np.nan, 3.0])
    assert table.matrix(("x", "heading")).shape == (3, 2)


def test_unit_check_on_a_long_recording_still_catches_g(tmp_path):
    # the unit guess looks at evenly spaced samples of long signals
    n = 300_000
    t = np.arange(n) / 100.0
    acc_g = np.random.default_rng(2).normal([0, 0, 1.0], 0.1, (n, 3))
    write_session(Session(imu=ImuStream(SensorSeries(t, acc_g), check_units=False)),
                  tmp_path / "s", table_format="parquet")
    with pytest.raises(UnitError, match="gravity in g"):
        read_session(tmp_path / "s")
