import json
import os

import numpy as np
import pytest
import typer
from typer.testing import CliRunner

from hrtls.cli.track import track
from hrtls.io.session import write_session
from hrtls.jobs.batch import find_recordings, is_batch, plan_batch, run_batch, track_one
from hrtls.parallel import LocalEngine, Outcome
from hrtls.runner import make_engine
from hrtls.sim.scenarios import run_scenario

app = typer.Typer()
app.command()(track)
runner = CliRunner()


@pytest.fixture(scope="module")
def recordings(tmp_path_factory):
    root = tmp_path_factory.mktemp("recs")
    for seed in (0, 1):
        sim = run_scenario("colombo_circle", seed=seed, laps=1)
        write_session(sim.session, root / f"circle{seed}")
    broken = root / "broken"
    broken.mkdir()
    (broken / "imu.csv").write_text("t,ax,ay,az\n0,0,0,9.81\n0.01,0,0,nan\n0.005,0,0,9.8\n")
    return root


def _square(x):
    return x * x


def _fails_on_two(x):
    if x == 2:
        raise ValueError("two is refused")
    return x


def test_local_engine_keeps_order_and_reports_failures():
    eng = LocalEngine(workers=2)
    out = eng.map(_fails_on_two, [0, 1, 2, 3])
    assert [o.index for o in out] == [0, 1, 2, 3]
    assert [o.value for o in out if o.ok] == [0, 1, 3]
    assert out[2].error == "ValueError: two is refused"
    assert "Traceback" in out[2].detail
    seen = []
    assert [o.value for o in LocalEngine(workers=1).map(_square, [1, 2, 3],
                                                        progress=lambda d, t: seen.append(d))] \
        == [1, 4, 9]
    assert seen == [1, 2, 3]


def test_engine_names_are_checked():
    from hrtls.errors import InputError

    with pytest.raises(InputError, match="--engine"):
        make_engine("spark")
    with pytest.raises(InputError, match="--workers"):
        LocalEngine(workers=0)
    with pytest.raises(InputError, match="--ray-address"):
        make_engine("local", ray_address="auto")


def test_batch_detection_and_listing(recordings):
    assert is_batch(str(recordings))
    assert not is_batch(str(recordings / "circle0"))
    assert is_batch(str(recordings / "circle*"))
    found = find_recordings(str(recordings))
    assert [p.name for p in found] == ["broken", "circle0", "circle1"]


def test_parallel_batch_equals_one_process(recordings, tmp_path):
    recs = find_recordings(str(recordings))
    serial = plan_batch(recs, tmp_path / "serial", preset="default", config_path=None)
    parallel = plan_batch(recs, tmp_path / "parallel", preset="default", config_path=None)
    a = run_batch(serial, tmp_path / "serial", engine=LocalEngine(workers=1))
    b = run_batch(parallel, tmp_path / "parallel", engine=LocalEngine(workers=2))
    assert [r["status"] for r in a.rows] == ["failed", "ok", "ok"]
    assert [r["status"] for r in b.rows] == ["failed", "ok", "ok"]
    assert "broken" in a.rows[0]["recording"] and a.rows[0]["error"]
    for name in ("circle0", "circle1"):
        ta = (tmp_path / "serial" / name / "trajectory.csv").read_text()
        tb = (tmp_path / "parallel" / name / "trajectory.csv").read_text()
        assert ta == tb
    summary = json.loads(b.summary_json.read_text())
    assert summary["workers"] == 2 and len(summary["recordings"]) == 3


def test_track_one_matches_plain_tracker(recordings, tmp_path):
    from hrtls.io.readers.detect import read_any
    from hrtls.pipeline import Tracker, preset

    task = plan_batch([recordings / "circle0"], tmp_path, preset="default", config_path=None)[0]
    s = track_one(task)
    direct = Tracker(preset("default")).run(read_any(recordings / "circle0"))
    assert s.steps == len(direct.steps)
    assert s.distance_walked_m == pytest.approx(direct.report["summary"]["distance_walked_m"])


def test_cli_batch_reports_failure_with_exit_code(recordings, tmp_path):
    r = runner.invoke(app, [str(recordings), "-o", str(tmp_path / "out"), "--workers", "1"])
    assert r.exit_code == 2, r.output
    assert "1 of 3 recordings failed" in r.output
    assert (tmp_path / "out" / "circle1" / "trajectory.csv").exists()
    r = runner.invoke(app, [str(recordings / "circle0"), "-o", str(tmp_path / "one"),
                            "--engine", "ray"])
    assert r.exit_code == 2 and "--engine" in r.output


def _ray_available() -> bool:
    try:
        import ray  # noqa: F401
    except ImportError:
        return False
    return True


@pytest.mark.skipif(not _ray_available() and os.environ.get("CI") != "true",
                    reason="Ray is not installed (pip install 'hrtls[ray]')")
def test_ray_batch_equals_local(recordings, tmp_path):
    import sys

    import ray
    from ray import cloudpickle

    # The workers cannot import this test module: ship its functions by value.
    cloudpickle.register_pickle_by_value(sys.modules[__name__])
    eng = make_engine("ray", workers=2)
    try:
        out = eng.map(_fails_on_two, [0, 1, 2, 3])
        assert [o.value for o in out] == [0, 1, None, 3]
        assert out[2].error is not None and "two is refused" in out[2].error
        recs = find_recordings(str(recordings / "circle*"))
        a = run_batch(plan_batch(recs, tmp_path / "ray", preset="default", config_path=None),
                      tmp_path / "ray", engine=eng)
        run_batch(plan_batch(recs, tmp_path / "loc", preset="default", config_path=None),
                      tmp_path / "loc", engine=LocalEngine(workers=1))
        assert [r["status"] for r in a.rows] == ["ok", "ok"]
        for name in ("circle0", "circle1"):
            xa = np.loadtxt(tmp_path / "ray" / name / "trajectory.csv", delimiter=",",
                            skiprows=1, usecols=range(9))
            xb = np.loadtxt(tmp_path / "loc" / name / "trajectory.csv", delimiter=",",
                            skiprows=1, usecols=range(9))
            np.testing.assert_array_equal(xa, xb)
    finally:
        ray.shutdown()


def test_outcome_ok_flag():
    assert Outcome(index=0, value=1).ok
    assert not Outcome(index=0, error="x").ok


def test_core_and_cli_never_import_ray(tmp_path):
    import subprocess
    import sys

    code = (
        "import sys\n"
        "import hrtls.cli.app, hrtls.pipeline, hrtls.parallel, hrtls.runner, hrtls.jobs.batch\n"
        "from hrtls.wsn import experiment as ex\n"
        "ex.loose_study(n_networks=2, seed=0)\n"
        "assert 'ray' not in sys.modules, 'ray was imported'\n"
    )
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
