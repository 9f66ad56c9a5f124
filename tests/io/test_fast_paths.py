"""The fast paths of reading and writing tables give what the exact, value-by-value ones give."""

import json
import warnings

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hrtls.data import ImuStream, SensorSeries, Session, StepEvents, Trajectory, activity_labels
from hrtls.errors import FormatError
from hrtls.io.csvtable import _text_array, arrow_columns, labelled_text, read_table
from hrtls.io.geojson import geojson_document
from hrtls.io.jsonstream import SLICE
from hrtls.io.schema import TABLES
from hrtls.io.session import read_session, write_session
from hrtls.io.tables import activity_text, from_arrow, read_parquet, to_arrow

# values that test the one-pass sum: non-finite ones, nulls, and finite ones whose sum overflows
cell = st.one_of(st.floats(allow_nan=True, allow_infinity=True, width=64), st.none(),
                 st.sampled_from([1e308, -1e308, 1.7e308]))


def exact_problem(columns, kinds):
    """The value checks by hand: column by column, its first null where numbers are required,
    else its first non-finite number (NaN allowed where nulls are); (row, column, message)."""
    for name, values in columns.items():
        kind = kinds[name]
        if kind == "float" and None in values:
            return values.index(None), name, f"{name!r} is missing"
        for row, v in enumerate(values):
            if v is not None and (np.isinf(v) or (kind == "float" and np.isnan(v))):
                return row, name, f"{name!r} is {v}"
    return None


def arrow_of(columns):
    arrays = [pa.array(np.array([np.nan if v is None else v for v in values]),
                       mask=np.array([v is None for v in values])) for values in columns.values()]
    return pa.Table.from_arrays(arrays, names=list(columns))


@settings(max_examples=200, deadline=None)
@given(st.integers(1, 30).flatmap(lambda n: st.tuples(
    st.lists(cell, min_size=n, max_size=n), st.lists(cell, min_size=n, max_size=n))))
def test_sum_test_accepts_and_refuses_exactly_what_the_value_checks_do(cols):
    kinds = TABLES["ranges"].kinds  # "range": float, "sigma": float_or_empty
    columns = {"range": list(cols[0]), "sigma": list(cols[1])}
    out, problem = arrow_columns(arrow_of(columns), kinds)
    want = exact_problem(columns, kinds)
    if want is None:
        assert problem is None
        for name, values in columns.items():
            got = np.concatenate([c.to_numpy(zero_copy_only=False) for c in out[name].chunks])
            np.testing.assert_array_equal(got, [np.nan if v is None else v for v in values])
    else:
        assert problem is not None
        assert (problem.row, problem.column, problem.problem) == want


def test_finite_values_whose_sum_overflows_are_accepted():
    table = pa.table({"t": [0.0, 1.0, 2.0], "pressure_pa": [1.7e308, 1.7e308, -1.0]})
    checked = from_arrow(table, table="pressure")
    np.testing.assert_array_equal(checked.float("pressure_pa"), [1.7e308, 1.7e308, -1.0])


@pytest.mark.parametrize("bad", [np.inf, -np.inf, np.nan])
def test_parquet_and_csv_name_the_same_row_for_a_bad_value(tmp_path, bad):
    rng = np.random.default_rng(1)
    n = 3000
    t = np.arange(n) / 100.0
    acc = rng.normal([0, 0, 9.81], 0.5, (n, 3))
    columns = {"t": t, "ax": acc[:, 0], "ay": acc[:, 1].copy(), "az": acc[:, 2]}
    columns["ay"][1234] = bad
    # the writer turns NaN into a null: write the Parquet file with the NaN kept as a value
    arrow = pa.Table.from_arrays([pa.array(v) for v in columns.values()], names=list(columns))
    pq.write_table(arrow, tmp_path / "imu.parquet")
    (tmp_path / "imu.csv").write_text(
        "t,ax,ay,az\n" + "\n".join(",".join(repr(float(v)) for v in row)
                                   for row in zip(*columns.values(), strict=True)) + "\n")
    with pytest.raises(FormatError) as from_parquet:
        read_parquet((tmp_path / "imu.parquet").read_bytes(), table="imu", name="imu.parquet")
    spec = TABLES["imu"]
    with pytest.raises(FormatError) as from_csv:
        read_table((tmp_path / "imu.csv").read_bytes(), name="imu.csv", kinds=spec.kinds,
                   required=spec.required)
    assert from_parquet.value.where == "imu.parquet row 1235"
    assert from_csv.value.where == "imu.csv line 1236"  # the header is line 1
    assert "'ay'" in from_parquet.value.problem and "'ay'" in from_csv.value.problem


