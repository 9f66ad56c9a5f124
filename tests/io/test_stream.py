import warnings

import numpy as np
import pytest

from hrtls.errors import FormatError, InputError
from hrtls.io.session import read_session, write_session
from hrtls.io.stream import open_stream
from hrtls.jobs.track import track_recording
from hrtls.pipeline import Tracker, preset
from hrtls.sim.scenarios import run_scenario


@pytest.fixture(scope="module")
def walk(tmp_path_factory):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sim = run_scenario("office_random_walk", 3, duration_s=150.0)
    root = tmp_path_factory.mktemp("walk")
    write_session(sim.session, root / "csv")
    write_session(sim.session, root / "pq.zip", table_format="parquet")
    return root


@pytest.mark.parametrize("name", ["csv", "pq.zip"])
def test_chunked_track_equals_whole_track(walk, name):
    cfg = preset("default")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        session = read_session(walk / name)
        whole = Tracker(cfg).run(session)
        run = track_recording(walk / name, cfg, chunk_rows=1500)
    assert run.streamed and run.samples == len(session.imu.accel)
    a, b = whole.trajectory, run.result.trajectory
    assert len(a) == len(b) > 100
    np.testing.assert_allclose(b.t, a.t, rtol=0, atol=1e-9)
    np.testing.assert_allclose(b.xyz, a.xyz, rtol=0, atol=1e-6)
    np.testing.assert_allclose(b.cov_xy, a.cov_xy, rtol=0, atol=1e-9)
    assert np.array_equal(b.activity, a.activity)
    assert len(run.result.steps) == len(whole.steps)
    np.testing.assert_allclose(run.result.steps.length_m, whole.steps.length_m, atol=1e-9)


def test_stream_chunks_cover_every_row_once(walk):
    stream = open_stream(walk / "csv", chunk_rows=1000)
    assert stream is not None
    whole = read_session(walk / "csv")
    chunks = list(stream.chunks())
    assert len(chunks) > 10
    t = np.concatenate([c.imu.accel.t for c in chunks])
    np.testing.assert_array_equal(t, whole.imu.accel.t)
    _, _, _, mag = whole.imu.aligned()
    np.testing.assert_allclose(np.concatenate([c.imu.mag.values for c in chunks]), mag)
    n_rss = sum(0 if c.rss is None else len(c.rss) for c in chunks)
    assert n_rss == len(whole.rss)
    # the times are kept for the whole-clock checks; the row count is estimated beforehand
    np.testing.assert_array_equal(stream.imu_t, whole.imu.accel.t)
    assert stream.rows_hint == pytest.approx(len(t), rel=0.05)


def test_stream_malformed_row_keeps_exact_message(walk, tmp_path):
    lines = (walk / "csv" / "imu.csv").read_text().splitlines()
    bad = tmp_path / "bad"
    write_session(read_session(walk / "csv"), bad)
    fields = lines[5000].split(",")
    fields[2] = "oops"
    lines[5000] = ",".join(fields)
    (bad / "imu.csv").write_text("\n".join(lines) + "\n")
    with pytest.raises(FormatError, match=r"imu\.csv line 5001: 'ay' is 'oops'; expected a number"):
        track_recording(bad, preset("default"), chunk_rows=1000)


def test_input_only_the_careful_reader_takes_is_tracked_whole(walk, tmp_path):
    session = read_session(walk / "csv")
    d = tmp_path / "spaced"
    write_session(session, d)
    lines = (d / "imu.csv").read_text().splitlines()
    fields = lines[100].split(",")
    fields[1] = "0_0"  # Python's float() reads it, Arrow's parser does not
    lines[100] = ",".join(fields)
    (d / "imu.csv").write_text("\n".join(lines) + "\n")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        run = track_recording(d, preset("default"), chunk_rows=1000)
    assert not run.streamed and run.samples == len(session.imu.accel)


def test_stream_time_going_back_late_keeps_exact_message(walk, tmp_path):
    # found by a late chunk, after earlier chunks were tracked: the whole-session reader's words
    bad = tmp_path / "back"
    write_session(read_session(walk / "csv"), bad)
    lines = (bad / "imu.csv").read_text().splitlines()
    lines[9000], lines[9001] = lines[9001], lines[9000]
    (bad / "imu.csv").write_text("\n".join(lines) + "\n")
    with pytest.raises(InputError) as whole:
        read_session(bad)
    assert "time goes backwards" in str(whole.value) and "index 9000" in str(whole.value)
    with pytest.raises(InputError) as streamed:
        track_recording(bad, preset("default"), chunk_rows=1000)
    assert str(streamed.value) == str(whole.value)
