"""Work on threads beside the caller's: read-ahead, values computed meanwhile, chunk borders."""

import threading
import warnings

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from hrtls.data import ImuStream, SensorSeries, Session
from hrtls.errors import FormatError
from hrtls.io.background import Background, read_ahead
from hrtls.io.session import read_session, write_session
from hrtls.io.stream import open_stream
from hrtls.jobs.track import track_recording
from hrtls.pipeline import preset


def _threads() -> set[str]:
    return {t.name for t in threading.enumerate()}


@given(st.lists(st.integers(), max_size=50), st.integers(1, 4))
def test_read_ahead_keeps_every_item_in_order(items, depth):
    assert list(read_ahead(iter(items), depth=depth)) == items


def test_read_ahead_raises_the_producers_error_at_its_item():
    failure = FormatError("x.csv line 7: 'ax' is 'oops'; expected a number")

    def produce():
        yield 1
        yield 2
        raise failure

    got = []
    with pytest.raises(FormatError) as raised:
        for item in read_ahead(produce(), name="test-failing"):
            got.append(item)
    assert raised.value is failure and got == [1, 2]
    assert "test-failing" not in _threads()


def test_read_ahead_closed_early_stops_its_thread():
    made = []

    def produce():
        for i in range(1000):
            made.append(i)
            yield i

    items = read_ahead(produce(), depth=2, name="test-closed")
    assert [next(items) for _ in range(3)] == [0, 1, 2]
    items.close()
    assert "test-closed" not in _threads()
    assert len(made) <= 3 + 2 + 1  # taken, queued, the one being made


def test_background_gives_the_value_or_raises_its_error():
    assert Background(lambda: 42).result() == 42
    failure = ValueError("truth.csv line 3")

    def fail():
        raise failure

    job = Background(fail)
    job.join()
    with pytest.raises(ValueError) as raised:
        job.result()
    assert raised.value is failure


@pytest.fixture(scope="module")
def imu_session(tmp_path_factory):
    rng = np.random.default_rng(7)
    n = 3001
    t = np.arange(n) / 100.0
    imu = ImuStream(SensorSeries(t, rng.normal([0, 0, 9.81], 0.3, (n, 3))),
                    SensorSeries(t, rng.normal(0, 0.1, (n, 3))),
                    SensorSeries(t, rng.normal([20, 0, -40], 1.0, (n, 3))))
    root = tmp_path_factory.mktemp("imu")
    write_session(Session(imu=imu), root / "csv")
    write_session(Session(imu=imu), root / "pq.zip", table_format="parquet")
    return root, imu


@settings(max_examples=25, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(chunk_rows=st.integers(2, 3500), name=st.sampled_from(["csv", "pq.zip"]),
       depth=st.integers(1, 3))
def test_read_ahead_chunks_lose_no_row_at_their_borders(imu_session, chunk_rows, name, depth):
    root, imu = imu_session
    stream = open_stream(root / name, chunk_rows=chunk_rows)
    assert stream is not None
    chunks = list(read_ahead(stream.chunks(), depth=depth))
    assert len(chunks) == -(-len(imu.accel) // chunk_rows)
    for part in ("accel", "gyro", "mag"):
        np.testing.assert_array_equal(
            np.concatenate([getattr(c.imu, part).values for c in chunks]),
            getattr(imu, part).values)
    np.testing.assert_array_equal(np.concatenate([c.imu.accel.t for c in chunks]), imu.accel.t)
    np.testing.assert_array_equal(stream.imu_t, imu.accel.t)


@pytest.fixture(scope="module")
def walk(tmp_path_factory):
    from hrtls.sim.scenarios import run_scenario

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sim = run_scenario("office_random_walk", 11, duration_s=90.0)
    root = tmp_path_factory.mktemp("walk")
    write_session(sim.session, root / "csv")
    return root / "csv"


def test_malformed_truth_read_on_a_thread_names_file_and_line(walk, tmp_path):
    bad = tmp_path / "bad"
    write_session(read_session(walk), bad)
    lines = (bad / "truth.csv").read_text().splitlines()
    fields = lines[2000].split(",")
    fields[1] = "oops"
    lines[2000] = ",".join(fields)
    (bad / "truth.csv").write_text("\n".join(lines) + "\n")
    header = lines[0].split(",")
    with pytest.raises(FormatError, match=rf"truth\.csv line 2001: '{header[1]}' is 'oops'"):
        track_recording(bad, preset("default"), chunk_rows=500)


def test_two_pass_on_a_session_folder_runs_both_passes(walk):
    from hrtls.pipeline import Tracker
    from hrtls.pipeline.finish import finish_track

    cfg = preset("default").model_copy(update={"offline": preset("default").offline.model_copy(
        update={"two_pass": True})})
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        run = track_recording(walk, cfg, chunk_rows=500)
        session = read_session(walk)
        whole = finish_track(Tracker(cfg).run(session), session, cfg)
    assert not run.streamed
    assert run.result.report["offline"]["two_pass"] is True
    np.testing.assert_array_equal(run.result.trajectory.xyz, whole.trajectory.xyz)
    one_pass = track_recording(walk, preset("default"), chunk_rows=500)
    assert one_pass.streamed and one_pass.result.report["offline"]["two_pass"] is False


def test_streamed_truth_is_the_whole_read_truth_and_its_thread_ends(walk):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        run = track_recording(walk, preset("default"), chunk_rows=500)
    whole = read_session(walk).truth
    got = run.session.truth
    assert got is not None and whole is not None and len(got.t) == len(whole.t) > 1000
    np.testing.assert_array_equal(got.t, whole.t)
    np.testing.assert_array_equal(got.xyz, whole.xyz)
    np.testing.assert_array_equal(got.heading_rad, whole.heading_rad)
    assert not [n for n in _threads() if n.startswith(("read truth of", "read "))]
