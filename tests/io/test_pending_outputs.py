"""The tables of a track written on a thread (:func:`start_track_outputs`) while the caller
evaluates: the same files as :func:`write_track_outputs`, errors raised at the end."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from hrtls.errors import InputError
from hrtls.io.session import write_session
from hrtls.jobs.track import (
    LOCAL_GEOJSON,
    TrackRun,
    evaluate_track,
    start_track_outputs,
    track_recording,
    write_track_outputs,
)
from hrtls.pipeline import preset
from hrtls.sim.scenarios import run_scenario


@pytest.fixture(scope="module")
def tracked(tmp_path_factory: pytest.TempPathFactory) -> TrackRun:
    folder = tmp_path_factory.mktemp("walk") / "session"
    write_session(run_scenario("colombo_circle", seed=0, laps=1).session, folder)
    return track_recording(folder, preset("default"))


def test_outputs_written_meanwhile_are_the_outputs_written_at_once(tracked: TrackRun,
                                                                    tmp_path: Path) -> None:
    result, session = tracked.result, tracked.session
    evaluation = evaluate_track(result, session)
    assert evaluation is not None
    at_once = write_track_outputs(result, session, tmp_path / "once", evaluation=evaluation)
    pending = start_track_outputs(result, session, tmp_path / "meanwhile")
    meanwhile = pending.finish(result, session, evaluation=evaluate_track(result, session))
    assert [p.name for p in at_once] == [p.name for p in meanwhile] == [
        "trajectory.csv", "steps.csv", LOCAL_GEOJSON, "report.json"]
    for a, b in zip(at_once, meanwhile, strict=True):
        assert a.read_bytes() == b.read_bytes(), a.name
    report = json.loads(meanwhile[-1].read_text())
    assert report["evaluation"] == json.loads(json.dumps(evaluation, default=float))


def test_report_holds_what_was_added_before_finish(tracked: TrackRun, tmp_path: Path) -> None:
    result, session = tracked.result, tracked.session
    pending = start_track_outputs(result, session, tmp_path / "out")
    result.report["reference_steps"] = {"reference": 3}
    try:
        pending.finish(result, session)
    finally:
        del result.report["reference_steps"]
    report = json.loads((tmp_path / "out" / "report.json").read_text())
    assert report["reference_steps"] == {"reference": 3} and "evaluation" not in report


def test_a_writer_error_is_raised_at_finish_without_a_report(tracked: TrackRun,
                                                             tmp_path: Path) -> None:
    out = tmp_path / "out"
    (out / LOCAL_GEOJSON).mkdir(parents=True)   # the GeoJSON cannot replace a folder
    pending = start_track_outputs(tracked.result, tracked.session, out, overwrite=True)
    with pytest.raises(InputError, match="is a folder") as raised:
        pending.finish(tracked.result, tracked.session)
    assert LOCAL_GEOJSON in str(raised.value)
    assert not (out / "report.json").exists()
    assert (out / "trajectory.csv").exists()   # the tables' writer ended first


def test_a_table_error_is_raised_at_finish(tracked: TrackRun, tmp_path: Path) -> None:
    out = tmp_path / "out"
    (out / "steps.csv").mkdir(parents=True)   # the steps table cannot replace a folder
    pending = start_track_outputs(tracked.result, tracked.session, out, overwrite=True)
    with pytest.raises((InputError, OSError)) as raised:
        pending.finish(tracked.result, tracked.session)
    assert "steps.csv" in str(raised.value)
    assert (out / LOCAL_GEOJSON).is_file() and not (out / "report.json").exists()


def test_refusals_come_before_any_thread_or_folder(tracked: TrackRun, tmp_path: Path) -> None:
    with pytest.raises(InputError, match="csv or parquet"):
        start_track_outputs(tracked.result, tracked.session, tmp_path / "a",
                            table_format="xlsx")  # type: ignore[arg-type]
    assert not (tmp_path / "a").exists()
    (tmp_path / "b").mkdir()
    (tmp_path / "b" / "report.json").write_text("{}")
    with pytest.raises(InputError, match="already holds results"):
        start_track_outputs(tracked.result, tracked.session, tmp_path / "b")