def test_parquet_time_is_a_writable_view_and_user_tables_are_copied(tmp_path):
    n = 500
    t = np.arange(n) / 100.0
    acc = np.tile([0.0, 0.0, 9.81], (n, 1)) + np.linspace(0, 0.1, n)[:, None]
    write_session(Session(imu=ImuStream(SensorSeries(t, acc))), tmp_path / "s",
                  table_format="parquet")
    back = read_session(tmp_path / "s")
    for values in (back.imu.accel.t, back.imu.accel.values):
        assert values.flags.writeable and values.flags.c_contiguous and values.flags.aligned
    np.testing.assert_array_equal(back.imu.accel.t, t)
    # a table the caller holds is never written through
    user = to_arrow({"t": t, "pressure_pa": np.full(n, 1e5)}, table="pressure")
    got = from_arrow(user, table="pressure").float("t")
    got[0] = -1.0
    assert user.column("t")[0].as_py() == 0.0


@settings(max_examples=100, deadline=None)
@given(st.lists(st.one_of(st.integers(-1, 4), st.integers(-5, 99),
                          st.integers(-10**9, 10**9)), max_size=60))
def test_activity_text_equals_the_per_row_labels(codes):
    codes = np.array(codes, dtype=np.int64)
    index, labels = activity_text(codes)
    assert [labels[k] for k in index] == activity_labels(codes).tolist()
    column = labelled_text(index, labels)
    assert column.equals(_text_array(activity_labels(codes)))


def test_labelled_text_refuses_an_index_outside_its_labels():
    with pytest.raises(IndexError):
        labelled_text(np.array([0, 2]), ["a", "b"])


def test_geojson_headings_and_labels_across_slices():
    n = 2 * SLICE + 17
    rng = np.random.default_rng(2)
    heading = rng.uniform(-3, 3, n)
    heading[SLICE + 5] = np.nan  # one slice with an unknown heading, the others without
    codes = rng.integers(-1, 5, n)
    tr = Trajectory.build(t=np.arange(n) * 0.1, xyz=rng.normal(0, 5, (n, 3)),
                          heading_rad=heading, activity=codes)
    steps = StepEvents.build(t_start=[0.0, 1.0], t_end=[0.5, 1.5], length_m=[0.7, 0.7],
                             heading_rad=[np.nan, 0.2], activity=["walking", "running"])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        doc = geojson_document(tr, steps=steps)
    json.dumps(doc, allow_nan=False)
    props = doc["features"][0]["properties"]
    assert props["heading_rad"] == [None if np.isnan(h) else float(h) for h in heading]
    assert props["activity"] == activity_labels(codes).tolist()
    step_props = [f["properties"] for f in doc["features"][1:3]]
    assert [p["activity"] for p in step_props] == ["walking", "running"]
    assert [p["heading_rad"] for p in step_props] == [None, 0.2]


def test_convert_to_parquet_and_back_to_csv(tmp_path):
    from typer.testing import CliRunner

    from hrtls.cli.app import app

    n = 400
    t = np.arange(n) / 100.0
    acc = np.tile([0.0, 0.0, 9.81], (n, 1)) + np.linspace(0, 0.1, n)[:, None]
    write_session(Session(imu=ImuStream(SensorSeries(t, acc))), tmp_path / "s")
    runner = CliRunner()
    res = runner.invoke(app, ["convert", str(tmp_path / "s"), "-o", str(tmp_path / "p"),
                              "--to", "parquet"])
    assert res.exit_code == 0, res.output
    assert (tmp_path / "p" / "imu.parquet").exists() and not (tmp_path / "p" / "imu.csv").exists()
    res = runner.invoke(app, ["convert", str(tmp_path / "p"), "-o", str(tmp_path / "c")])
    assert res.exit_code == 0, res.output
    np.testing.assert_array_equal(read_session(tmp_path / "c").imu.accel.values, acc)
    res = runner.invoke(app, ["convert", str(tmp_path / "s"), "-o", str(tmp_path / "x"),
                              "--to", "hdf5"])
    assert res.exit_code != 0 and "--to" in res.output and "csv or parquet" in res.output
